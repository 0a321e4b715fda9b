#!/usr/bin/env bash
# Installs what is missing, builds matep (Release) and runs the default case.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target matep
build/matep run cases/default.toml --out out/default "$@"
