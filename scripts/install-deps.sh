#!/usr/bin/env bash
# Installs the Debian 12 packages forest-slam needs. Idempotent: does nothing
# (no apt-get update, no root needed) when everything is already installed.
set -euo pipefail

PACKAGES=(
  build-essential cmake g++ pkg-config
  libmrpt-dev mrpt-apps
  libpcl-dev liboctomap-dev libceres-dev libnanoflann-dev libeigen3-dev
  librosbag-storage-dev libsensor-msgs-dev libroslz4-dev libsqlite3-dev
  libtf2-msgs-dev libbz2-dev
  libgeographiclib-dev zlib1g-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libjsoncpp-dev
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null; then SUDO="sudo"; else
    echo "install-deps: need root (or sudo) to install: ${missing[*]}" >&2
    exit 1
  fi
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
