# From-region visibility dependencies (view cells, occluder shrinking, PVS baking): GEOS, OpenMP and
# MPI. Included at the end of CMakeLists.txt, after the targets exist.
#  - GEOS (libgeos-dev): the C API through pkg-config (geos.pc), reentrant _r functions only.
#  - OpenMP (gcc -fopenmp): the PVS bake distributes view cells over threads (the library).
#  - MPI (mpich, libmpich-dev): `mpiexec -n N sightline pvs build ...` distributes cells over
#    processes. Only the command links it (tools/pvs_mpi.c): a program using libsightline never
#    needs MPI. Optional at configure time: without it tools/pvs_mpi.c is compiled with
#    SL_HAVE_MPI undefined and `sightline pvs build --mpi` fails with a clear message.
pkg_check_modules(GEOS REQUIRED IMPORTED_TARGET geos)
find_package(OpenMP REQUIRED COMPONENTS C)
find_package(MPI COMPONENTS C)

set(SL_REGION_DEPS PkgConfig::GEOS OpenMP::OpenMP_C)
foreach(layer ${SL_FULL_LAYERS}) # never the run-time layers (libsightline_runtime)
  target_link_libraries(sl_layer_${layer} PRIVATE ${SL_REGION_DEPS})
endforeach()
target_link_libraries(sightline PRIVATE ${SL_REGION_DEPS})
target_link_libraries(sightline_static PUBLIC ${SL_REGION_DEPS})
if(MPI_C_FOUND)
  target_compile_definitions(sightline_cli PRIVATE SL_HAVE_MPI=1)
  target_link_libraries(sightline_cli PRIVATE MPI::MPI_C)
endif()
# tools/pvs_mpi.c uses OpenMP pragmas itself (process 0's server and baking threads)
target_link_libraries(sightline_cli PRIVATE OpenMP::OpenMP_C)

# tests/cli/pvs_mpi.sh needs mpiexec: hand its path to every CLI test through the environment.
if(SL_BUILD_TESTS AND TEST cli_pvs_mpi)
  if(MPIEXEC_EXECUTABLE)
    set_property(TEST cli_pvs_mpi APPEND PROPERTY ENVIRONMENT "SL_MPIEXEC=${MPIEXEC_EXECUTABLE}")
  endif()
endif()
