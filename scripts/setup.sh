#!/usr/bin/env bash
# Installs what omnicave needs on a fresh Debian/Ubuntu machine: a Vulkan driver (lavapipe, so
# it renders even without a GPU), the X libraries and Xvfb for the application and its window
# tests, libudev for gamepads, Node.js for the Khronos glTF validator used by the tests,
# cmake and g++ to build the VRPN server the tracking tests talk to, and Open MPI with
# libclang for cluster mode.
# Idempotent: packages already present are not reinstalled.
#
# On Debian 12 (bookworm) lavapipe comes from bookworm-backports (Mesa 25): bookworm's own Mesa
# 22.3 leaks about 0.6 MB every time a draw switches bind groups (gigabytes per minute for the
# bundled city) and renders 10–25 times slower.
set -euo pipefail

sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
apt_install() {
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "$@"
}

codename=$(. /etc/os-release 2>/dev/null && echo "${VERSION_CODENAME:-}")
updated=false
if [ "$codename" = bookworm ]; then
  mesa=$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || true)
  if [ -z "$mesa" ] || dpkg --compare-versions "$mesa" lt 23; then
    list=/etc/apt/sources.list.d/omnicave-bookworm-backports.list
    if ! grep -rqs "bookworm-backports" /etc/apt/sources.list /etc/apt/sources.list.d/; then
      echo "setup: adding bookworm-backports for a current lavapipe (Mesa 25)"
      echo "deb http://deb.debian.org/debian bookworm-backports main" |
        "${sudo_cmd[@]}" tee "$list" >/dev/null
    fi
    "${sudo_cmd[@]}" apt-get update -qq
    updated=true
    echo "setup: installing mesa-vulkan-drivers from bookworm-backports"
    apt_install -t bookworm-backports mesa-vulkan-drivers libvulkan1
  fi
fi

# The application's tests run it in windows on a virtual X server and screenshot it: Xvfb,
# xwd (x11-apps), ImageMagick's convert, and the X client libraries winit loads at run time.
# Gamepads (gilrs) need libudev's headers and pkg-config to build.
# The VRPN tests build the real VRPN server from ../shared/peers: cmake and a C++ compiler.
# Cluster mode (`--features cluster`) runs under Open MPI's `mpirun`; the `mpi` crate's
# bindings are generated at build time by bindgen, which needs libclang.
wanted=(mesa-vulkan-drivers libvulkan1 xvfb x11-apps imagemagick libx11-6 libx11-xcb1
  libxcursor1 libxrandr2 libxi6 libxkbcommon-x11-0 libudev-dev pkg-config cmake g++ make
  openmpi-bin libopenmpi-dev libclang-dev)
# Node may come from elsewhere than Debian's package (e.g. a preinstalled toolchain).
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  wanted+=(nodejs npm)
fi
missing=()
for p in "${wanted[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  $updated || "${sudo_cmd[@]}" apt-get update -qq
  apt_install "${missing[@]}"
fi
command -v cargo >/dev/null || { echo "setup: cargo not found; install Rust (rustup) first" >&2; exit 1; }
echo "setup: ready ($(dpkg-query -W -f='mesa-vulkan-drivers ${Version}' mesa-vulkan-drivers 2>/dev/null || echo 'no lavapipe package'))"
