#!/usr/bin/env bash
# Builds springbake's Python package (python/, maturin, the stable ABI for CPython >= 3.11)
# and installs it into .venv, so `.venv/bin/python -c "import springbake"` works. Its own
# target folder (target/python): the extension build sets PyO3's extension-module switch,
# which would otherwise rebuild the CLI's Python crates on every alternation.
# Incremental: a few seconds when nothing changed. Needs scripts/setup-test-env.sh first.
set -euo pipefail
cd "$(dirname "$0")/.."
log=$(mktemp)
if ! CARGO_TARGET_DIR=target/python .venv/bin/maturin develop -m python/Cargo.toml >"$log" 2>&1; then
  cat "$log"
  rm -f "$log"
  exit 1
fi
rm -f "$log"
echo "python package: springbake installed into .venv"
