#!/usr/bin/env bash
# The same bed in a box of five planes and in a box mesh (10 triangles, open top): the shipped
# pour-and-settle case (2000 Hertz grains, friction 0.5) in TDM and the hybrid, over several seeds;
# prints each run's mean grain height and the mesh/planes ratio of the seed means.
# Usage: tests/validation/mesh_bed.sh [build/matep] [seeds...]   (about a minute per run)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
matep="$(realpath "${1:-$here/../../build/matep}")"
shift || true
seeds=("${@:-7 8 9}")
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
python3 - "$here/../../cases/pour_settle.toml" "$tmp" <<'PY'
import sys, struct
case, tmp = sys.argv[1], sys.argv[2]
s = open(case).read()
head, tail = s[:s.index('[wall.floor]')], s[s.index('[hybrid]'):]
open(f'{tmp}/planes.toml', 'w').write(s)
open(f'{tmp}/mesh.toml', 'w').write(head + '[wall.box]\ntype = "mesh"\nfile = "box.stl"\nmaterial = "glass"\n\n' + tail)
L, H = 0.15, 1.0
P = lambda x, y, z: (x * L, y * L, z * H)
quads = [[P(0,0,0),P(1,0,0),P(1,1,0),P(0,1,0)], [P(0,0,0),P(0,1,0),P(0,1,1),P(0,0,1)],
         [P(1,0,0),P(1,0,1),P(1,1,1),P(1,1,0)], [P(0,0,0),P(0,0,1),P(1,0,1),P(1,0,0)],
         [P(0,1,0),P(1,1,0),P(1,1,1),P(0,1,1)]]
with open(f'{tmp}/box.stl', 'wb') as f:  # binary STL
    f.write(b'\0' * 80 + struct.pack('<I', 2 * len(quads)))
    for q in quads:
        for t in ((q[0], q[1], q[2]), (q[0], q[2], q[3])):
            f.write(struct.pack('<3f', 0, 0, 0))
            for v in t: f.write(struct.pack('<3f', *v))
            f.write(struct.pack('<H', 0))
PY
for method in tdm hybrid; do
  for walls in planes mesh; do
    for seed in ${seeds[@]}; do
      "$matep" run "$tmp/$walls.toml" --quiet --out "$tmp/o-$method-$walls-$seed" --set run.method=$method \
        --set run.seed=$seed --set run.threads=1 > /dev/null
      python3 -c "
import csv,sys
z=[float(r['z']) for r in csv.DictReader(open('$tmp/o-$method-$walls-$seed/final_state.csv'))]
print('$method $walls seed $seed mean_z %.7f' % (sum(z)/len(z)))"
    done
  done
done | tee "$tmp/all.txt"
python3 - "$tmp/all.txt" <<'PY'
import sys, collections
m = collections.defaultdict(list)
for line in open(sys.argv[1]):
    w = line.split(); m[(w[0], w[1])].append(float(w[-1]))
for method in ('tdm', 'hybrid'):
    p, q = m[(method, 'planes')], m[(method, 'mesh')]
    a, b = sum(p) / len(p), sum(q) / len(q)
    print(f'{method}: mean height planes {a:.6f}, mesh {b:.6f} over {len(p)} seeds: mesh/planes - 1 = {b / a - 1:+.4f}')
PY
