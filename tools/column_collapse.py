#!/usr/bin/python3
"""Granular column collapse against the published runout laws (Lube et al. 2005, Lajeunesse et
al. 2005): (L_f - L_i) / L_i = 1.2 a for small aspect ratios a = H_i / L_i, 1.9 a^(2/3) for large.

  tools/column_collapse.py [--geometry 2d|slot|slice] [--matep build/matep] [--ratios 0.5,1,2,3,5,8]
                           [--width 60,30,20,20,20,20] [--methods tdm,hybrid] [--threads 1]
                           [--jobs 2] [--out charts] [--runs out/column_collapse] [--plot-only]

Three geometries: `2d`, disks in a plane (cases/column_fill.toml, cases/column_collapse.toml);
`slot`, spheres in a narrow channel between two glass panes 6 d apart, the laboratory's
quasi-2D set-up (cases/column_slot_fill.toml, cases/column_slot.toml); and `slice`, the same
spheres in a slice 6 d deep that repeats across (periodic, no panes: the middle of a wide
channel; cases/column_slice_fill.toml, cases/column_slice.toml).
For each target aspect ratio the script (1) settles a column behind a gate L_i from the left wall
(the fill scene with the count and the loose start region scaled, the domain and the gate made
tall enough), (2) measures the settled column's height H_i (the mean over four strips of the
highest grain top, above the base's top) and so its actual a = H_i / L_i, (3) releases it
without the gate (the collapse scene, the column and the base read from the settled state, which
the script splits by group) and runs
until the deposit is at rest (end time 0.6 s + 6 sqrt(H_i / g), the kinetic energy checked), and
(4) measures the runout: L_f is the deposit's front, where the deposit thins below one grain
(the first strip, one mean diameter long, whose highest grain top is less than one mean diameter
above the base); the sparse tail of single grains beyond it is reported too (`runout_with_tail`:
the contiguous grains' extent, gaps up to one diameter). Writes
OUT/column_collapse[_slot|_slice].csv (one row per run) and OUT/column_collapse[_slot|_slice].png (runout
against a, log-log, with the two published laws and their +-25 % bands), and prints the table,
each point's ratio to the published law of its regime and the hybrid's wall time against TDM's.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import tomllib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from matep_runs import import_pyplot, run_matep, write_csv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
G, D, L_I = 9.81, 0.002, 0.04            # |g|, mean diameter, gate at 20 d (the shipped scenes)
BASE_TOP = 0.0024                         # the top of the strip of fixed grains on the floor
# E[pi r^2] and E[4/3 pi r^3] for r uniform in [0.8, 1.2] mm
MEAN_AREA = math.pi * (0.0012 ** 3 - 0.0008 ** 3) / (3 * 0.0004)
MEAN_VOLUME = 4 / 3 * math.pi * (0.0012 ** 4 - 0.0008 ** 4) / (4 * 0.0004)
FIELDS = ["method", "a_target", "L_i", "a", "H_i", "L_f", "runout", "published", "ratio_to_published", "runout_with_tail",
          "kinetic_at_end", "grains", "wall_seconds"]


class Geometry:
    """What differs between the plane of disks and the slot or slice of spheres: the scenes, the
    vertical axis, the slot's width W (the panes' gap, or the slice's period, from the fill scene's
    domain) and the packings the grain count is sized from (settled: measured; loose: the random
    start)."""

    def __init__(self, kind: str):
        self.kind = kind
        self.slot = kind in ("slot", "slice")      # spheres in 3D, the column W deep
        self.periodic = kind == "slice"            # no panes: the slice repeats across
        stem = {"2d": "column", "slot": "column_slot", "slice": "column_slice"}[kind]
        self.fill = ROOT / "cases" / f"{stem}_fill.toml"
        self.collapse = ROOT / "cases" / (f"{stem}.toml" if self.slot else "column_collapse.toml")
        scene = tomllib.loads(self.fill.read_text())
        self.up = "z" if self.slot else "y"
        self.length = scene["domain"]["upper"][0]
        self.width = scene["domain"]["upper"][1] if self.slot else None
        # A grain's mean area (disks) or volume (spheres), and the column's depth across the plane
        # (1 for disks, W in the slot): a column L_i wide and H tall holds L_i H depth phi / grain.
        self.grain, self.depth = (MEAN_VOLUME, self.width) if self.slot else (MEAN_AREA, 1.0)
        self.phi_settled, self.phi_loose = (0.52, 0.25) if self.slot else (0.8, 0.4)
        self.tag = f"_{kind}" if self.slot else ""

    def count(self, a: float, li: float) -> int:
        return round(a * li * li * self.depth * self.phi_settled / self.grain)

    def loose_height(self, n: int, li: float) -> float:
        return n * self.grain / (li * self.depth * self.phi_loose)

    def tall(self, top: float, gap: float = 0.0) -> dict:
        """The domain and the roof at height top (the collapse scene's panes stand gap back; a
        periodic slice keeps its period)."""
        if self.periodic:
            gap = 0.0
        if self.slot:
            return {"domain.upper": [self.length, self.width + gap, top], "wall.roof.point": [0.0, 0.0, top]}
        return {"domain.upper": [self.length, top], "wall.roof.point": [0.0, top]}

    def fill_sets(self, n: int, li: float, loose: float, top: float) -> dict:
        if self.slot:
            return {**self.tall(top), "particles.column.count": n,
                    "particles.column.region.upper": [li, self.width, 0.0025 + loose],
                    "wall.gate.point": [li, 0.5 * self.width, 0.5 * top],
                    "wall.gate.patch.size": [self.width, top - 0.005]}
        return {**self.tall(top), "particles.column.count": n,
                "particles.column.region.upper": [li, 0.0025 + loose],
                "wall.gate.point": [li, 0.5 * top], "wall.gate.patch.length": top - 0.005}

    def columns(self) -> list[str]:
        return (["x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "radius"] if self.slot
                else ["x", "y", "vx", "vy", "w", "radius"])


def published(a: float) -> float:
    """Lube et al. 2005 (PRE 72, 041301) and Lajeunesse et al. 2005 (Phys. Fluids 17, 103302),
    docs/references.md §7: 1.2 a below a ~ 2.3 (where the two laws cross), 1.9 a^(2/3) above."""
    return 1.2 * a if a < (1.9 / 1.2) ** 3 else 1.9 * a ** (2.0 / 3.0)


def read_state(path: Path):
    """The rows of a particle file or final_state.csv (its group and material columns are words)."""
    with open(path) as f:
        return [{k: v if k in ("group", "material") else float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def column_height(grains, li: float = L_I, up: str = "y") -> float:
    strips = [max((g[up] + g["radius"] for g in grains if k * li / 4 <= g["x"] < (k + 1) * li / 4), default=0.0)
              for k in range(4)]
    return sum(strips) / 4 - BASE_TOP


def front(grains, up: str = "y") -> float:
    """The deposit's front: the left edge of the first strip (one mean diameter wide, from the left
    wall) whose highest grain top stands less than one mean diameter above the base's top. A
    sparse tail of single grains resting in the base's hollows lies beyond it."""
    x = 0.0
    while True:
        tops = [g[up] + g["radius"] for g in grains if x <= g["x"] < x + D]
        if not tops or max(tops) - BASE_TOP < D:
            return x
        x += D


