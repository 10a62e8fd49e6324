#!/usr/bin/env bash
# Regenerates include/psr.h from src/ffi.rs with the pinned cbindgen.
#   scripts/gen_header.sh           write include/psr.h
#   scripts/gen_header.sh OUT.h     write elsewhere (used by tests/header_fresh.rs)
set -euo pipefail
CBINDGEN_VERSION=0.29.4 # also in cbindgen.toml, tests/header_fresh.rs, .ci/c_api.sh
export PATH="$PATH:${CARGO_HOME:-$HOME/.cargo}/bin"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${1:-$root/include/psr.h}"
if ! command -v cbindgen >/dev/null || [ "$(cbindgen --version)" != "cbindgen $CBINDGEN_VERSION" ]; then
    echo "error: cbindgen $CBINDGEN_VERSION is required; install it with" >&2
    echo "  cargo install cbindgen --version $CBINDGEN_VERSION --locked" >&2
    exit 1
fi
# The whole crate is read (as `cbindgen --crate psr` does, and the before-stop hook with it);
# cbindgen.toml's [export] include/exclude lists keep the core's public items out of the header.
cd "$root"
cbindgen --quiet --config "$root/cbindgen.toml" --crate psr --output "$out"
