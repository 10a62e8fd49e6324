#!/usr/bin/env bash
# Runs the C API's users and the Rust FFI and threading tests under sanitizers, on a fresh
# Debian 12 machine (as root) or a dev box:
#   1. installs what is missing: gcc and g++ (Debian's gcc brings the ASan, UBSan, LSan and TSan
#      runtimes) and a nightly Rust with rust-src (PSR_NIGHTLY picks another, e.g.
#      nightly-2026-01-15, should a nightly break the -Z flags below);
#   2. builds libpsr.so with stable cargo, feature test-panic (the forced-panic hook), in
#      target/sanitize; the library itself is not instrumented here (steps 5 and 6 do that):
#      these runs check the C side and, through LeakSanitizer's malloc interception, that
#      nothing the library allocates for a C caller is leaked or freed twice;
#   3. compiles the C contract test (tests/c/contract.c, -DPSR_TEST_PANIC), the C example and the
#      C++ example with -fsanitize=address,undefined -fno-sanitize-recover=all, and runs them
#      (leak detection on);
#   4. runs the many-hosts stress program (tests/c/stress.c) built the same way, 4 threads for
#      STRESS_SECONDS (default 20) seconds: random parameters, thread counts, cancellations,
#      frees and handle moves, every completed mesh checked bit for bit against a one-handle
#      reference;
#   5. the Rust FFI tests with the library instrumented by AddressSanitizer (nightly,
#      -Zsanitizer=address, LeakSanitizer included): ffi_contract, ffi_threads and bad_input;
#   6. ThreadSanitizer (nightly, -Zsanitizer=thread -Zbuild-std, so std and rayon are
#      instrumented too) on the tests about threads, about 12 of them, seconds each: the unit
#      tests of src/parallel.rs (the unsafe disjoint writes, directly) and those whose names say
#      "thread" (deterministic CG at several thread counts, an implicit handle shared between
#      threads), ffi_contract's (two handles on two threads, one mesh trimmed and one implicit
#      function evaluated from many threads at once, the progress callback's thread),
#      ffi_threads (workers joined before solve returns) and worker_threads (joined on a panic
#      too). These run whole reconstructions at 1 to 4 worker threads, so every stage's
#      parallel loops run under TSan. The long pipeline suites stay out: instrumented, they
#      would take far longer than this step should;
#   7. the stress program under ThreadSanitizer, 4 threads for STRESS_SECONDS seconds, with
#      libpsr.so itself built with -Zsanitizer=thread -Zbuild-std: races between the host's
#      threads, psr's workers and handles passed between threads. A process must hold exactly
#      one TSan runtime, the one the library was instrumented for, and gcc 12's libtsan lacks
#      entry points that nightly's LLVM emits (__tsan_memset, __tsan_memcpy, __tsan_memmove); so
#      the program is compiled with gcc -fsanitize=thread (same __tsan_* calls) but linked with
#      the nightly toolchain's own TSan runtime (librustc-nightly_rt.tsan.a), exported with
#      -rdynamic for the library to find.
# A run fails on a non-zero exit or any sanitizer report in its output; each prints a one-line
# summary (counts and seconds), and all of them are repeated at the end.
#
#   .ci/sanitizers.sh   (KEEP=1 keeps the temporary directory; STRESS_SECONDS=N and STRESS_SEED=N
#                        change the stress runs, PSR_NIGHTLY the toolchain)
set -euo pipefail

script=sanitizers.sh
work_prefix=psr-sanitizers
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
cd "$root"
make_work
nightly="${PSR_NIGHTLY:-nightly}"
stress_seconds="${STRESS_SECONDS:-20}"
host="$(rustc -vV | sed -n 's/^host: //p')"
summaries=()

