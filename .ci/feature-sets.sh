#!/usr/bin/env bash
# The README's two set-up commands must share one build: every crate that
# `cargo run --release -p scanatlas-cli` compiles must appear in `cargo test --release` with the
# same features, or the test command recompiles it (and the engine above it). Fails with the
# crates whose features differ; the fix is to name the test's features in tools/Cargo.toml.
set -euo pipefail
cd "$(dirname "$0")/.."
features() { cargo tree --locked "$@" -f '{p} {f}' --prefix none | sed 's/ (\*)$//' | sort -u; }
demo=$(mktemp)
tests=$(mktemp)
trap 'rm -f "$demo" "$tests"' EXIT
features -p scanatlas-cli -e normal,build >"$demo"
features -e normal,build,dev >"$tests"
differing=$(comm -23 "$demo" "$tests")
if [ -n "$differing" ]; then
  echo "the demo build and the test build differ in these crates' features:" >&2
  echo "$differing" >&2
  exit 1
fi
echo "one feature set: the test command reuses all $(wc -l <"$demo") crates of the demo build"
