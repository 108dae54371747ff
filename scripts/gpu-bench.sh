#!/usr/bin/env bash
# The bench on a machine with a real GPU: every wall of config/cave.toml at 1920×1200, the
# bundled living room, city and atrium, stereo against the plain warp and the error
# criterion from coarse to fine (the exact method's candidates), 12 rounds of the three
# `--quick` cases per scene (the config's head, the head 0.3 m from the front wall, and the
# view turned 180°). Writes results.csv, report.md and the charts (time against triangles
# among them) under OUT_DIR and says how long it took. Meant to take under 5 minutes: the
# frames on the GPU, the accuracy (the CPU twin) on every core.
#
#   scripts/gpu-bench.sh [OUT_DIR]        SIZE=WxH FRAMES=N to change the defaults
#
# SIZE=192x120 FRAMES=2 runs the same on a software rasteriser in a few minutes (a check of
# the script, not a measurement). The binary is target/release/omnicave, brought up to date
# by cargo where there is one (OMNICAVE=path uses another as it is).
set -euo pipefail
cd "$(dirname "$0")/.."

out=${1:-out/gpu-bench}
size=${SIZE:-1920x1200}
frames=${FRAMES:-12}
bin=${OMNICAVE:-target/release/omnicave}
if [ -z "${OMNICAVE:-}" ] && command -v cargo >/dev/null; then
  cargo build --release --locked --bin omnicave
fi
[ -x "$bin" ] || { echo "no omnicave binary at $bin (build it, or set OMNICAVE)" >&2; exit 1; }

start=$(date +%s)
"$bin" bench --quick --config config/cave.toml --size "$size" --frames "$frames" --out "$out" \
  --scene assets/living-room.glb --scene assets/city.glb --scene assets/atrium.glb \
  --method omni-offaxis \
  --method 'omni-offaxis + tess error:8' --method 'omni-offaxis + tess error:2' \
  --method 'omni-offaxis + tess error:1' --method 'omni-offaxis + tess error:0.5'
end=$(date +%s)
echo "bench took $((end - start)) s; results in $out (results.csv, report.md, *.png)"
