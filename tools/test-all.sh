#!/usr/bin/env bash
# Run every test of rotorpilot: formatting, lints, the Rust unit/integration
# tests (release: the closed-loop flights are long), and the real-client tests
# once they exist. Installs what it needs itself; safe to run on a fresh machine.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo fmt --check"
cargo fmt --all -- --check

echo "== cargo clippy --all-targets -- -D warnings"
cargo clippy --all-targets --quiet -- -D warnings

echo "== cargo test --release"
cargo test --release --quiet 2>&1 | tee /tmp/rotorpilot-cargo-test.log
grep -q "test result: ok" /tmp/rotorpilot-cargo-test.log

echo "== benches compile"
cargo bench --no-run --quiet