def farthest(grains) -> float:
    """The right edge of the contiguous grains (sorted by their left edge, up to the first gap
    wider than a mean diameter): the front including the tail."""
    edge = 0.0
    for g in sorted(grains, key=lambda g: g["x"] - g["radius"]):
        if g["x"] - g["radius"] > edge + D:
            break
        edge = max(edge, g["x"] + g["radius"])
    return edge


def one(geo: Geometry, matep, a_target: float, li: float, method: str, runs: Path, threads: int,
        plot_only: bool) -> dict | None:
    n = geo.count(a_target, li)
    loose = geo.loose_height(n, li)
    top = max(0.5, 0.0025 + loose + 0.05)
    fill_dir, bed = runs / f"fill_a{a_target:g}", runs / f"bed_a{a_target:g}.csv"
    base = runs / f"base_a{a_target:g}.csv"
    if not plot_only and method == "tdm":
        fill_end = 0.3 + 2 * math.sqrt(2 * loose / G)
        r = run_matep(matep, geo.fill, {**geo.fill_sets(n, li, loose, top), "run.end_time": fill_end,
                                        "run.threads": threads}, fill_dir)
        if r.status != "ok":
            print(f"a = {a_target:g}: fill {r.status} {r.message}", file=sys.stderr)
            return None
        settled = read_state(fill_dir / "final_state.csv")
        for path, group in ((bed, "column"), (base, "base")):
            with open(path, "w") as f:
                f.write(",".join(geo.columns()) + "\n")
                for g in settled:
                    if g["group"] == group:
                        f.write(",".join(repr(g[k]) for k in geo.columns()) + "\n")
    state = read_state(bed)
    h_i = column_height(state, li, geo.up)
    end = 0.6 + 6 * math.sqrt(h_i / G)
    out_dir = runs / f"{method}_a{a_target:g}"
    if plot_only:
        with open(out_dir / "summary.json") as f:
            summary = json.load(f)
    else:
        sets = {**geo.tall(top, 0.0001), "run.method": method, "run.end_time": end, "run.threads": threads,
                "particles.column.file": str(bed), "particles.base.file": str(base)}
        if method == "hybrid":
            sets["hybrid.rest_speed"] = 0.01 * math.sqrt(G * D)   # the deposit sleeps once at rest
        r = run_matep(matep, geo.collapse, sets, out_dir)
        if r.status != "ok":
            print(f"a = {a_target:g} {method}: {r.status} {r.message}", file=sys.stderr)
            return None
        summary = r.summary
    final = [g for g in read_state(out_dir / "final_state.csv") if g["group"] == "column"]
    with open(out_dir / "thermo.csv") as f:
        thermo = list(csv.DictReader(f))
    ke_peak = max(float(t["kinetic_energy"]) for t in thermo)
    a = h_i / li
    lf = front(final, geo.up)
    runout = (lf - li) / li
    tail = (farthest(final) - li) / li
    return {"method": method, "a_target": a_target, "L_i": li, "a": a, "H_i": h_i, "L_f": lf, "runout": runout,
            "published": published(a), "ratio_to_published": runout / published(a), "runout_with_tail": tail,
            "kinetic_at_end": float(thermo[-1]["kinetic_energy"]) / ke_peak, "grains": len(final),
            "wall_seconds": float(summary["wall_seconds"])}


