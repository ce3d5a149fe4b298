# From-region visibility dependencies (view cells, occluder shrinking, PVS baking): GEOS, OpenMP and
# MPI. Included at the end of CMakeLists.txt, after the targets exist.
#  - GEOS (libgeos-dev): the C API through pkg-config (geos.pc), reentrant _r functions only.
#  - OpenMP (gcc -fopenmp): the PVS bake distributes view cells over threads.
#  - MPI (mpich, libmpich-dev): `mpiexec -n N sightline pvs build ...` distributes cells over
#    processes. Optional at configure time: without it src/region/pvs_mpi.c is compiled with
#    SL_HAVE_MPI undefined and sl_pvs_build_mpi fails with SL_ERROR_UNSUPPORTED.
pkg_check_modules(GEOS REQUIRED IMPORTED_TARGET geos)
find_package(OpenMP REQUIRED COMPONENTS C)
find_package(MPI COMPONENTS C)

set(SL_REGION_DEPS PkgConfig::GEOS OpenMP::OpenMP_C)
if(MPI_C_FOUND)
  list(APPEND SL_REGION_DEPS MPI::MPI_C)
  target_compile_definitions(sightline_objects PRIVATE SL_HAVE_MPI=1)
endif()
target_link_libraries(sightline_objects PRIVATE ${SL_REGION_DEPS})
target_link_libraries(sightline PRIVATE ${SL_REGION_DEPS})
target_link_libraries(sightline_static PUBLIC ${SL_REGION_DEPS})

# tests/cli/pvs_mpi.sh needs mpiexec: hand its path to every CLI test through the environment.
if(SL_BUILD_TESTS AND TEST cli_pvs_mpi)
  if(MPIEXEC_EXECUTABLE)
    set_property(TEST cli_pvs_mpi APPEND PROPERTY ENVIRONMENT "SL_MPIEXEC=${MPIEXEC_EXECUTABLE}")
  endif()
endif()
