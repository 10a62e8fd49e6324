#!/usr/bin/env bash
# The whole test suite, as CI runs it (README's second command):
#   1. the C API as users meet it (.ci/c_api.sh: header freshness, CMake install to a temporary
#      prefix, examples in C, C++ and Python, C contract tests under valgrind); it installs the
#      tools it needs (cmake, valgrind, pinned cbindgen) when they are missing;
#   2. the comparisons with CGAL's and PCL's Poisson reconstructions (.ci/cpp_tests.sh: C++
#      tests through the installed package; installs libcgal-dev, libpcl-dev, libeigen3-dev and
#      libgtest-dev when missing; refreshes docs/comparisons.md);
#   3. formatting;
#   4. every Rust test in release mode (unit, pipeline, real scans, FFI contract).
# Real-scan tests read ../shared/data (or $PSR_DATA_DIR); they skip with a visible message when
# it is absent, and fail when it is absent under CI=true.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
export PATH="${CARGO_HOME:-$HOME/.cargo}/bin:$PATH"

bash .ci/c_api.sh
bash .ci/cpp_tests.sh
cargo fmt --all -- --check
cargo test --release --all-targets 2>&1