def plot(rows, png: Path, title: str):
    plt = import_pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    aa = [0.3 * 1.05 ** k for k in range(80)]
    small = [a for a in aa if a < 4]
    large = [a for a in aa if a > 1.2]
    ax.plot(small, [1.2 * a for a in small], "k--", lw=1, label="1.2 a (Lube et al. 2005)")
    ax.fill_between(small, [0.75 * 1.2 * a for a in small], [1.25 * 1.2 * a for a in small], color="0.85", lw=0)
    ax.plot(large, [1.9 * a ** (2 / 3) for a in large], "k-", lw=1, label="1.9 a^(2/3) (Lube; Lajeunesse)")
    ax.fill_between(large, [0.75 * 1.9 * a ** (2 / 3) for a in large], [1.25 * 1.9 * a ** (2 / 3) for a in large],
                    color="0.9", lw=0, label="±25 %")
    for method, mk in (("tdm", "o"), ("hybrid", "s")):
        pts = [r for r in rows if r["method"] == method]
        if pts:
            ax.plot([float(r["a"]) for r in pts], [float(r["runout"]) for r in pts], mk,
                    mfc="none" if method == "hybrid" else None, ms=7, label=method.upper() if method == "tdm" else method)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("aspect ratio a = H_i / L_i")
    ax.set_ylabel("runout (L_f − L_i) / L_i")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--geometry", choices=("2d", "slot", "slice"), default="2d",
                    help="disks in a plane, spheres in a slot between two panes, or spheres in a periodic slice")
    ap.add_argument("--matep", default=str(ROOT / "build" / "matep"))
    ap.add_argument("--ratios", default="0.5,1,2,3,5,8")
    ap.add_argument("--width", default="60,30,20,20,20,20", help="each column's width L_i in mean diameters")
    ap.add_argument("--methods", default="tdm,hybrid")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=2, help="aspect ratios run at a time")
    ap.add_argument("--out", default=str(ROOT / "charts"))
    ap.add_argument("--runs", help="folder for the runs' outputs (default out/column_collapse[_slot|_slice])")
    ap.add_argument("--plot-only", action="store_true", help="analyse the runs already in --runs")
    a = ap.parse_args()
    geo = Geometry(a.geometry)
    out = Path(a.out)
    runs = Path(a.runs) if a.runs else ROOT / "out" / f"column_collapse{geo.tag}"
    out.mkdir(parents=True, exist_ok=True)
    runs.mkdir(parents=True, exist_ok=True)
    csv_path, png_path = out / f"column_collapse{geo.tag}.csv", out / f"column_collapse{geo.tag}.png"
    methods = a.methods.split(",")

    widths = [float(w) * D for w in a.width.split(",")]

    def ratio(x_w):
        # TDM first: it settles the column the other methods start from.
        return [one(geo, a.matep, float(x_w[0]), x_w[1], m, runs, a.threads, a.plot_only)
                for m in sorted(methods, key=lambda m: m != "tdm")]

    rows = []
    with ThreadPoolExecutor(max_workers=max(1, a.jobs)) as pool:
        for res in pool.map(ratio, zip(a.ratios.split(","), widths)):
            for r in res:
                if r is None:
                    continue
                rows.append(r)
                print(f"a = {r['a']:.3f} {r['method']:6s}: runout {r['runout']:.3f} (with the tail {r['runout_with_tail']:.3f}), published {r['published']:.3f} "
                      f"(ratio {r['ratio_to_published']:.3f}), kinetic energy at the end {r['kinetic_at_end']:.1e} of its peak, "
                      f"{r['wall_seconds']:.1f} s wall", flush=True)
    write_csv(csv_path, FIELDS, rows)
    for x in a.ratios.split(","):
        by = {r["method"]: r for r in rows if r["a_target"] == float(x)}
        if "tdm" in by and "hybrid" in by:
            print(f"a = {by['tdm']['a']:.3f}: hybrid runout / TDM = {by['hybrid']['runout'] / by['tdm']['runout']:.4f}, "
                  f"hybrid wall time / TDM = {by['hybrid']['wall_seconds'] / by['tdm']['wall_seconds']:.3f}")
    what = (f"spheres in a periodic slice {geo.width / D:g} d deep" if geo.periodic else
            f"spheres in a slot {geo.width / D:g} d wide" if geo.slot else "disks in a plane")
    plot(rows, png_path, f"column collapse, {what} ({geo.collapse.relative_to(ROOT)})")
    print(f"wrote {csv_path} and {png_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
