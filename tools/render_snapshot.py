#!/usr/bin/python3
"""Draws one snapshot of a run (grains and walls) to a PNG, from the run's snapshots.pvd.

  tools/render_snapshot.py OUT_DIR [--time T | --index K] [--png FILE] [--cut AXIS:VALUE]
                           [--view ELEV,AZIM] [--color velocity|mode|radius|id]

OUT_DIR is a `matep run` output folder written with output.snapshot_interval > 0. The snapshot is
the last one by default. Grains are drawn as disks of their radius (2D) or as spheres seen from the
view direction (3D, painter's order), coloured by speed (default), mode, radius or id; walls from
their .vtp files (3D: translucent polygons; 2D: lines). --cut y:0 keeps only grains with y <= 0
(a section through a silo or a drum). Needs Debian's python3-matplotlib (use /usr/bin/python3).
"""
from __future__ import annotations

import argparse
import math
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent / "python"))
from matep.outputs import read_vtp  # noqa: E402
from matep_runs import import_pyplot  # noqa: E402


def arrays(vtp: Path) -> dict:
    """Every array of a matep .vtp (ASCII or binary) by Name as flat float lists (the points as
    'points'), plus the cells of Polys or Lines."""
    v = read_vtp(vtp)
    out = {k: a.ravel().tolist() for k, a in v.items() if hasattr(a, "ravel")}
    out["points"] = out.pop("position")
    out["cells"] = [c.tolist() for c in v["cells"]]
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out_dir", type=Path)
    ap.add_argument("--time", type=float)
    ap.add_argument("--index", type=int)
    ap.add_argument("--png", type=Path)
    ap.add_argument("--cut", help="AXIS:VALUE, keep grains with coordinate <= VALUE (3D)")
    ap.add_argument("--view", default="20,-60", help="ELEV,AZIM in degrees (3D)")
    ap.add_argument("--color", default="velocity", choices=["velocity", "mode", "radius", "id", "group", "material"])
    a = ap.parse_args()

    pvd = a.out_dir / "snapshots.pvd"
    if not pvd.exists():
        print(f"{pvd}: missing (run with output.snapshot_interval > 0)", file=sys.stderr)
        return 2
    frames: dict[float, dict[int, str]] = {}
    for ds in ET.parse(pvd).getroot().iter("DataSet"):
        frames.setdefault(float(ds.get("timestep")), {})[int(ds.get("part"))] = ds.get("file")
    times = sorted(frames)
    if a.index is not None:
        t = times[a.index]
    elif a.time is not None:
        t = min(times, key=lambda x: abs(x - a.time))
    else:
        t = times[-1]
    parts = frames[t]
    grains = arrays(a.out_dir / parts[0])
    P = grains["points"]
    n = len(P) // 3
    x = [P[3 * i] for i in range(n)]
    y = [P[3 * i + 1] for i in range(n)]
    z = [P[3 * i + 2] for i in range(n)]
    r = grains.get("radius", [0.0] * n)
    dim = 2 if all(v == 0.0 for v in z) else 3
    if a.color == "velocity":
        V = grains.get("velocity", [0.0] * 3 * n)
        c = [math.sqrt(V[3 * i] ** 2 + V[3 * i + 1] ** 2 + V[3 * i + 2] ** 2) for i in range(n)]
    else:
        c = grains.get(a.color, [0.0] * n)
    keep = list(range(n))
    if a.cut and dim == 3:
        m = re.fullmatch(r"([xyz]):(-?[0-9.eE+-]+)", a.cut)
        if not m:
            print(f"--cut {a.cut}: expected AXIS:VALUE such as y:0", file=sys.stderr)
            return 2
        k, v = "xyz".index(m.group(1)), float(m.group(2))
        keep = [i for i in keep if (x, y, z)[k][i] <= v]
    walls = [arrays(a.out_dir / f) for p, f in sorted(parts.items()) if p > 0]

    plt = import_pyplot()
    from matplotlib import cm
    from matplotlib.colors import Normalize

    cmax = max([c[i] for i in keep], default=1.0) or 1.0
    norm = Normalize(0.0, cmax)
    cmap = cm.get_cmap("viridis")
    if dim == 2:
        from matplotlib.patches import Circle
        fig, ax = plt.subplots(figsize=(6, 6))
        for i in keep:
            ax.add_patch(Circle((x[i], y[i]), r[i], color=cmap(norm(c[i])), lw=0))
        for w in walls:
            wp = w["points"]
            for cell in w["cells"]:
                ax.plot([wp[3 * k] for k in cell], [wp[3 * k + 1] for k in cell], color="0.2", lw=1.5)
        ax.set_aspect("equal")
        ax.autoscale_view()
    else:
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection
        fig = plt.figure(figsize=(7, 7))
        ax = fig.add_subplot(projection="3d")
        elev, azim = (float(v) for v in a.view.split(","))
        ax.view_init(elev=elev, azim=azim)
        for w in walls:
            wp = w["points"]
            polys = [[(wp[3 * k], wp[3 * k + 1], wp[3 * k + 2]) for k in cell] for cell in w["cells"]]
            ax.add_collection3d(Poly3DCollection(polys, facecolor=(0.6, 0.6, 0.7, 0.12), edgecolor=(0.3, 0.3, 0.4, 0.25),
                                                 lw=0.3))
        # Marker size from the radius in points: the axes' data-to-points scale, roughly.
        span = max(max(x) - min(x), max(y) - min(y), max(z) - min(z)) or 1.0
        scale = (fig.get_size_inches()[0] * 72 * 0.6 / span) ** 2
        ax.scatter([x[i] for i in keep], [y[i] for i in keep], [z[i] for i in keep],
                   s=[math.pi * (r[i]) ** 2 * scale for i in keep], c=[c[i] for i in keep], cmap=cmap, norm=norm,
                   depthshade=True, lw=0)
        allx = x + [w["points"][3 * k] for w in walls for k in range(len(w["points"]) // 3)]
        ally = y + [w["points"][3 * k + 1] for w in walls for k in range(len(w["points"]) // 3)]
        allz = z + [w["points"][3 * k + 2] for w in walls for k in range(len(w["points"]) // 3)]
        ax.set_xlim(min(allx), max(allx))
        ax.set_ylim(min(ally), max(ally))
        ax.set_zlim(min(allz), max(allz))
        ax.set_box_aspect((max(allx) - min(allx), max(ally) - min(ally), max(allz) - min(allz)))
    ax.set_title(f"{a.out_dir.name}: t = {t:.4g} s, {len(keep)} of {n} grains, colour: {a.color}")
    png = a.png or (a.out_dir / f"snapshot_{times.index(t):06d}.png")
    fig.savefig(png, dpi=110)
    print(f"wrote {png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
