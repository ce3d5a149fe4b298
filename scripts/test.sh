#!/usr/bin/env bash
# Quick start, second command: build with -Werror and run every test through CTest.
# With --sanitize it does the same in an ASan+UBSan build (build-asan/). With --tsan it builds with
# clang and ThreadSanitizer (build-tsan/) and runs the tests that share a BVH, a scene or an oracle
# between threads (pthreads and OpenMP bakes); OpenMP runs with LLVM's libomp and its Archer tool,
# which tells TSan about OpenMP's barriers and locks.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
dir=build-test
flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DSL_WERROR=ON)
if [ "${1:-}" = "--sanitize" ]; then
  dir=build-asan
  flags=(-DCMAKE_BUILD_TYPE=Debug -DSL_WERROR=ON -DSL_SANITIZE=ON -DSL_BUILD_BENCH=OFF)
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  export SL_SANITIZED=1
  # assimp itself leaks on some malformed inputs; our own memory is checked by counting allocators
  export LSAN_OPTIONS=suppressions=$PWD/tests/lsan.supp
fi
tests=
if [ "${1:-}" = "--tsan" ]; then
  dir=build-tsan
  export CC=clang
  flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DSL_WERROR=ON -DSL_TSAN=ON -DSL_BUILD_BENCH=OFF)
  # Embree's TBB worker threads are not instrumented: tests/tsan.supp names what it hides
  export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 ignore_noninstrumented_modules=1 suppressions=$PWD/tests/tsan.supp"
  archer=/usr/lib/llvm-14/lib/libarcher.so
  [ -e "$archer" ] && export OMP_TOOL_LIBRARIES="$archer" ARCHER_OPTIONS=verbose=0
  export SL_SANITIZED=1
  # the tests whose threads share a BVH, a scene, an oracle or a rasterizer (README, "ThreadSanitizer")
  tests='^(test_bvh|test_oracle|test_raster|test_pvs_build|test_portal|test_domain|test_near_wall|test_bench|test_embree_scene|test_gvs|test_shared_accel|test_backend|test_net)$'
fi
cmake -S . -B "$dir" "${flags[@]}" >/dev/null
if [ -n "$tests" ]; then
  # only the programs those tests run (and the command, which some of them call)
  cmake --build "$dir" -j"$(nproc)" --target sightline_cli $(echo "$tests" | tr -d '^()$' | tr '|' ' ')
  cd "$dir"
  ctest --output-on-failure -j"$(nproc)" -R "$tests"
  exit
fi
cmake --build "$dir" -j"$(nproc)"
cd "$dir"
ctest --output-on-failure -j"$(nproc)"
