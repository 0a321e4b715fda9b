#!/usr/bin/python3
"""Angle of repose of a poured heap (2D) against sliding and rolling friction.

  tools/heap_repose.py [--matep build/matep] [--mu 0.3,0.5,0.8] [--mu-r 0,0.1,0.2]
                       [--hybrid 0.5:0.1] [--methods tdm,hybrid] [--end 5] [--average 1] [--threads 1] [--jobs 2]
                       [--out charts] [--runs out/heap_repose] [--plot-only]

Runs cases/heap.toml (disks poured from a narrow inlet onto a plate of fixed disks 60 d wide with
open edges; what runs off falls out through the bottom outlet) for each friction coefficient mu and
rolling-resistance coefficient mu_r (EPSD model) to --end seconds. The heap's angle is measured on
each snapshot of the last --average seconds: the free surface is the highest grain top in strips
one mean diameter d wide across the plate (grains faster than 0.1 m/s, the falling stream and
bouncing grains, left out); on each flank a least-squares line is fitted to the
surface between 6 d from the plate's edge and 8 d from the heap's axis (leaving out the pour's
impact and the rounded edge); the angle is the mean of the two flanks' arctangents, and its
uncertainty the spread over the snapshots and flanks. --hybrid MU:MU_R also runs that pair with
run.method = "hybrid" (falling grains hard, the heap soft, resting grains asleep:
hybrid.rest_speed = 0.01 sqrt(g d)) and prints its wall time against TDM's.
Writes OUT/heap_repose.csv and OUT/heap_repose.png (angle against mu_r, one line per mu).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent / "python"))
from matep.outputs import read_vtp, snapshots  # noqa: E402
from matep_runs import import_pyplot, run_matep, write_csv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "cases" / "heap.toml"
G, D = 9.81, 0.002                       # cases/heap.toml: |g|, mean grain diameter
PLATE = (0.04, 0.16)                     # the plate's extent along x
SLOW = 0.1                               # m/s: faster grains are falling or bouncing, not the heap's surface
FIELDS = ["method", "mu", "mu_r", "angle", "angle_err", "left", "right", "height_over_d", "grains", "grains_out",
          "wall_seconds"]


def surface(x, top, lo: float, hi: float, width: float = D):
    """Centres and heights of the strips [lo, hi) of `width` that hold a grain: the highest top."""
    edges = np.arange(lo, hi + 1e-12, width)
    xs, hs = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        sel = (x >= a) & (x < b)
        if sel.any():
            xs.append(0.5 * (a + b))
            hs.append(float(top[sel].max()))
    return np.array(xs), np.array(hs)


def flank_angles(xs, hs, axis: float, lo: float, hi: float):
    """Degrees of the left and right flanks: least-squares slopes of the surface between 6 d from
    the plate's edges and 8 d from the axis."""
    out = []
    for a, b, sign in ((lo + 6 * D, axis - 8 * D, 1.0), (axis + 8 * D, hi - 6 * D, -1.0)):
        sel = (xs >= a) & (xs <= b)
        if sel.sum() < 4:
            out.append(math.nan)
            continue
        slope = np.polyfit(xs[sel], hs[sel], 1)[0]
        out.append(math.degrees(math.atan(sign * slope)))
    return out


def measure(run_dir: Path, end: float, average: float) -> dict:
    lefts, rights, heights = [], [], []
    for _, vtp in snapshots(run_dir, end - average):
        g = read_vtp(vtp)
        free = g["mode"] != 4
        base = float(np.max(g["position"][~free, 1] + g["radius"][~free]))
        x, top = g["position"][free, 0], g["position"][free, 1] + g["radius"][free]
        slow = np.linalg.norm(g["velocity"][free], axis=1) < SLOW
        on = (x >= PLATE[0]) & (x <= PLATE[1]) & (top > base) & slow
        xs, hs = surface(x[on], top[on] - base, *PLATE)
        left, right = flank_angles(xs, hs, 0.5 * (PLATE[0] + PLATE[1]), *PLATE)
        lefts.append(left)
        rights.append(right)
        heights.append(float(hs.max()) if len(hs) else 0.0)
    both = np.array(lefts + rights)
    return {"angle": float(np.nanmean(both)), "angle_err": float(np.nanstd(both)),
            "left": float(np.nanmean(lefts)), "right": float(np.nanmean(rights)), "height_over_d": heights[-1] / D}


