# Scene generator for bench/sparse_memory.sh: METHOD (edm|tdm|hybrid) KIND (compact|sparse|utube)
# -> TOML on stdout; for sparse and utube, the domain's volume over the grains' volume on stderr
# (and in a comment of the TOML).
#   compact  N grains at phi = 0.3 filling a periodic cube
#   sparse   the same cube walled by six planes inside a domain 10 times wider (1000 x the volume)
#   utube    a 3D U-tube (pipe wall, legs vertical) whose two legs each hold N/2 grains at
#            phi = 0.3 in a square box inscribed in the tube's cross-section (no grain overlaps
#            the wall); the domain is the tube's bounding box (end caps included) plus a margin
import sys
import math
method, kind = sys.argv[1], sys.argv[2]
N=100000; d=0.01
grain_volume = N*math.pi/6*d**3
# a cube holding N grains at phi = 0.3
L = (grain_volume/0.3)**(1/3)
groups = [("a", N, [0.0, 0.0, 0.0], [L, L, L])]
walls = ""
if kind == "compact":
    dom = f"lower = [0.0, 0.0, 0.0]\nupper = [{L}, {L}, {L}]\nperiodic = [true, true, true]"
    box = [L, L, L]
elif kind == "sparse":
    big = 10*L
    dom = f"lower = [0.0, 0.0, 0.0]\nupper = [{big}, {big}, {big}]"
    box = [big, big, big]
    for k,(n) in enumerate(["x","y","z"]):
        for side in (0,1):
            p=[0.0,0.0,0.0]; nv=[0.0,0.0,0.0]
            p[k] = L if side else 0.0; nv[k] = -1.0 if side else 1.0
            walls += f"[wall.{n}{side}]\ntype = \"plane\"\npoint = {p}\nnormal = {nv}\nmaterial = \"g\"\n\n"
elif kind == "utube":
    R = 0.25       # tube radius (25 d)
    Rb = 4.5       # bend radius: the legs' axes are 2 Rb = 9 m apart
    H = 5.5        # length of each (vertical) leg
    margin = 0.05  # between the tube (caps included) and the domain's faces
    # The tube starts at the top of the left leg heading down (-z), bends through 180 degrees
    # about -y (towards +x) and rises in the right leg; its ends are closed by hemispherical caps.
    x0 = margin + R
    y0 = margin + R
    zbend = margin + R + Rb  # the bend's centre: the legs' straight parts start here
    ztop = zbend + H
    box = [2*margin + 2*R + 2*Rb, 2*margin + 2*R, ztop + R + margin]
    dom = f"lower = [0.0, 0.0, 0.0]\nupper = {box}"
    walls = f"""[wall.tube]
type = "pipe"
point = [{x0}, {y0}, {ztop}]
direction = [0.0, 0.0, -1.0]
radius = {R}
pieces = [["straight", {H}], ["arc", {Rb}, 180.0, [0.0, -1.0, 0.0]], ["straight", {H}]]
material = "g"

"""
    # Each leg: a square box of side s inscribed in the cross-section (with a little play), its
    # height such that its N/2 grains fill it at phi = 0.3, standing on the leg's lower end.
    s = math.sqrt(2)*R*0.999
    h = (N//2)*math.pi/6*d**3/0.3/(s*s)
    assert h < H
    groups = []
    for name, xc, n in (("left", x0, N//2), ("right", x0 + 2*Rb, N - N//2)):
        groups.append((name, n, [xc - s/2, y0 - s/2, zbend], [xc + s/2, y0 + s/2, zbend + h]))
else:
    sys.exit(f"unknown kind {kind!r} (expected compact, sparse or utube)")
assert sum(g[1] for g in groups) == N
ratio = box[0]*box[1]*box[2]/grain_volume
note = f"domain volume / grains' volume = {ratio:.0f}"
if kind != "compact":
    print(f"{kind}: {note}", file=sys.stderr)
    assert ratio >= 1000
particles = ""
for name, n, lo, hi in groups:
    particles += f"""[particles.{name}]
material = "g"
radius = {d/2}
count = {n}
arrangement = "random"
region = {{lower = {lo}, upper = {hi}}}
temperature = 1e-3

"""
print(f"""# bench/sparse_memory_scene.py {method} {kind}: N = {N}, d = {d}; {note}
[run]
dimension = 3
method = "{method}"
end_time = {1e-3 if method!='edm' else 2e-3}
seed = 3

[domain]
{dom}

[material.g]
density = 2500.0
restitution = 0.9
contact = "linear"
stiffness = 1.0e4

{particles}{walls}""")
