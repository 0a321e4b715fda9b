#!/usr/bin/env bash
# Installs what is missing, builds matep with its tests and Python module (Release) and runs the
# whole suite.
# MATEP_SANITIZE=1 tools/test.sh builds in build-asan with AddressSanitizer + UBSan instead.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
dir=build; flags=(-DCMAKE_BUILD_TYPE=Release)
if [ "${MATEP_SANITIZE:-0}" = 1 ]; then dir=build-asan; flags=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DMATEP_SANITIZE=ON); fi
cmake -S . -B "$dir" "${flags[@]}" -DMATEP_BUILD_TESTS=ON >/dev/null
cmake --build "$dir" -j"$(nproc)" --target matep_test_deps  # not the benchmarks
ctest --test-dir "$dir" -j"$(nproc)" --output-on-failure --no-tests=error
