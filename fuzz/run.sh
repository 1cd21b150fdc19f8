#!/usr/bin/env bash
# The fuzz campaign: every target (or those named) for SECONDS each, one after another, niced;
# then a table of executions, exec/s and findings per target. See fuzz/README.md.
#
#   fuzz/run.sh [SECONDS] [TARGET ...]       # default: 300 s, every target
#
# Environment: FUZZ_SANITIZER (default `none`: see the README), FUZZ_NICE (default 10).
set -euo pipefail

root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
secs="${1:-300}"
shift || true
all=(decode ply pcd scene pointcloud2 mcap)
targets=("${@:-${all[@]}}")
sanitizer="${FUZZ_SANITIZER:-none}"
nice_level="${FUZZ_NICE:-10}"

# Largest input per target [bytes]: datagram-sized messages, small files, one small recording.
max_len() {
    case "$1" in
        decode) echo 4096 ;;
        ply | pcd) echo 16384 ;;
        scene | pointcloud2) echo 8192 ;;
        mcap) echo 131072 ;;
        *) echo 4096 ;;
    esac
}

command -v cargo-fuzz >/dev/null || {
    echo "cargo-fuzz is not installed: cargo install cargo-fuzz --locked" >&2
    exit 2
}
for t in "${targets[@]}"; do
    [[ -d "fuzz/seeds/$t" ]] || { echo "unknown target '$t' (no fuzz/seeds/$t); targets: ${all[*]}" >&2; exit 2; }
    # libFuzzer writes new inputs to the first directory; it must exist (it does not create it).
    mkdir -p "fuzz/corpus/$t" "fuzz/artifacts/$t" "fuzz/logs"
done

nice -n "$nice_level" cargo +nightly fuzz build -s "$sanitizer"

rows=()
for t in "${targets[@]}"; do
    log="fuzz/logs/$t.log"
    before=$(find "fuzz/artifacts/$t" -type f | wc -l)
    start=$(date +%s)
    set +e
    nice -n "$nice_level" cargo +nightly fuzz run -s "$sanitizer" "$t" "fuzz/corpus/$t" "fuzz/seeds/$t" -- \
        -max_total_time="$secs" -max_len="$(max_len "$t")" -timeout=10 -rss_limit_mb=2048 \
        -print_final_stats=1 >"$log" 2>&1
    rc=$?
    set -e
    # libFuzzer's own time (the build, if cargo had to redo it, is left out).
    elapsed=$(grep -o 'runs in [0-9]* second' "$log" | grep -o '[0-9]*' | tail -1 || true)
    elapsed="${elapsed:-$(( $(date +%s) - start ))}"
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1 || true)
    rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1 || true)
    corpus=$(find "fuzz/corpus/$t" -type f | wc -l)
    found=$(( $(find "fuzz/artifacts/$t" -type f | wc -l) - before ))
    if [[ $rc -ne 0 && $found -eq 0 ]]; then found="exit $rc (see $log)"; fi
    rows+=("$(printf '| %-11s | %6s | %12s | %8s | %6s | %s |' "$t" "$elapsed" "${execs:-?}" "${rate:-?}" "$corpus" "$found")")
    echo "$t: ${elapsed} s, ${execs:-?} executions, ${rate:-?} exec/s, corpus $corpus, findings $found" >&2
done

echo
echo "| target      | s      | executions   | exec/s   | corpus | findings |"
echo "|-------------|--------|--------------|----------|--------|----------|"
printf '%s\n' "${rows[@]}"
