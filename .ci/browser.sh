#!/usr/bin/env bash
# CI: the HTML report rendered in headless Chromium (tools/tests/suite/report_browser.rs). Installs the
# Debian package `chromium` when it is missing (CI runs as root), then runs the test, which fails
# when the browser cannot be found.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never

find_chromium() {
  for name in chromium chromium-browser; do
    if command -v "$name" >/dev/null 2>&1; then
      command -v "$name"
      return 0
    fi
  done
  return 1
}

if ! browser=$(find_chromium); then
  echo "== installing chromium (Debian package)"
  apt-get update
  DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends chromium
  browser=$(find_chromium) || { echo "chromium is still missing after apt-get install" >&2; exit 1; }
fi
echo "== report in headless chromium ($browser)"
# --workspace, as in .ci/run, so the dependencies' features unify and nothing is rebuilt.
SCANATLAS_CHROMIUM="$browser" \
  cargo test --release --test suite report_browser:: -- --ignored --test-threads=1