# run NAME LOG COUNTS-COMMAND -- COMMAND...: runs COMMAND with its output in LOG, fails on a
# non-zero exit or any sanitizer report in LOG, else prints "NAME: <counts>, 0 reports (Ns)"
# where <counts> is what COUNTS-COMMAND (a shell snippet reading $log) prints.
run() {
    local name="$1" log="$2" counts="$3" t0=$SECONDS rc=0 reports
    shift 4
    "$@" >"$log" 2>&1 || rc=$?
    reports="$(grep -cE 'ERROR: (Address|Leak)Sanitizer|WARNING: ThreadSanitizer|runtime error:|SUMMARY: UndefinedBehaviorSanitizer' "$log" || true)"
    if [ "$rc" -ne 0 ] || [ "$reports" -ne 0 ]; then
        grep -nE 'Sanitizer|runtime error:|FAIL|panicked' "$log" | head -20 || true
        tail -60 "$log"
        die "$name: exit status $rc, $reports sanitizer report(s); full log above (KEEP=1 keeps $log)"
    fi
    local line
    line="$name: $(log="$log" bash -c "$counts"), 0 reports ($((SECONDS - t0))s)"
    echo "$line"
    summaries+=("$line")
}

# Counts of Rust test runs: the "test result:" lines added up.
rust_counts='awk "/^test result:/ { for (i = 1; i <= NF; i++) { if (\$i ~ /^passed;?\$/) p += \$(i - 1); if (\$i ~ /^failed;?\$/) f += \$(i - 1) } } END { printf \"%d passed, %d failed\", p, f }" "$log"'

# --- 1. tools ----------------------------------------------------------------------------------
step "tools"
missing=()
command -v cc >/dev/null || missing+=(gcc libc6-dev)
command -v c++ >/dev/null || missing+=(g++)
[ "${#missing[@]}" -eq 0 ] || apt_install "${missing[@]}"
command -v cargo >/dev/null || die "cargo not found: install Rust first"
if ! rustup run "$nightly" rustc --version >/dev/null 2>&1; then
    rustup toolchain install "$nightly" --profile minimal --component rust-src
fi
rustup component list --toolchain "$nightly" --installed 2>/dev/null | grep -q '^rust-src' ||
    rustup component add rust-src --toolchain "$nightly"
cc --version | head -1
c++ --version | head -1
rustup run "$nightly" rustc --version

# --- 2. the library ----------------------------------------------------------------------------
step "build libpsr.so (release, test-panic) in target/sanitize"
cargo build --release -p psr --features test-panic --target-dir target/sanitize
lib="$root/target/sanitize/release"
[ -f "$lib/libpsr.so" ] || die "no $lib/libpsr.so"

# --- 3. C and C++ under ASan + UBSan -----------------------------------------------------------
san=(-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer -g -O1)
link=(-L"$lib" -lpsr -Wl,-rpath,"$lib" -lpthread -lm)
export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:strict_string_checks=1:check_initialization_order=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
data="\"$root/examples/data/kitten_cgal.ply\""

step "the C contract test, the C and C++ examples under ASan + UBSan"
cc -std=c99 -Wall -Wextra -Werror "${san[@]}" -DPSR_TEST_PANIC -Iinclude tests/c/contract.c -o "$work/contract" "${link[@]}"
cc -std=c99 -Wall -Wextra -Werror "${san[@]}" -DPSR_EXAMPLE_DATA="$data" -Iinclude examples/c/reconstruct.c -o "$work/example_c" "${link[@]}"
c++ -std=c++17 -Wall -Wextra -Werror "${san[@]}" -DPSR_EXAMPLE_DATA="$data" -Iinclude examples/cpp/reconstruct.cpp -o "$work/example_cpp" "${link[@]}"
run "C contract (asan+ubsan)" "$work/contract.log" \
    'tail -1 "$log" | tr -d "\n"' -- "$work/contract"
grep -q "SKIP forced panic" "$work/contract.log" && die "the forced-panic checks did not run"
run "C example (asan+ubsan)" "$work/example_c.log" \
    'printf "%s vertices, %s triangles" "$(sed -n "s/^vertices: //p" "$log")" "$(sed -n "s/^triangles: //p" "$log")"' \
    -- "$work/example_c"
run "C++ example (asan+ubsan)" "$work/example_cpp.log" \
    'printf "%s vertices, %s triangles" "$(sed -n "s/^vertices: //p" "$log")" "$(sed -n "s/^triangles: //p" "$log")"' \
    -- "$work/example_cpp"

