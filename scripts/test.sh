#!/usr/bin/env bash
# Runs every check CI runs: installs the test clients (bpy, usd-core, gltf-validator) into
# ignored folders, then formatting, clippy and the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/setup-test-env.sh
echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy --all-targets -D warnings"
cargo clippy --workspace --all-targets --quiet -- -D warnings
echo "== cargo test"
set +e
log=$(mktemp)
cargo test --workspace --no-fail-fast 2>&1 | tee "$log"
status=${PIPESTATUS[0]}
set -e
passed=$({ grep -oE "test result: [a-zA-Z]+\. [0-9]+ passed" "$log" || true; } | awk '{s+=$4} END {print s+0}')
failed=$({ grep -oE "; [0-9]+ failed" "$log" || true; } | awk '{s+=$2} END {print s+0}')
echo "tests: $passed passed, $failed failed"
rm -f "$log"
exit "$status"
