#!/usr/bin/env bash
# Compares psr's meshes with CGAL's and PCL's Poisson reconstructions (cpp_tests/), on a fresh
# Debian 12 machine (as root) or a dev box:
#   1. installs what is missing: libcgal-dev, libeigen3-dev, libpcl-dev, libgtest-dev, cmake,
#      g++, make (apt-get update first; if the install fails, apt-get --fix-broken install and
#      one retry);
#   2. builds and installs psr with the top-level CMakeLists.txt into a temporary prefix, with
#      the same cmake invocation and cargo target directory as .ci/c_api.sh;
#   3. configures cpp_tests/ as a separate CMake project with find_package(psr CONFIG REQUIRED)
#      against that prefix, builds it with -O2, and runs ctest --output-on-failure;
#   4. when every test passed and every input ran, writes the comparison tables the tests
#      printed to docs/comparisons.md (and prints them).
# Any failure stops the script with a non-zero status. Real point sets come from
# ../shared/data (or $PSR_DATA_DIR): missing files skip their test with a message, or fail it
# when CI is set.
#
#   .ci/cpp_tests.sh        (KEEP=1 keeps the temporary directory; JOBS=N compiles N at a time)
set -euo pipefail

script=cpp_tests.sh
work_prefix=psr-cpp-tests
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
make_work

# --- 1. packages -------------------------------------------------------------------------------
step "packages"
installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
missing=()
for pkg in libcgal-dev libeigen3-dev libpcl-dev libgtest-dev cmake g++ make; do
    installed "$pkg" || missing+=("$pkg")
done
[ "${#missing[@]}" -eq 0 ] || apt_install "${missing[@]}"
command -v cargo >/dev/null || die "cargo not found: install Rust first"
for pkg in libcgal-dev libpcl-dev libgtest-dev; do
    printf '%s %s\n' "$pkg" "$(dpkg-query -W -f='${Version}' "$pkg")"
done
cmake --version | head -1

# --- 2. psr, installed as .ci/c_api.sh installs it ---------------------------------------------
step "build and install psr with CMake"
# The cargo target directory of .ci/c_api.sh (kept between runs, gitignored): when that script
# ran first, the library is already built.
cargo_dir="$root/target/c_api"
prefix="$work/prefix"
cmake -S "$root" -B "$work/build" -DCMAKE_INSTALL_PREFIX="$prefix" -DPSR_CARGO_TARGET_DIR="$cargo_dir" >/dev/null
cmake --build "$work/build"
cmake --install "$work/build" >/dev/null
[ -f "$prefix/lib/cmake/psr/psrConfig.cmake" ] || die "psr's CMake package is missing from $prefix"

# --- 3. cpp_tests/ as a separate project -------------------------------------------------------
step "configure cpp_tests/ with find_package(psr)"
cmake -S "$root/cpp_tests" -B "$work/cpp_tests" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release

step "build cpp_tests/ (-O2)"
cmake --build "$work/cpp_tests" --parallel "${JOBS:-2}"

step "run the tests"
tables="$work/comparisons"
mkdir -p "$tables"
status=0
(cd "$work/cpp_tests" && PSR_COMPARISONS_DIR="$tables" ctest --output-on-failure) || status=$?

# --- 4. docs/comparisons.md --------------------------------------------------------------------
step "comparison tables"
shopt -s nullglob
sections=("$tables"/*.md)
expected=5 # sphere, torus, kitten, oni, bunny
if [ "${#sections[@]}" -gt 0 ]; then
    out="$work/comparisons.md"
    {
        echo "# psr, CGAL and PCL compared"
        echo
        echo "Written by \`.ci/cpp_tests.sh\` from the tables the tests in \`cpp_tests/compare_test.cpp\` print;"
        echo "do not edit by hand. Latest run: $(date -u '+%Y-%m-%d %H:%M UTC'), psr $(git -C "$root" describe --always --dirty 2>/dev/null || echo unknown),"
        echo "CGAL $(dpkg-query -W -f='${Version}' libcgal-dev), PCL $(dpkg-query -W -f='${Version}' libpcl-dev),"
        echo "$(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1), $(nproc) cores (shared: times are indicative only)."
        echo
        echo "Each input goes to the three reconstructions with every parameter set (listed under each"
        echo "heading; psr and PCL share the octree parameters, CGAL's facets are bounded by the same octree"
        echo "cell). The meshes are measured by the same code (\`cpp_tests/mesh_metrics.hpp\`): topology"
        echo "(closed = every edge in exactly two triangles; boundary and non-manifold edges; vertices whose"
        echo "triangles form more than one fan; edges whose two triangles disagree on orientation;"
        echo "components; Euler characteristic χ), area, signed volume, and distances between 100,000"
        echo "area-uniform samples (fixed seed) of one surface and the other surface (exact point-to-triangle"
        echo "distances), in thousandths of the input's bounding-box diagonal."
        echo
        for f in "${sections[@]}"; do
            cat "$f"
            echo
        done
    } >"$out"
    cat "$out"
    if [ "$status" -eq 0 ] && [ "${#sections[@]}" -eq "$expected" ]; then
        cp "$out" "$root/docs/comparisons.md"
        echo "wrote docs/comparisons.md"
    else
        echo "docs/comparisons.md not updated: ${#sections[@]} of $expected inputs ran, ctest status $status"
    fi
fi

[ "$status" -eq 0 ] || die "ctest failed (status $status)"
printf '\ncpp_tests: passed (%ds)\n' "$((SECONDS - start))"
