#!/usr/bin/env bash
# The soak (issue 18): `omnicave run` under Xvfb for MINUTES (default 30) with `track-sim`
# sending a figure eight at 120 Hz and, after every pose packet, a hostile datagram (random
# bytes, cut packets, huge and non-finite coordinates). Every 10 s it logs the application's
# RSS, frame rate and tracking counters to soak.csv; at the end it stops the application with
# SIGTERM, checks that it exits 0, and prints a summary. Not run in CI (it takes half an hour).
#
#   scripts/soak.sh [MINUTES] [OUT_DIR]      PROFILE=dev|release (default release)
set -euo pipefail
cd "$(dirname "$0")/.."

minutes=${1:-30}
out=${2:-target/soak}
profile=${PROFILE:-release}
mkdir -p "$out"

cargo build --profile "$profile" --bin omnicave
dir=$([ "$profile" = dev ] && echo debug || echo "$profile")
bin="target/$dir/omnicave"

display=""
for n in $(seq 150 199); do
  if [ ! -e "/tmp/.X$n-lock" ] && [ ! -e "/tmp/.X11-unix/X$n" ]; then display=":$n"; break; fi
done
[ -n "$display" ] || { echo "no free X display" >&2; exit 1; }
Xvfb "$display" -screen 0 1600x1000x24 -nolisten tcp >/dev/null 2>&1 &
xvfb=$!
port=$((20000 + RANDOM % 20000))
app=""
sim=""
cleanup() {
  [ -n "$sim" ] && kill "$sim" 2>/dev/null || true
  [ -n "$app" ] && kill "$app" 2>/dev/null || true
  kill "$xvfb" 2>/dev/null || true
}
trap cleanup EXIT
sleep 1

export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
DISPLAY="$display" NO_COLOR=1 RUST_LOG=info "$bin" run --config config/desktop.toml \
  --osc-listen "127.0.0.1:$port" --stats-every 10 >"$out/app.log" 2>&1 &
app=$!
"$bin" track-sim --target "127.0.0.1:$port" --pattern figure-eight --rate 120 --junk 1 \
  >"$out/track-sim.log" 2>&1 &
sim=$!

echo "t_s,rss_mb,fps,frames,received,accepted,dropped,clamped,implausible,lost" >"$out/soak.csv"
start=$(date +%s)
end=$((start + minutes * 60))
while [ "$(date +%s)" -lt "$end" ]; do
  sleep 10
  kill -0 "$app" 2>/dev/null || { echo "omnicave exited early; see $out/app.log" >&2; exit 1; }
  rss_kb=$(awk '/^VmRSS/ {print $2}' "/proc/$app/status")
  stats=$(grep ' stats: [0-9]' "$out/app.log" | tail -1 || true)
  tracking=$(grep 'tracking: tracking' "$out/app.log" | tail -1 || true)
  fps=$(sed -n 's/.*stats: \([0-9.]*\) fps.*/\1/p' <<<"$stats")
  frames=$(sed -n 's/.*| frames \([0-9]*\).*/\1/p' <<<"$stats")
  packets=$(sed -n 's/.*packets \([0-9]*\) received, \([0-9]*\) accepted, [0-9]* ignored, \([0-9]*\) dropped, \([0-9]*\) clamped | samples refused: [0-9]* conflicting, \([0-9]*\) implausible, .* lost \([0-9]*\) times.*/\1,\2,\3,\4,\5,\6/p' <<<"$tracking")
  echo "$(( $(date +%s) - start )),$((rss_kb / 1024)),${fps:-},${frames:-},${packets:-,,,,,}" >>"$out/soak.csv"
  tail -1 "$out/soak.csv"
done

kill "$sim" 2>/dev/null || true
sim=""
kill -TERM "$app"
status=0
wait "$app" || status=$?
app=""
echo "omnicave exit status after SIGTERM: $status"
awk -F, 'NR > 1 && $2 != "" {
    n++; rss[n] = $2; if ($3 != "") { fps_sum += $3; fps_n++; if (fps_min == "" || $3 < fps_min) fps_min = $3 }
    if (min == "" || $2 < min) min = $2; if ($2 > max) max = $2; last = $0 }
  END {
    printf "samples %d; RSS first %d MB, last %d MB, min %d, max %d; fps mean %.1f, min %.1f\n",
      n, rss[1], rss[n], min, max, fps_sum / fps_n, fps_min
    print "last sample (t_s,rss_mb,fps,frames,received,accepted,dropped,clamped,implausible,lost): " last
  }' "$out/soak.csv"
echo "\"tracking lost\" lines in the log: $(grep -c 'WARN.*tracking lost' "$out/app.log" || true)"
[ "$status" -eq 0 ]
