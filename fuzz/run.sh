#!/usr/bin/env bash
# Runs each fuzz target for a bounded time, one after another, and prints the executions of
# each. Usage: fuzz/run.sh [SECONDS_PER_TARGET] [TARGET...]   (default: 120 s; obj gltf camera_path)
#
# Environment: RUNS=N stops each target after N executions instead (the time bound still
# applies); SANITIZER=address|none (default address); JOBS=N runs N fuzzing processes per
# target (default 1). Needs the nightly toolchain and cargo-fuzz.
#
# New corpus entries go to fuzz/work/corpus/<target>/ (not checked in; the seeds in
# fuzz/corpus/<target>/ are only read). A crash or hang leaves its input in
# fuzz/artifacts/<target>/: minimize it (cargo +nightly fuzz tmin <target> <file>), fix the
# loader, and add the minimized input to fuzz/regressions/<target>/ so `cargo test` replays it.
set -euo pipefail
cd "$(dirname "$0")"

secs=${1:-120}
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(obj gltf camera_path)
sanitizer=${SANITIZER:-address}
jobs=${JOBS:-1}

max_len() {
    case $1 in
        obj) echo 4096 ;;
        gltf) echo 8192 ;;
        *) echo 2048 ;;
    esac
}

mkdir -p work
# The harness writes every input to files in a sandbox folder: on a RAM file system when there
# is one (several times faster than a disk), else under fuzz/work/.
if [ -d /dev/shm ] && [ -w /dev/shm ]; then
    TMPDIR=$(mktemp -d /dev/shm/sightline-fuzz.XXXXXX)
else
    mkdir -p work/tmp
    TMPDIR=$(mktemp -d "$PWD/work/tmp/run.XXXXXX")
fi
export TMPDIR
trap 'rm -rf "$TMPDIR"' EXIT
nice -n 10 cargo +nightly fuzz build -s "$sanitizer"

status=0
summary=()
for t in "${targets[@]}"; do
    mkdir -p "work/corpus/$t" "artifacts/$t"
    log="work/$t.log"
    args=(-max_total_time="$secs" -max_len="$(max_len "$t")" -timeout=10 -rss_limit_mb=2048
          -dict="dict/$t.dict" -artifact_prefix="artifacts/$t/" -print_final_stats=1)
    [ -n "${RUNS:-}" ] && args+=(-runs="$RUNS")
    [ "$jobs" -gt 1 ] && args+=(-fork="$jobs")
    echo "== $t: up to $secs s (log: fuzz/$log)"
    if ! nice -n 10 cargo +nightly fuzz run -s "$sanitizer" "$t" "work/corpus/$t" "corpus/$t" -- "${args[@]}" \
        >"$log" 2>&1; then
        echo "   $t FAILED: see fuzz/$log and fuzz/artifacts/$t/"
        status=1
    fi
    rm -rf "${TMPDIR:?}"/sightline-fuzz-*
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | awk '{s+=$1} END {print s+0}')
    rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' | awk '{s+=$1} END {print s+0}')
    cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || echo '?')
    summary+=("$(printf '%-12s %12s executions %8s exec/s  coverage %s' "$t" "$execs" "$rate" "$cov")")
done
echo
printf '%s\n' "${summary[@]}"
exit $status
