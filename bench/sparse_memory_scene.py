# Scene generator for bench/sparse_memory.sh: METHOD (edm|tdm|hybrid) KIND (compact|sparse) -> TOML on stdout.
import sys
method, kind = sys.argv[1], sys.argv[2]
N=100000; d=0.01
# a cube holding N grains at phi = 0.3
import math
L = (N*math.pi/6*d**3/0.3)**(1/3)
if kind == "compact":
    dom = f"lower = [0.0, 0.0, 0.0]\nupper = [{L}, {L}, {L}]\nperiodic = [true, true, true]"
    walls = ""
else:
    big = 10*L
    dom = f"lower = [0.0, 0.0, 0.0]\nupper = [{big}, {big}, {big}]"
    walls = ""
    for k,(n) in enumerate(["x","y","z"]):
        for side in (0,1):
            p=[0.0,0.0,0.0]; nv=[0.0,0.0,0.0]
            p[k] = L if side else 0.0; nv[k] = -1.0 if side else 1.0
            walls += f"[wall.{n}{side}]\ntype = \"plane\"\npoint = {p}\nnormal = {nv}\nmaterial = \"g\"\n\n"
print(f"""[run]
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

[particles.a]
material = "g"
radius = {d/2}
count = {N}
arrangement = "random"
region = {{lower = [0.0, 0.0, 0.0], upper = [{L}, {L}, {L}]}}
temperature = 1e-3

{walls}""")
