#!/usr/bin/env bash
# scalemesh set-up on Debian 12, as root: installs the Debian packages that are
# missing, configures and builds, then
#   bash setup.sh        runs the default sample case (cases/tube)
#   bash setup.sh test   runs the whole test suite with ctest, then its fast
#                        part again built with the sanitizers, then the fuzz
#                        targets for a short while (needs clang)
#   bash setup.sh bench  runs the benchmarks in bench/
# Both are idempotent: with nothing missing and nothing changed they only
# re-check the packages and let the build find nothing to do.
set -euo pipefail
cd "$(dirname "$0")"

packages=(
  cmake ninja-build g++ pkg-config dpkg-dev
  libopenvdb-dev libboost-iostreams-dev libembree-dev libcgal-dev libgmsh-dev libtbb-dev
  libboost-dev libtomlplusplus-dev libcli11-dev nlohmann-json3-dev
  libinsighttoolkit5-dev libgdcm-tools zlib1g-dev
  libtinyobjloader-dev libexpat1-dev libpng-dev
  googletest libgtest-dev libbenchmark-dev
  clang libclang-rt-14-dev
  openfoam python3
  pybind11-dev python3-dev python3-gmsh python3-numpy python3-meshio
  gmsh
  locales time
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

build=build
if [ ! -f "$build/build.ninja" ]; then
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
fi
cmake --build "$build"

case "${1:-run}" in
  run)
    "$build/src/cli/scalemesh" run cases/tube
    ;;
  test)
    ctest --test-dir "$build" --output-on-failure -j "$(nproc)" --timeout 900
    # The fast part of the suite again, and a short bounded libFuzzer run of
    # every importer and of the case-file parser from its seeds
    # (docs/fuzzing.md has the long campaigns), from one clang build with
    # AddressSanitizer, UndefinedBehaviorSanitizer and libFuzzer's coverage
    # (any report fails the test). Leak checking is off in the suite: the Gmsh
    # SDK keeps allocations until the process ends. clang at -O1 with line
    # tables only builds it in a third of GCC's -O2 -g time (570 s against
    # 1713 s on 2 cores), and its UBSan checks at least as much; -O1 is also
    # libFuzzer's own advice. One build for both saves building every library
    # twice.
    sanitize=build-sanitize
    if [ ! -f "$sanitize/build.ninja" ]; then
      CC=clang CXX=clang++ cmake -S . -B "$sanitize" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
        -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only -DNDEBUG" \
        -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only -DNDEBUG" -DSCALEMESH_FUZZ=ON -DSCALEMESH_BENCH=OFF \
        -DSCALEMESH_TEST_DRIVER_FLAGS=-O0
    fi
    fast_targets=$(sed -n 's/^scalemesh_test(\([a-z_]*\) FAST.*/\1/p' tests/*/CMakeLists.txt)
    # shellcheck disable=SC2086
    cmake --build "$sanitize" --target $fast_targets fuzzers
    ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
      ctest --test-dir "$sanitize" --output-on-failure -j "$(nproc)" --timeout 900 -L fast
    ctest --test-dir "$sanitize" --output-on-failure -j "$(nproc)" -L fuzz
    ;;
  bench)
    "$build/bench/bench_surface" bench-surface.json
    "$build/bench/bench_export" 1.5 bench-export.json
    # Issue 9: the whole pipeline against image size, with references; it
    # regenerates docs/performance.md and its plot (gnuplot draws the plot).
    command -v gnuplot >/dev/null || { apt-get update -qq && apt-get install -y -qq --no-install-recommends gnuplot-nox >/dev/null; }
    "$build/bench/bench_pipeline" --json bench-pipeline.json --plot docs/performance.png \
      --doc docs/performance.md --notes bench/performance-notes.md
    ;;
  validate)
    # Issue 31: CFD validation on the straight tube, scalemesh at several M
    # against an isotropic Gmsh tet mesh and snappyHexMesh with wall layers at
    # matched cell counts (simpleFoam, wallShearStress, Hagen-Poiseuille);
    # regenerates docs/validation.md and validation/results.json, results.csv,
    # tube.png with the schemes scalemesh writes (about 25 minutes).
    # Then issue 31 item 2: a curved tube (Dean flow) and the stenosis phantom
    # at M = 5 ... 28 against a Richardson-extrapolated reference; regenerates
    # its own section of docs/validation.md and validation/curved_results.json,
    # curved.png (about 20 minutes on 2 cores, most of it the M = 28 bend).
    for p in python3-gmsh gnuplot-nox python3-netgen; do
      dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || {
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$p" >/dev/null
      }
    done
    /usr/bin/python3 validation/tube_validation.py --scalemesh "$build/src/cli/scalemesh"
    /usr/bin/python3 validation/curved_validation.py --scalemesh "$build/src/cli/scalemesh" --jobs 2
    # Issue 41: scale invariance in the flow. The stepped tube (8, 4, 2, 1 mm
    # in series) and a symmetric tree of 4 generations (6 mm down to 1.3 mm),
    # scalemesh with the paper's Delaunay layers and with prism layers at
    # several M, against Gmsh (uniform, and sized from curvature), CGAL
    # Mesh_3 (uniform, and sized from the centreline's radius; its tool is
    # built here, outside the default build) and, on the stepped tube,
    # snappyHexMesh with a refinement level per segment, and Netgen sized
    # from the STL's curvature with 3 prism layers; each run merged
    # into validation/multiscale_results.json as it ends, then the sections
    # of docs/validation.md and docs/multiscale.png regenerated from it.
    cmake --build "$build" --target mesh3_surface
    /usr/bin/python3 validation/multiscale_validation.py --scalemesh "$build/src/cli/scalemesh" \
      --mesh3-surface "$build/validation/mesh3_surface" --M 5 7 10 14 --layers delaunay prisms --gmsh-h 0.8 \
      --gmsh-curvature 20 32 --snappy 8 12 --mesh3-h 0.8 --mesh3-radius 0.4 0.3 0.2 --netgen-curvature 4 6 \
      --workdir "$build/multiscale-stepped" --out validation
    /usr/bin/python3 validation/multiscale_validation.py --scalemesh "$build/src/cli/scalemesh" \
      --mesh3-surface "$build/validation/mesh3_surface" --geometry tree --M 5 7 10 --layers delaunay prisms \
      --gmsh-h 0.5 --gmsh-curvature 16 24 --mesh3-h 0.6 --mesh3-radius 0.4 0.3 --netgen-curvature 4 6 \
      --workdir "$build/multiscale-tree" --out validation --doc docs/validation.md --plot docs/multiscale.png
    ;;
  *)
    echo "usage: bash setup.sh [run|test|bench|validate]" >&2
    exit 2
    ;;
esac
