#!/bin/bash
# Makes the checkpoint corpus of the fuzz target (tests/fuzz/corpus/*.ckpt): checkpoints of small
# runs of each method (EDM with an event log and snapshots, 2D and 3D; TDM with friction; the hybrid
# under gravity; TDM with an inlet and an outlet), each a few kilobytes.
# usage: tests/fuzz/make_checkpoint_corpus.sh BUILD/matep   (from the repository root)
set -euo pipefail
matep=${1:-build/matep}
corpus=tests/fuzz/corpus
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
v() {  # the 3D or the 2D form of a vector: v DIMENSION "x, y, z" "x, y"
  if [ "$1" = 3 ]; then echo "[$2]"; else echo "[$3]"; fi
}
scene() {  # NAME DIMENSION METHOD OUTPUT-KEYS MORE-TABLES FLOOR(yes|no)
  local d=$2
  {
    cat <<TOML
[run]
dimension = $d
method = "$3"
end_time = 0.05
gravity = $(v "$d" "0.0, 0.0, -9.81" "0.0, -9.81")
[domain]
lower = $(v "$d" "0.0, 0.0, 0.0" "0.0, 0.0")
upper = $(v "$d" "0.04, 0.04, 0.08" "0.04, 0.08")
periodic = $(v "$d" "true, true, false" "true, false")
[material.glass]
density = 2500.0
restitution = 0.7
contact = "linear"
stiffness = 2.0e5
friction = 0.4
[particles.beads]
material = "glass"
radius = 0.004
count = 12
arrangement = "random"
temperature = 0.0001
[output]
thermo_interval = 0.01
$4
[wall.roof]
type = "plane"
point = $(v "$d" "0.0, 0.0, 0.08" "0.0, 0.08")
normal = $(v "$d" "0.0, 0.0, -1.0" "0.0, -1.0")
material = "glass"
$5
TOML
    if [ "$6" = yes ]; then
      cat <<TOML
[wall.floor]
type = "plane"
point = $(v "$d" "0.0, 0.0, 0.0" "0.0, 0.0")
normal = $(v "$d" "0.0, 0.0, 1.0" "0.0, 1.0")
material = "glass"
TOML
    fi
  } > "$work/$1.toml"
}
scene edm3d 3 edm 'events = true
snapshot_interval = 0.02' '' yes
scene edm2d 2 edm 'events = true' '' yes
scene tdm3d 3 tdm 'snapshot_interval = 0.025' '' yes
scene hybrid3d 3 hybrid 'events = true' '' yes
scene flow2d 2 tdm '' '[inlet.feed]
type = "box"
lower = [0.0, 0.05]
upper = [0.04, 0.07]
material = "glass"
grain_radius = 0.004
rate = 200.0
[outlet.floor]
type = "face"
face = "y-"' no
for n in edm3d edm2d tdm3d hybrid3d flow2d; do
  "$matep" run "$work/$n.toml" --quiet --out "$work/out_$n" > /dev/null
  cp "$work/out_$n/checkpoint.bin" "$corpus/checkpoint_$n.ckpt"
done
ls -l "$corpus"/*.ckpt
