#!/usr/bin/env bash
# Checks the C API the way its users meet it, on a fresh Debian 12 machine (as root) or a dev box:
#   1. installs what is missing: cmake, a C/C++ compiler, pkg-config, valgrind, python3, and
#      cbindgen at the pinned version;
#   2. checks include/psr.h is what cbindgen generates from src/ffi.rs;
#   3. builds and installs psr with the top-level CMakeLists.txt into a temporary prefix, checks
#      the installed layout and that the SONAME, its links and psrConfig.cmake agree, then MOVES the prefix (relocatability) and deletes the
#      build tree;
#   4. compiles the installed header alone as C99 and C++17 with -Wall -Wextra -Werror;
#   5. builds examples/ and tests/c/ as separate CMake projects with find_package(psr), and the
#      C example once more with pkg-config only;
#   6. runs every example (C shared and static, C++, Python via ctypes with PSR_LIBRARY), the C
#      and C++ ones under valgrind;
#   7. builds a second install with -DPSR_TEST_PANIC=ON and runs the C contract test (shared and
#      static) against it under valgrind, forced panic included.
# Any failure stops the script with a non-zero status.
#
#   .ci/c_api.sh            (KEEP=1 keeps the temporary directory for inspection)
set -euo pipefail

script=c_api.sh
work_prefix=psr-c-api
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
# The pinned cbindgen (Cargo.toml's [workspace.metadata.cbindgen], read by the header script).
CBINDGEN_VERSION="$("$root/scripts/gen_header.sh" --cbindgen-version)"
make_work

# --- 1. tools ----------------------------------------------------------------------------------
step "tools"
missing=()
command -v cmake >/dev/null || missing+=(cmake)
command -v cc >/dev/null || missing+=(gcc libc6-dev)
command -v c++ >/dev/null || missing+=(g++)
command -v make >/dev/null || missing+=(make)
command -v pkg-config >/dev/null || missing+=(pkgconf)
command -v valgrind >/dev/null || missing+=(valgrind)
command -v python3 >/dev/null || missing+=(python3)
command -v readelf >/dev/null || missing+=(binutils)
[ "${#missing[@]}" -eq 0 ] || apt_install "${missing[@]}"
command -v cargo >/dev/null || die "cargo not found: install Rust first"
if [ "$(cbindgen --version 2>/dev/null || true)" != "cbindgen $CBINDGEN_VERSION" ]; then
    echo "installing cbindgen $CBINDGEN_VERSION"
    cargo install cbindgen --version "$CBINDGEN_VERSION" --locked --quiet
fi
cmake --version | head -1
cc --version | head -1
cbindgen --version
valgrind --version

# --- 2. header ---------------------------------------------------------------------------------
step "include/psr.h is fresh"
"$root/scripts/gen_header.sh" "$work/psr.h"
if ! diff -u "$root/include/psr.h" "$work/psr.h" >"$work/header.diff"; then
    head -40 "$work/header.diff"
    die "include/psr.h is stale; refresh it with: scripts/gen_header.sh"
fi

# --- 3. build, install, relocate ---------------------------------------------------------------
# A cargo target dir of its own (kept between runs, gitignored), shared by both installs below so
# the dependencies are compiled once.
cargo_dir="$root/target/c_api"
install_psr() { # install_psr BUILD_DIR PREFIX [cmake args...]
    local build="$1" prefix="$2"
    shift 2
    cmake -S "$root" -B "$build" -DCMAKE_INSTALL_PREFIX="$prefix" -DPSR_CARGO_TARGET_DIR="$cargo_dir" "$@" >/dev/null
    cmake --build "$build"
    cmake --install "$build" >/dev/null
}

step "build and install psr with CMake"
install_psr "$work/build" "$work/staging"
version="$(sed -n 's/^version *= *"\([0-9.]*\)".*/\1/p' "$root/Cargo.toml" | head -1)"
lib="$work/staging/lib"
for f in "$lib/libpsr.so.$version" "$lib/libpsr.a" "$work/staging/include/psr.h" \
    "$lib/cmake/psr/psrConfig.cmake" "$lib/cmake/psr/psrConfigVersion.cmake" "$lib/pkgconfig/psr.pc"; do
    [ -f "$f" ] || die "missing from the install: $f"
