#!/usr/bin/env bash
# Regenerates include/psr.h from src/ffi.rs with the pinned cbindgen.
# Its version is written once, in Cargo.toml's [workspace.metadata.cbindgen].
#   scripts/gen_header.sh                     write include/psr.h
#   scripts/gen_header.sh OUT.h               write elsewhere (used by tests/header_fresh.rs)
#   scripts/gen_header.sh --cbindgen-version  print the pinned version (for .ci/c_api.sh and
#                                             tests/header_fresh.rs)
set -euo pipefail
export PATH="$PATH:${CARGO_HOME:-$HOME/.cargo}/bin"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
CBINDGEN_VERSION="$(awk -F'"' '/^\[/ { section = $0 }
    section == "[workspace.metadata.cbindgen]" && /^version *=/ { print $2; exit }' "$root/Cargo.toml")"
if [ -z "$CBINDGEN_VERSION" ]; then
    echo "error: no version = \"...\" under [workspace.metadata.cbindgen] in $root/Cargo.toml" >&2
    exit 1
fi
if [ "${1:-}" = --cbindgen-version ]; then
    echo "$CBINDGEN_VERSION"
    exit 0
fi
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
