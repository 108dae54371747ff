#!/usr/bin/env bash
# Installs what omnicave needs on a fresh Debian/Ubuntu machine: a Vulkan driver (lavapipe, so
# it renders even without a GPU) and Node.js for the Khronos glTF validator used by the tests.
# Idempotent: packages already present are not reinstalled.
set -euo pipefail

wanted=(mesa-vulkan-drivers libvulkan1)
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
  sudo_cmd=()
  [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
command -v cargo >/dev/null || { echo "setup: cargo not found; install Rust (rustup) first" >&2; exit 1; }
echo "setup: ready"
