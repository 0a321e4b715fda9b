#!/usr/bin/env bash
# Installs the Debian packages matep needs, only those that are missing. Idempotent; run as root.
set -euo pipefail
packages=(g++ cmake make pkg-config
          libboost-dev libboost-program-options-dev libeigen3-dev libfmt-dev
          libtomlplusplus-dev libgtest-dev libbenchmark-dev
          python3-matplotlib python3-numpy python3-pandas python3-ase pybind11-dev python3-dev
          paraview python3-paraview xvfb xauth)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "matep: installing ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
