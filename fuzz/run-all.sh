#!/usr/bin/env bash
# Runs every fuzz target in turn for $1 seconds each (default 1800), at low priority.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-1800}
for t in obj ply gltf image colmap bundler config; do
  mkdir -p "fuzz/corpus/$t"
  RUSTC_BOOTSTRAP=1 nice -n 19 cargo fuzz run "$t" --fuzz-dir fuzz -- \
    -max_total_time="$secs" -rss_limit_mb=1024 -timeout=10 -print_final_stats=1
done
