# %% [markdown]
# # A pour from Python, notebook style
# Builds a scene as a dict, checks it, runs it with soft spheres (TDM), and reads the outputs back as
# numpy arrays: the kinetic energy as the grains land and settle, the bed's height and packing
# fraction, and the grains of one snapshot. Run it as a script or cell by cell (`# %%` cells, as
# Jupyter / VS Code read them):
#
#     PYTHONPATH=build/python /usr/bin/python3 tools/python/examples/pour.py
# %%
import math
import sys

import numpy as np

import matep

scene = {
    "run": {"dimension": 3, "method": "tdm", "end_time": 0.5, "seed": 3, "gravity": [0.0, 0.0, -9.81]},
    "domain": {"lower": [0.0, 0.0, 0.0], "upper": [0.08, 0.08, 0.2]},
    "material": {"glass": {"density": 2500.0, "restitution": 0.5, "contact": "hertz", "young": 1.0e7,
                           "poisson": 0.3, "friction": 0.5}},
    "particles": {"beads": {"material": "glass", "radius": 0.004, "count": 300, "arrangement": "random",
                            "region": {"lower": [0.0, 0.0, 0.02], "upper": [0.08, 0.08, 0.18]}}},
    "wall": {name: {"type": "plane", "point": p, "normal": n, "material": "glass"} for name, p, n in [
        ("floor", [0, 0, 0], [0, 0, 1]), ("left", [0, 0, 0], [1, 0, 0]), ("right", [0.08, 0, 0], [-1, 0, 0]),
        ("front", [0, 0, 0], [0, 1, 0]), ("back", [0, 0.08, 0], [0, -1, 0])]},
    "output": {"thermo_interval": 0.01, "snapshot_interval": 0.1, "format": ["vtk", "xyz"]},
}

# %% Check it: what `matep check` prints.
print(matep.check(scene)["description"])

# %% Run it (Ctrl-C stops it cleanly and raises KeyboardInterrupt once the outputs are written).
out = sys.argv[1] if len(sys.argv) > 1 else "out/python_pour"
run = matep.run(scene, out=out)
print(run, f"{run.outcome['steps']} steps in {run.outcome['wall_seconds']:.2f} s")

# %% The kinetic energy: the landing, then the bed at rest.
th = run.thermo()
for t, ke in zip(th["time"][::5], th["kinetic_energy"][::5]):
    print(f"t = {t:5.2f} s   kinetic energy {ke:.3e} J")

# %% The bed: height of the highest tops and bulk packing fraction below it.
fs = run.final_state()
tops = np.sort(fs["z"] + fs["radius"])[-30:].mean()
solid = (4.0 / 3.0 * math.pi * fs["radius"] ** 3).sum()
print(f"bed height {tops * 100:.2f} cm, packing fraction {solid / (0.08 * 0.08 * tops):.3f}")

# %% One snapshot: every grain's arrays (binary VTK read into numpy).
last = run.snapshot(-1)
print(sorted(k for k in last if k not in ("cells",)), "groups:", last["group_names"])
