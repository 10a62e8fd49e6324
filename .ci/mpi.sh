#!/usr/bin/env bash
# Checks psr-mpi, the reconstruction out of core with its slabs shared by MPI ranks (issue 21;
# cli/src/bin/psr-mpi.rs, built with psr-cli's `mpi` feature):
#   1. tools: Open MPI (libopenmpi-dev, openmpi-bin) and libclang-dev (the mpi crate's bindings
#      are generated from mpi.h), installed when missing;
#   2. clippy on psr-cli with the feature, warnings as errors;
#   3. cli/tests/mpi.rs: mpirun with 1 to 4 ranks on a sphere, the bunny (also with the screening
#      following its noise) and the Happy Buddha
#      (the mesh of psr --out-of-core with the same slabs, bit for bit), a rank stopped and a rank
#      killed (the job ends, no hang), a temporary directory or output each rank sees its own of
#      (a tmpfs in a mount namespace per rank, as nodes with their own /tmp; refused with the
#      reason). More ranks than this machine's cores (--oversubscribe),
#      root allowed (--allow-run-as-root); one test at a time, since each runs up to 4 ranks.
#
#   .ci/mpi.sh
set -euo pipefail

script=mpi.sh
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
cd "$root"

step "tools: Open MPI and libclang"
missing=()
command -v mpirun >/dev/null || missing+=(openmpi-bin)
command -v mpicc >/dev/null || missing+=(libopenmpi-dev)
# libclang alone (libclang1-*, which other packages pull in) is not enough: bindgen also needs
# clang's own headers (stddef.h), which come with libclang-dev.
ls /usr/lib/llvm-*/lib/clang/*/include/stddef.h >/dev/null 2>&1 || missing+=(libclang-dev)
[ "${#missing[@]}" -eq 0 ] || apt_install "${missing[@]}"
mpirun --version | head -1

step "lints: cargo clippy -p psr-cli --all-targets --features mpi -- -D warnings"
cargo clippy -p psr-cli --all-targets --features mpi -- -D warnings

step "psr-mpi under mpirun: cargo test --release -p psr-cli --features mpi --test mpi"
cargo test --release -p psr-cli --features mpi --test mpi -- --test-threads 1