done
# The SONAME rule (cargo-c's) is written in CMakeLists.txt alone; here its result is read from
# the library and checked for agreement: a libpsr.so.<leading part of the version> that the
# links and psrConfig.cmake name too.
soname="$(readelf -d "$lib/libpsr.so.$version" | sed -n 's/.*Library soname: \[\(.*\)\]/\1/p')"
abi="${soname#libpsr.so.}"
case "$soname" in libpsr.so.?*) ;; *) die "SONAME is '$soname', want libpsr.so.<ABI version>" ;; esac
case "$version." in "$abi".*) ;; *) die "SONAME $soname: $abi is not a leading part of version $version" ;; esac
[ "$(readlink "$lib/$soname")" = "libpsr.so.$version" ] || die "$soname should link to libpsr.so.$version"
[ "$(readlink "$lib/libpsr.so")" = "$soname" ] || die "libpsr.so should link to $soname"
grep -qF "set(_psr_soname \"$soname\")" "$lib/cmake/psr/psrConfig.cmake" || die "psrConfig.cmake does not give the SONAME $soname"
echo "installed psr $version, SONAME $soname"
if grep -rl -e "$work" -e "$root" "$lib/cmake" "$lib/pkgconfig"; then
    die "the package files above contain absolute build or install paths"
fi
# Relocatable: move the prefix and drop the build tree; everything below uses the moved copy.
prefix="$work/moved/prefix"
mkdir -p "$work/moved"
mv "$work/staging" "$prefix"
rm -rf "$work/build"
lib="$prefix/lib"

# --- 4. header alone ---------------------------------------------------------------------------
step "the installed header compiles alone as C99 and C++17"
printf '#include <psr.h>\nint main(void) { return psr_version_major() == PSR_VERSION_MAJOR ? 0 : 1; }\n' >"$work/alone.c"
for define in "" "-DPSR_TEST_PANIC"; do
    cc -std=c99 -Wall -Wextra -Werror -pedantic $define -I"$prefix/include" -c "$work/alone.c" -o "$work/alone_c.o"
    c++ -std=c++17 -Wall -Wextra -Werror -pedantic $define -I"$prefix/include" -x c++ -c "$work/alone.c" -o "$work/alone_cpp.o"
done

# --- 5. examples and tests as separate projects ------------------------------------------------
step "examples/ with find_package(psr)"
cmake -S "$root/examples" -B "$work/examples" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/examples"

step "tests/c/ with find_package(psr)"
cmake -S "$root/tests/c" -B "$work/tests-c" -DCMAKE_PREFIX_PATH="$prefix" >/dev/null
cmake --build "$work/tests-c"

step "the C example with pkg-config only"
export PKG_CONFIG_PATH="$lib/pkgconfig"
# shellcheck disable=SC2046
cc -std=c99 -Wall -Wextra -Werror -DPSR_EXAMPLE_DATA="\"$root/examples/data/kitten_cgal.ply\"" \
    $(pkg-config --cflags psr) "$root/examples/c/reconstruct.c" -o "$work/reconstruct_pkgconfig" \
    $(pkg-config --libs psr) -Wl,-rpath,"$lib"
"$work/reconstruct_pkgconfig" >/dev/null 2>&1 || die "the pkg-config build of the C example failed"
unset PKG_CONFIG_PATH

# --- 6. run the examples -----------------------------------------------------------------------
# --fair-sched=yes: valgrind runs one thread at a time, and its default lock lets a busy worker
# take it back again and again, so the thread waiting in psr_reconstructor_solve could miss a
# whole stage; the contract test's stop inside the extraction needs that thread to run in it.
vg=(valgrind --fair-sched=yes --leak-check=full --error-exitcode=1 --quiet --suppressions="$root/tests/c/valgrind.supp")
step "run the C example (shared, under valgrind)"
"${vg[@]}" "$work/examples/reconstruct_c" 2>&1
step "run the C example (static)"
"$work/examples/reconstruct_c_static" 2>&1
step "run the C++ example (under valgrind)"
"${vg[@]}" "$work/examples/reconstruct_cpp" 2>&1
step "run the Python example (ctypes, PSR_LIBRARY)"
PSR_LIBRARY="$lib/libpsr.so" python3 "$root/examples/python/reconstruct.py" 2>&1
step "run the C contract test (no test hook)"
"$work/tests-c/contract_shared" | tail -3

# --- 7. contract test with the panic hook, under valgrind --------------------------------------
step "build and install psr with -DPSR_TEST_PANIC=ON"
install_psr "$work/build-panic" "$work/prefix-panic" -DPSR_TEST_PANIC=ON
grep -q 'set(psr_TEST_PANIC ON)' "$work/prefix-panic/lib/cmake/psr/psrConfig.cmake" || die "psr_TEST_PANIC not exported"
cmake -S "$root/tests/c" -B "$work/tests-c-panic" -DCMAKE_PREFIX_PATH="$work/prefix-panic" >/dev/null
cmake --build "$work/tests-c-panic"
step "run the C contract test (shared, under valgrind)"
"${vg[@]}" "$work/tests-c-panic/contract_shared" 2>&1 | tee "$work/contract.log" | tail -4
grep -q "SKIP forced panic" "$work/contract.log" && die "the forced-panic checks did not run"
step "run the C contract test (static, under valgrind)"
"${vg[@]}" "$work/tests-c-panic/contract_static" 2>&1 | tail -2

printf '\nc_api: %d passed, 0 failed (%ds)\n' "$steps" "$((SECONDS - start))"