# --- 4. the stress program ---------------------------------------------------------------------
step "the stress program under ASan + UBSan + LSan: 4 threads, $stress_seconds s"
cc -std=c99 -Wall -Wextra -Werror "${san[@]}" -Iinclude tests/c/stress.c -o "$work/stress" "${link[@]}"
run "stress, 4 threads x ${stress_seconds}s (asan+ubsan+lsan)" "$work/stress.log" \
    'sed -n "s/^stress: [0-9]* threads x [0-9.]* s (seed [0-9]*): //p" "$log" | tr -d "\n"' \
    -- "$work/stress" --threads 4 --seconds "$stress_seconds" --seed "${STRESS_SEED:-1}"

# --- 5. Rust FFI tests, library under ASan -----------------------------------------------------
step "Rust FFI tests with -Zsanitizer=address (nightly)"
unset ASAN_OPTIONS UBSAN_OPTIONS
run "Rust ffi_contract, ffi_threads, bad_input (asan)" "$work/rust-asan.log" "$rust_counts" -- \
    env RUSTFLAGS="-Zsanitizer=address" ASAN_OPTIONS="detect_leaks=1" \
    cargo "+$nightly" test --release -p psr --features test-panic --target "$host" --target-dir target/asan \
    --test ffi_contract --test ffi_threads --test bad_input

# --- 6. threading tests under TSan -------------------------------------------------------------
step "Rust threading tests with -Zsanitizer=thread -Zbuild-std (nightly)"
run "Rust threading tests (tsan)" "$work/rust-tsan.log" "$rust_counts" -- \
    env RUSTFLAGS="-Zsanitizer=thread" TSAN_OPTIONS="halt_on_error=1" \
    cargo "+$nightly" test -Zbuild-std --release -p psr --target "$host" --target-dir target/tsan \
    --lib --test ffi_contract --test ffi_threads --test worker_threads -- thread workers parallel::

# --- 7. the stress program under TSan ----------------------------------------------------------
step "the stress program under TSan (library built with -Zsanitizer=thread): 4 threads, $stress_seconds s"
# A target dir apart from step 6's: with -Zbuild-std, `cargo test` builds the library against
# one more sysroot crate (test) than `cargo build` does, under the same name, so in one target
# dir each would rebuild psr (over a minute) every time the other ran.
env RUSTFLAGS="-Zsanitizer=thread" \
    cargo "+$nightly" build -Zbuild-std --release -p psr --target "$host" --target-dir target/tsan-lib
tsan_lib="$root/target/tsan-lib/$host/release"
tsan_rt="$(ls "$(rustup run "$nightly" rustc --print sysroot)/lib/rustlib/$host/lib/"librustc-*_rt.tsan.a | head -1)"
[ -f "$tsan_rt" ] || die "no TSan runtime in the $nightly toolchain"
cc -std=c99 -Wall -Wextra -Werror -fsanitize=thread -g -O1 -Iinclude -c tests/c/stress.c -o "$work/stress-tsan.o"
cc "$work/stress-tsan.o" -o "$work/stress-tsan" -Wl,--whole-archive "$tsan_rt" -Wl,--no-whole-archive -rdynamic \
    -L"$tsan_lib" -lpsr -Wl,-rpath,"$tsan_lib" -lpthread -lm -ldl -lstdc++
run "stress, 4 threads x ${stress_seconds}s (tsan)" "$work/stress-tsan.log" \
    'sed -n "s/^stress: [0-9]* threads x [0-9.]* s (seed [0-9]*): //p" "$log" | tr -d "\n"' \
    -- env TSAN_OPTIONS="halt_on_error=1" "$work/stress-tsan" --threads 4 --seconds "$stress_seconds" --seed "${STRESS_SEED:-1}"

printf '\n'
printf '%s\n' "${summaries[@]}"
printf 'sanitizers: %d runs, 0 reports (%ds)\n' "${#summaries[@]}" "$((SECONDS - start))"
