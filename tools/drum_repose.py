#!/usr/bin/python3
"""Dynamic angle of repose of the rotating drum (cases/drum.toml) against the Froude number.

  tools/drum_repose.py [--matep build/matep] [--speeds 0.75,1.5,3,4.5] [--methods tdm,hybrid]
                       [--end 2.0] [--out charts] [--plot-only]

For each rotation speed w and method, runs the drum (wall.drum.rotation.angular_velocity = w) to
--end seconds and measures the angle of the free surface in every snapshot (every 0.05 s) from
t >= --end / 2. The bed of a drum with a flat free surface is a circular segment, whose centroid
lies on the chord's perpendicular bisector through the drum's centre: the angle of the free
surface to the horizontal is the angle of the grains' centroid (x_c, z_c), seen from the drum's
axis, to the vertical, atan(|x_c| / |z_c|). It uses every grain (a fit to the highest grains of a
slice four grains thick is noisier). The angle is the mean over the snapshots, its spread their
standard deviation (large in the slumping regime at low Fr, where avalanches come and go).
Froude number Fr = w^2 R / g. Also reports each run's wall time and the drive's mean power
-w <torque about the axis> over the second half (thermo.csv's drum_ty).
Writes OUT/drum_repose.csv and OUT/drum_repose.png.
"""
from __future__ import annotations

import argparse
import csv
import math
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent / "python"))
from matep.outputs import read_vtp, snapshots  # noqa: E402
from matep_runs import import_pyplot, run_matep, write_csv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
R_DRUM, G = 0.05, 9.81  # cases/drum.toml's drum radius; gravity


def surface_angle(vtp: Path) -> float | None:
    P = read_vtp(vtp)["position"]
    if len(P) == 0:
        return None
    xc, zc = float(P[:, 0].mean()), float(P[:, 2].mean())
    return math.degrees(math.atan2(abs(xc), abs(zc)))


def measure(run_dir: Path, end: float, w: float) -> tuple[float, float, float]:
    angles = []
    for _, vtp in snapshots(run_dir, 0.5 * end):
        a = surface_angle(vtp)
        if a is not None:
            angles.append(a)
    with open(run_dir / "thermo.csv") as f:
        rows = [r for r in csv.DictReader(f) if float(r["time"]) >= 0.5 * end + 1e-9]
    power = -w * statistics.fmean(float(r["drum_ty"]) for r in rows) if rows else float("nan")
    return statistics.fmean(angles), (statistics.stdev(angles) if len(angles) > 1 else 0.0), power


def plot(rows, png: Path):
    plt = import_pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for method, style in (("tdm", "o-"), ("hybrid", "s--")):
        pts = sorted((float(r["froude"]), float(r["angle_deg"]), float(r["angle_sd_deg"])) for r in rows
                     if r["method"] == method)
        if pts:
            ax.errorbar([p[0] for p in pts], [p[1] for p in pts], yerr=[p[2] for p in pts], fmt=style, capsize=3,
                        label=method.upper() if method == "tdm" else "hybrid")
    ax.set_xscale("log")
    ax.set_xlabel("Froude number  w² R / g")
    ax.set_ylabel("dynamic angle of repose (degrees)")
    ax.set_title("Rotating drum (cases/drum.toml): free-surface angle")
    ax.legend()
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--matep", default=str(ROOT / "build" / "matep"))
    ap.add_argument("--speeds", default="0.75,1.5,3,4.5")
    ap.add_argument("--methods", default="tdm,hybrid")
    ap.add_argument("--end", type=float, default=2.0)
    ap.add_argument("--out", default=str(ROOT / "charts"))
    ap.add_argument("--plot-only", action="store_true")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    csv_path, png_path = out / "drum_repose.csv", out / "drum_repose.png"
    if a.plot_only:
        with open(csv_path) as f:
            plot(list(csv.DictReader(f)), png_path)
        print(f"wrote {png_path}")
        return 0
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for w in (float(s) for s in a.speeds.split(",")):
            for method in a.methods.split(","):
                run = run_matep(a.matep, ROOT / "cases" / "drum.toml",
                                {"run.method": method, "run.end_time": a.end, "run.threads": 1,
                                 "wall.drum.rotation.angular_velocity": w, "output.snapshot_interval": 0.05},
                                Path(tmp) / f"{method}_{w}")
                if run.summary is None or run.status != "ok":
                    print(f"w = {w} {method}: {run.status} {run.message}", file=sys.stderr)
                    continue
                ang, sd, power = measure(run.out_dir, a.end, w)
                rows.append({"method": method, "omega": w, "froude": w * w * R_DRUM / G, "angle_deg": ang,
                             "angle_sd_deg": sd, "power_w": power, "wall_seconds": run.summary["wall_seconds"]})
                print(f"w = {w:g} rad/s (Fr = {w * w * R_DRUM / G:.4f}) {method}: angle {ang:.1f} +- {sd:.1f} deg, "
                      f"power {power:.3g} W, {run.summary['wall_seconds']:.1f} s", flush=True)
    write_csv(csv_path, ["method", "omega", "froude", "angle_deg", "angle_sd_deg", "power_w", "wall_seconds"], rows)
    plot(rows, png_path)
    print(f"wrote {csv_path} and {png_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
