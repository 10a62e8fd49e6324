#!/usr/bin/env bash
# Fuzzes one target of fuzz/ (ply_reader, c_api, reconstruct) for SECONDS with libFuzzer under
# AddressSanitizer (cargo-fuzz's default; LeakSanitizer included), then minimises its corpus,
# so that fuzz/corpus/TARGET keeps the smallest set of inputs that reach the coverage found.
#
#   bash scripts/fuzz.sh TARGET SECONDS [JOBS]
#
# Needs the nightly toolchain and cargo-fuzz (installed here when missing). A crash, leak,
# timeout or out-of-memory leaves its input in fuzz/artifacts/TARGET/ and makes this script
# fail; fix the cause, then copy the input into fuzz/regressions/TARGET/ under a name that says
# what it found, so that the replay test (fuzz/tests/replay.rs, run by CI) keeps it fixed (the
# corpus is minimised after every run and may drop it). Record the run in docs/reliability.md.
set -euo pipefail
target=${1:?usage: scripts/fuzz.sh TARGET SECONDS [JOBS]}
seconds=${2:?usage: scripts/fuzz.sh TARGET SECONDS [JOBS]}
jobs=${3:-1}
cd "$(dirname "$0")/../fuzz"
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked
# Per run: an input may take 20 s (a slow unit is a finding) and 4 GiB (a larger allocation is
# a finding: no input of these sizes needs it).
log=$(mktemp)
trap 'rm -f "$log"' EXIT
started=$(date +%s)
status=0
# With several jobs libFuzzer writes each job's output to fuzz-N.log; they are collected below.
parallel=()
[ "$jobs" -gt 1 ] && parallel=(-jobs="$jobs" -workers="$jobs")
rm -f fuzz-*.log
cargo +nightly fuzz run --features libfuzzer "$target" "corpus/$target" -- \
    -max_total_time="$seconds" -timeout=20 -rss_limit_mb=4096 "${parallel[@]}" \
    -print_final_stats=1 2>&1 | tee "$log" | grep -E "^#[0-9]+ +(DONE|pulse)|ERROR|SUMMARY|Test unit written" || true
cat fuzz-*.log >> "$log" 2>/dev/null || true
rm -f fuzz-*.log
grep -q -E "ERROR: (libFuzzer|AddressSanitizer|LeakSanitizer)|SUMMARY: " "$log" && status=1
elapsed=$(( $(date +%s) - started ))
runs=$(grep -E "stat::number_of_executed_units" "$log" | awk '{s += $2} END {print s + 0}')
cargo +nightly fuzz cmin --features libfuzzer "$target" "corpus/$target" >/dev/null 2>&1 || true
echo "fuzz $target: ${elapsed} s, ${runs} inputs run, corpus $(ls "corpus/$target" | wc -l) files," \
    "$([ $status = 0 ] && echo "no finding" || echo "FINDING in fuzz/artifacts/$target")"
exit $status