def plot(rows, png: Path):
    plt = import_pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    for mu in sorted({float(r["mu"]) for r in rows}):
        pts = sorted((float(r["mu_r"]), float(r["angle"]), float(r["angle_err"])) for r in rows
                     if r["method"] == "tdm" and float(r["mu"]) == mu)
        ax.errorbar([p[0] for p in pts], [p[1] for p in pts], yerr=[p[2] for p in pts], fmt="o-", capsize=3,
                    label=f"TDM, μ = {mu:g}")
    hyb = [r for r in rows if r["method"] == "hybrid"]
    if hyb:
        ax.plot([float(r["mu_r"]) for r in hyb], [float(r["angle"]) for r in hyb], "ks", mfc="none", ms=9,
                label="hybrid")
    ax.set_xlabel("rolling-resistance coefficient μ_r (EPSD)")
    ax.set_ylabel("angle of repose (degrees)")
    ax.set_title("Poured 2D heap (cases/heap.toml)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--matep", default=str(ROOT / "build" / "matep"))
    ap.add_argument("--mu", default="0.3,0.5,0.8")
    ap.add_argument("--mu-r", default="0,0.1,0.2")
    ap.add_argument("--hybrid", default="0.5:0.1", help="MU:MU_R pairs also run with the hybrid ('' for none)")
    ap.add_argument("--methods", default="tdm,hybrid", help="tdm: the grid of mu and mu_r; hybrid: the --hybrid pairs")
    ap.add_argument("--end", type=float, default=5.0)
    ap.add_argument("--average", type=float, default=1.0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=2, help="runs at a time")
    ap.add_argument("--out", default=str(ROOT / "charts"))
    ap.add_argument("--runs", default=str(ROOT / "out" / "heap_repose"), help="folder for the runs' outputs")
    ap.add_argument("--plot-only", action="store_true", help="analyse the runs already in --runs")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    csv_path, png_path = out / "heap_repose.csv", out / "heap_repose.png"
    methods = a.methods.split(",")
    jobs = [("tdm", float(m), float(r)) for m in a.mu.split(",") for r in a.mu_r.split(",")] if "tdm" in methods else []
    if "hybrid" in methods:
        jobs += [("hybrid", float(p.split(":")[0]), float(p.split(":")[1])) for p in a.hybrid.split(",") if p]

    def one(job):
        method, mu, mu_r = job
        d = Path(a.runs) / f"{method}_mu{mu:g}_mur{mu_r:g}"
        if a.plot_only:
            with open(d / "summary.json") as f:
                return job, "ok", "", json.load(f)
        sets = {"run.method": method, "run.end_time": a.end, "run.threads": a.threads,
                "material.glass.friction": mu, "material.glass.rolling_friction": mu_r}
        if method == "hybrid":
            sets["hybrid.rest_speed"] = 0.01 * math.sqrt(G * D)
        r = run_matep(a.matep, SCENE, sets, d)
        return job, r.status, r.message, r.summary

    rows = []
    with ThreadPoolExecutor(max_workers=max(1, a.jobs)) as pool:
        for (method, mu, mu_r), status, message, summary in pool.map(one, jobs):
            if summary is None or status != "ok":
                print(f"mu = {mu:g}, mu_r = {mu_r:g} {method}: {status} {message}", file=sys.stderr)
                continue
            r = measure(Path(a.runs) / f"{method}_mu{mu:g}_mur{mu_r:g}", a.end, a.average)
            r.update({"method": method, "mu": mu, "mu_r": mu_r, "grains": summary["grains_at_end"],
                      "grains_out": summary["outflow"]["grains"], "wall_seconds": float(summary["wall_seconds"])})
            rows.append(r)
            print(f"mu = {mu:g}, mu_r = {mu_r:g} {method:6s}: angle {r['angle']:.1f} +- {r['angle_err']:.1f} deg "
                  f"(left {r['left']:.1f}, right {r['right']:.1f}), height {r['height_over_d']:.1f} d, "
                  f"{r['grains']} grains in the run, {r['grains_out']} out, {r['wall_seconds']:.1f} s wall", flush=True)
    write_csv(csv_path, FIELDS, rows)
    for h in [r for r in rows if r["method"] == "hybrid"]:
        t = [r for r in rows if r["method"] == "tdm" and r["mu"] == h["mu"] and r["mu_r"] == h["mu_r"]]
        if t:
            print(f"mu = {h['mu']:g}, mu_r = {h['mu_r']:g}: hybrid angle - TDM angle = {h['angle'] - t[0]['angle']:+.2f} deg, "
                  f"hybrid wall time / TDM = {h['wall_seconds'] / t[0]['wall_seconds']:.3f}")
    plot(rows, png_path)
    print(f"wrote {csv_path} and {png_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
