#!/usr/bin/env bash
# Fuzzes every target until it has used SECONDS of CPU time (argument 1, default 1800), JOBS
# targets at a time (argument 2, default: the number of cores), at the lowest priority, then
# prints one table row per target. Budgets are CPU time rather than wall time so that a machine
# busy with other work still gives each target the same amount of fuzzing.
# Logs: fuzz/logs/<target>.log; findings: fuzz/artifacts/<target>/; corpora: fuzz/corpus/<target>/.
# TARGETS="obj ply" limits the run to some targets; `fuzz/run-all.sh table` only prints the table of
# the last runs' logs.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-1800}
jobs=${2:-$(nproc)}
targets=${TARGETS:-obj ply gltf image colmap bundler config}
host=$(rustc -vV | sed -n 's/^host: //p')
bin="fuzz/target/$host/release"
tick=$(getconf CLK_TCK)

# One table row per target, from its log and its findings.
table() {
  echo "| target | CPU s | executions | coverage (cov / ft) | corpus | peak RSS | findings |"
  echo "|---|---|---|---|---|---|---|"
  for t in $targets; do
    log="fuzz/logs/$t.log"
    cpu=$(sed -n 's/^cpu_seconds: //p' "$log" | tail -1)
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
    rss=$(sed -n 's/^stat::peak_rss_mb: *//p' "$log" | tail -1)
    last=$(grep -E '^#[0-9]+' "$log" | tail -1)
    cov=$(sed -n 's/.* cov: \([0-9]*\) ft: \([0-9]*\).*/\1 \/ \2/p' <<<"$last")
    corp=$(sed -n 's/.* corp: \([^ ]*\).*/\1/p' <<<"$last")
    found=$(find "fuzz/artifacts/$t" -type f | wc -l)
    echo "| $t | $cpu | $execs | $cov | $corp | ${rss} MB | $found |"
  done
}

if [ "$secs" = table ]; then
  table
  exit 0
fi

RUSTC_BOOTSTRAP=1 cargo fuzz build --fuzz-dir fuzz -O
mkdir -p fuzz/logs

# CPU seconds (user + system) a running process has used so far.
cpu_seconds() {
  awk -v tick="$tick" '{ print int(($14 + $15) / tick) }' "/proc/$1/stat" 2>/dev/null
}

fuzz_one() {
  local t=$1 log="fuzz/logs/$1.log" used=0 pid
  mkdir -p "fuzz/corpus/$t" "fuzz/artifacts/$t"
  nice -n 19 "$bin/$t" -rss_limit_mb=1024 -timeout=10 -print_final_stats=1 \
    -artifact_prefix="fuzz/artifacts/$t/" "fuzz/corpus/$t" >"$log" 2>&1 &
  pid=$!
  while kill -0 "$pid" 2>/dev/null; do
    sleep 5
    used=$(cpu_seconds "$pid") || break
    [ -n "$used" ] || break
    if [ "$used" -ge "$secs" ]; then
      # libFuzzer prints its final statistics when interrupted.
      kill -INT "$pid"
      break
    fi
  done
  wait "$pid" || true
  echo "cpu_seconds: $used" >>"$log"
}

running=0
for t in $targets; do
  if [ "$running" -ge "$jobs" ]; then
    wait -n
    running=$((running - 1))
  fi
  fuzz_one "$t" &
  running=$((running + 1))
done
wait

table
