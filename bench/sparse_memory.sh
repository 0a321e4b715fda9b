#!/usr/bin/env bash
# Memory only where grains are: peak RSS and wall time of N = 100 000 grains (d = 1 cm, phi = 0.3)
# in a compact periodic box (compact), of the same grains walled in a cube inside a domain 10 times
# wider (sparse: 1000 times the cube's volume) and of the same number of grains in the two legs of
# a 3D U-tube whose bounding box is the domain (utube: 1166 times the grains' volume), for EDM, TDM
# and the hybrid (one thread, a few steps / events). Scenes: bench/sparse_memory_scene.py.
# Usage: bench/sparse_memory.sh [build/matep]   (prints one line per run; the generator prints
# each mostly empty domain's volume over the grains' volume on stderr)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
matep="${1:-$here/../build/matep}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
for m in edm tdm hybrid; do
  for k in compact sparse utube; do
    python3 "$here/sparse_memory_scene.py" "$m" "$k" > "$tmp/$m-$k.toml"
    /usr/bin/time -f "$m $k peak_rss_kB %M wall_s %e" "$matep" run "$tmp/$m-$k.toml" --quiet --out "$tmp/o-$m-$k" \
      --set run.threads=1 2>&1 | tail -1
  done
done
