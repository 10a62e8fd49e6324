#!/usr/bin/env bash
# Prints the rustup toolchain of the declared minimum Rust: rust-version in Cargo.toml, as a full
# x.y.z release (1.89 -> 1.89.0, the oldest compiler the declaration admits).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
version="$(sed -n 's/^rust-version *= *"\([0-9.]*\)".*/\1/p' "$root/Cargo.toml" | head -1)"
[ -n "$version" ] || { echo "msrv.sh: no rust-version in $root/Cargo.toml" >&2; exit 1; }
case "$version" in *.*.*) ;; *) version="$version.0" ;; esac
echo "$version"
