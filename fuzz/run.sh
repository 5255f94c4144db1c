#!/usr/bin/env bash
# Builds every fuzz target and runs each (or the TARGETs given: `run.sh SECONDS [TARGET...]`)
# for SECONDS (default 10), then prints one JSON line per
# target: {"bench":"fuzz_execs","target":T,"ours":EXECS,"reference":0,"unit":"execs","crashes":N}.
# Exits 1 when any target crashed (the input is in fuzz/artifacts/T/, the log in
# fuzz/logs/T.log), 2 when the build fails.
#
# Each target starts from seeds/T (real files and the parsers' test strings; never written to)
# and grows corpus/T (not committed). Needs cargo-fuzz (`cargo install cargo-fuzz --locked`);
# RUSTC_BOOTSTRAP=1 lets the stable toolchain build with the sanitizer flags cargo-fuzz uses.
set -uo pipefail
cd "$(dirname "$0")"
seconds="${1:-10}"
shift || true
export RUSTC_BOOTSTRAP=1

if ! cargo fuzz build >logs.build 2>&1; then
    cat logs.build >&2
    exit 2
fi
rm -f logs.build

mkdir -p logs
status=0
targets="$*"
[ -n "$targets" ] || targets=$(cargo fuzz list)
for target in $targets; do
    mkdir -p "corpus/$target" "artifacts/$target"
    before=$(find "artifacts/$target" -type f | wc -l)
    log="logs/$target.log"
    # -timeout: an input taking more than 10 s counts as a crash (a hang).
    cargo fuzz run "$target" "corpus/$target" "seeds/$target" -- \
        -max_total_time="$seconds" -print_final_stats=1 -timeout=10 >"$log" 2>&1
    code=$?
    execs=$(sed -n 's/^stat::number_of_executed_units: *\([0-9]*\).*/\1/p' "$log" | tail -n 1)
    after=$(find "artifacts/$target" -type f | wc -l)
    crashes=$((after - before))
    if [ "$code" -ne 0 ] && [ "$crashes" -eq 0 ]; then
        crashes=1 # libFuzzer failed without writing an artifact: count it, never hide it
    fi
    if [ "$crashes" -gt 0 ]; then
        status=1
        echo "fuzz target $target crashed (exit $code); log $PWD/$log:" >&2
        grep -E -A12 '^(thread .* panicked|==[0-9]+==ERROR)' "$log" | head -n 40 >&2
        grep -E '^artifact_prefix|Test unit written to' "$log" >&2
    fi
    printf '{"bench":"fuzz_execs","target":"%s","ours":%s,"reference":0,"unit":"execs","crashes":%s}\n' \
        "$target" "${execs:-0}" "$crashes"
done
exit "$status"
