#!/usr/bin/env bash
# Builds the real VRPN server from ../shared/peers (a peer to test omnicave's VRPN client
# against, never code of ours) and prints the path of `vrpn_server`. The build is cached outside
# the clone, keyed by the tarball's name, in ${OMNICAVE_PEER_CACHE:-~/.cache/omnicave/peers};
# a cached server is reused. Needs cmake and g++ (installed by scripts/setup.sh).
# Usage: scripts/vrpn-server.sh [TARBALL]     (default: the newest ../shared/peers/vrpn-*.tar.gz)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
tarball="${1:-$(ls -1 "$here"/../shared/peers/vrpn-*.tar.gz 2>/dev/null | tail -n 1 || true)}"
if [ -z "$tarball" ] || [ ! -f "$tarball" ]; then
  echo "vrpn-server: no VRPN tarball (looked for ../shared/peers/vrpn-*.tar.gz)" >&2
  exit 2
fi
name="$(basename "$tarball" .tar.gz)"
cache="${OMNICAVE_PEER_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/omnicave/peers}/$name"
server="$cache/build/server_src/vrpn_server"
if [ -x "$server" ]; then
  echo "$server"
  exit 0
fi
for tool in cmake g++ make; do
  command -v "$tool" >/dev/null || { echo "vrpn-server: $tool not found (run scripts/setup.sh)" >&2; exit 2; }
done
# Build in a scratch folder and move it into place only when it succeeded, so an interrupted
# build is never taken for a cached one.
scratch="$(mktemp -d "${TMPDIR:-/tmp}/vrpn-build.XXXXXX")"
trap 'rm -rf "$scratch"' EXIT
tar xzf "$tarball" -C "$scratch"
src="$(find "$scratch" -maxdepth 2 -name CMakeLists.txt -printf '%h\n' | head -n 1)"
echo "vrpn-server: building $name (a few minutes on two cores)" >&2
# Only the server and its library: no clients, no optional device libraries, no Python/Java.
cmake -S "$src" -B "$scratch/build" -DCMAKE_BUILD_TYPE=Release \
  -DVRPN_BUILD_CLIENTS=OFF -DVRPN_BUILD_CLIENT_LIBRARY=OFF -DVRPN_BUILD_SERVERS=ON \
  -DVRPN_BUILD_PYTHON=OFF -DVRPN_BUILD_PYTHON_HANDCODED_2X=OFF \
  -DVRPN_BUILD_PYTHON_HANDCODED_3X=OFF -DVRPN_BUILD_JAVA=OFF -DVRPN_USE_HID=OFF \
  -DVRPN_USE_LIBUSB_1_0=OFF -DVRPN_USE_JSONNET=OFF -DVRPN_USE_MPI=OFF \
  -DVRPN_USE_DEV_INPUT=OFF -DVRPN_USE_JOYLIN=OFF -DVRPN_USE_GPM_MOUSE=OFF \
  -DVRPN_USE_I2CDEV=OFF -DVRPN_USE_WIIUSE=OFF -DVRPN_USE_LIBNIFALCON=OFF \
  -DVRPN_USE_MODBUS=OFF >"$scratch/cmake.log" 2>&1 ||
  { tail -n 30 "$scratch/cmake.log" >&2; exit 1; }
cmake --build "$scratch/build" --target vrpn_server -j "$(nproc)" >"$scratch/build.log" 2>&1 ||
  { tail -n 40 "$scratch/build.log" >&2; exit 1; }
mkdir -p "$cache/build/server_src"
cp "$scratch/build/server_src/vrpn_server" "$server"
cp "$src/server_src/vrpn.cfg" "$cache/vrpn.cfg.example"
echo "$server"
