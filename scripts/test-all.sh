#!/usr/bin/env bash
# The whole test suite, as CI runs it (README's second command). Cheap checks first, so that a
# formatting slip or a lint fails in minutes rather than after the long suites:
#   1. formatting (cargo fmt --check);
#   2. clippy on every target of the workspace, warnings as errors;
#   3. rustdoc of the workspace, warnings as errors (broken intra-doc links and the like);
#   4. the workspace at the declared minimum Rust (rust-version in Cargo.toml): cargo check of
#      every target with that toolchain, in its own target dir (target/msrv) so the main build
#      is not invalidated;
#   5. the C API as users meet it (.ci/c_api.sh: header freshness, CMake install to a temporary
#      prefix, examples in C, C++ and Python, C contract tests under valgrind); it installs the
#      tools it needs (cmake, valgrind, pinned cbindgen) when they are missing;
#   6. the comparisons with CGAL's and PCL's Poisson reconstructions (.ci/cpp_tests.sh: C++
#      tests through the installed package; installs libcgal-dev, libpcl-dev, libeigen3-dev and
#      libgtest-dev when missing; refreshes docs/comparisons.md);
#   7. every Rust test in release mode (unit, pipeline, real scans, FFI contract, CLI);
#   8. the library's unit tests once more in the test profile, whose debug assertions and overflow checks
#      release builds compile out (optimised all the same: [profile.test] opt-level = 3), and the
#      small whole-pipeline tests (bad_input, worker_threads: every stage on small clouds, in
#      seconds), so the pipeline's debug assertions run too. The reconstructions of real scans
#      in tests/ are left to step 7: in this profile they would take far longer;
#   9. the Python package (.ci/python.sh: its wheel built, installed into a fresh virtual
#      environment and tested there with pytest, against the psr program bit for bit; pip
#      install ./python and the package's example; ruff and mypy --strict). It installs
#      python3-venv when missing and pytest, tqdm, trimesh, ruff and mypy into its own venvs;
#  10. the fuzz targets (fuzz/, their own workspace): formatting, clippy with warnings as errors,
#      and every committed corpus and regression input replayed through its target on stable Rust
#      (fuzz/tests/replay.rs), so that past findings stay fixed; fuzzing itself is
#      scripts/fuzz.sh (nightly, libFuzzer), run by hand and recorded in docs/reliability.md;
#  11. sanitizers (.ci/sanitizers.sh, about 2.5 minutes once built, 10 to 15 more for the first
#      build of its four target dirs, std included): the C contract test and the C and C++
#      examples under AddressSanitizer + UndefinedBehaviorSanitizer, the many-hosts stress
#      program (tests/c/stress.c) for 20 s under ASan/UBSan/LeakSanitizer and 20 s under
#      ThreadSanitizer, the Rust FFI tests with the library under ASan, and the threading tests
#      under ThreadSanitizer; it installs what it needs when missing (gcc, g++, a nightly Rust
#      with rust-src);
#  12. psr-mpi (.ci/mpi.sh): the out-of-core reconstruction with its slabs shared by 1 to 4 MPI
#      ranks, its mesh one process's bit for bit, and a rank stopped or killed ending the job; it
#      installs Open MPI and libclang-dev when missing.
# Step 0 installs what steps 1-4 need when it is missing: rustfmt, clippy (rustup components) and
# the minimum toolchain (rustup toolchain install --profile minimal).
# Real-scan tests read ../shared/data (or $PSR_DATA_DIR); they skip with a visible message when
# it is absent, and fail when it is absent under CI=true.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
export PATH="${CARGO_HOME:-$HOME/.cargo}/bin:$PATH"
start=$SECONDS
heading() { printf '\n==== %s (%ds)\n' "$*" "$((SECONDS - start))"; }
# The Rust test runs' output is also kept here, for the closing count of passed and failed tests.
rust_log="$(mktemp)"
trap 'rm -f "$rust_log"' EXIT

msrv="$(bash scripts/msrv.sh)"
heading "0. tools: rustfmt, clippy, Rust $msrv (installed when missing)"
for component in rustfmt clippy; do
    rustup component list --installed 2>/dev/null | grep -q "^$component" || rustup component add "$component"
done
rustup run "$msrv" rustc --version >/dev/null 2>&1 || rustup toolchain install "$msrv" --profile minimal
cargo --version
cargo clippy --version
rustup run "$msrv" rustc --version

heading "1. formatting: cargo fmt --all -- --check"
cargo fmt --all -- --check

heading "2. lints: cargo clippy --workspace --all-targets -- -D warnings"
cargo clippy --workspace --all-targets -- -D warnings

heading "3. docs: cargo doc --workspace --no-deps with RUSTDOCFLAGS=\"-D warnings\""
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps

heading "4. minimum Rust $msrv: cargo +$msrv check --workspace --all-targets"
cargo "+$msrv" check --workspace --all-targets --target-dir target/msrv

heading "5. the C API (.ci/c_api.sh)"
bash .ci/c_api.sh

heading "6. comparisons with CGAL and PCL (.ci/cpp_tests.sh)"
bash .ci/cpp_tests.sh

heading "7. Rust tests, release: cargo test --release --workspace --all-targets"
cargo test --release --workspace --all-targets 2>&1 | tee -a "$rust_log"

heading "8. with debug assertions: cargo test -p psr --lib --test bad_input --test worker_threads"
cargo test -p psr --lib --test bad_input --test worker_threads 2>&1 | tee -a "$rust_log"

heading "9. the Python package (.ci/python.sh)"
bash .ci/python.sh

heading "10. fuzz corpora replayed: cargo test --release --manifest-path fuzz/Cargo.toml"
cargo fmt --manifest-path fuzz/Cargo.toml -- --check
cargo clippy --manifest-path fuzz/Cargo.toml --all-targets --target-dir target/fuzz -- -D warnings
cargo test --release --manifest-path fuzz/Cargo.toml --target-dir target/fuzz 2>&1 | tee -a "$rust_log"

heading "11. sanitizers: ASan, UBSan, LSan and TSan (.ci/sanitizers.sh)"
bash .ci/sanitizers.sh

heading "12. psr-mpi under mpirun (.ci/mpi.sh)"
bash .ci/mpi.sh 2>&1 | tee -a "$rust_log"

heading "all steps passed"
# One closing line over every Rust test run above (steps 7, 8 and 10).
awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($(i) ~ /^passed;?$/) p += $(i - 1); if ($(i) ~ /^failed;?$/) f += $(i - 1) } }
     END { printf "%d passed, %d failed\n", p, f }' "$rust_log"
