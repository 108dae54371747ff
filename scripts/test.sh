#!/usr/bin/env bash
# Runs every check CI runs: formatting, lints, the Khronos glTF validator on the bundled scenes,
# and all tests (which render for real, headless, on whatever Vulkan adapter is present —
# lavapipe on a machine without a GPU).
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/setup.sh
# libwayland warns when this is unset; harmless, but it clutters test output.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
chmod 0700 "$XDG_RUNTIME_DIR"

# A one-off build gains nothing from incremental state, and it is gigabytes on a small disk.
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"

echo "== cargo fmt --check"
cargo fmt --check
# Everything is built and tested with cluster mode (MPI) in: one build serves both.
echo "== cargo clippy"
cargo clippy --all-targets --locked --features cluster -- -D warnings
echo "== cargo clippy, without cluster mode (a build without MPI must stay clean)"
cargo clippy --all-targets --locked -- -D warnings
echo "== Khronos glTF validator on assets/"
(cd tools/gltf-validator && npm install --no-audit --no-fund --silent && node validate.mjs ../../assets/*.glb)
echo "== cargo test"
log=$(mktemp)
cargo test --locked --features cluster 2>&1 | tee "$log"
echo "build size: $(du -sh target | cut -f1)"
# One total over every test binary, as the last line.
awk '/^test result:/ { p += $4; f += $6 } END { printf "%d passed, %d failed\n", p, f }' "$log"
