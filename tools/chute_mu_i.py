#!/usr/bin/python3
"""Inclined chute flows against Bagnold's profile and the mu(I) rheology (GDR MiDi 2004).

  tools/chute_mu_i.py [--matep build/matep] [--angles 14,16,18,20,22,24,26,28] [--methods tdm,hybrid]
                      [--hybrid-angles 20,24] [--end 10] [--average 4] [--threads 1] [--jobs 2]
                      [--out charts] [--runs out/chute_mu_i] [--plot-only]

Runs cases/chute_flow.toml (2D: about 900 polydisperse disks, mean diameter d = 2 mm, 22 d deep, on
a row of fixed disks, periodic along the flow) at each angle theta (gravity tilted to
g (sin theta, -cos theta)) to --end seconds, then averages the snapshots of the last --average
seconds in slabs parallel to the base, half a diameter thick:
  * packing fraction phi(z): the area of every disk inside the slab (circle segments, exact) over
    the slab's area;
  * velocity u(z): the area-weighted mean of the disks' velocity along the flow;
  * pressure P(z) = rho_s g cos(theta) * integral_z^inf phi dz' and shear stress
    tau(z) = rho_s g sin(theta) * integral_z^inf phi dz': the steady, uniform flow's momentum
    balance, so tau / P = tan(theta) at every depth (GDR MiDi 2004, sec. 3; the base carries the
    weight's tangential part exactly when the flow no longer accelerates);
  * the inertial number I(z) = gamma_dot d / sqrt(P / rho_s) (GDR MiDi 2004, eq. 1).
A flow is steady when the least-squares trend of its mean velocity over the averaging window changes
it by less than 5 % across the window (the mean velocity of a steady flow near the stopping angle
fluctuates by about 5 % from snapshot to snapshot); it has stopped when the mean velocity of the
last snapshot is under 1e-3 sqrt(g d); otherwise it accelerates (or decelerates).

Bagnold's profile (Silbert et al. 2001, eq. 9): u(z) = u_0 + A (h^(3/2) - (h - z)^(3/2)), z from
the top of the base, h the flow's height (where phi falls to half its bulk value); u_0 and A by
least squares over the bulk (z between 3 d and h - 3 d), with the fit's R^2 there. In the bulk,
I is nearly constant (gamma_dot ~ sqrt(h - z) and P ~ h - z): each steady angle gives one point
(I, mu = tan theta), I the median of the local I(z) from the fitted gamma_dot over the bulk.

Writes OUT/chute_mu_i.csv (one row per run) and OUT/chute_mu_i.png (u(z) with Bagnold's fit,
phi(z), and mu against I with the fit mu(I) = mu_s + (mu_2 - mu_s) / (I_0 / I + 1) of Jop et al.
2006), and prints the table and the hybrid's wall time against TDM's.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import re
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent / "python"))
from matep.outputs import read_vtp, snapshots  # noqa: E402
from matep_runs import import_pyplot, run_matep, write_csv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "cases" / "chute_flow.toml"
G, RHO, D = 9.81, 2500.0, 0.002          # cases/chute_flow.toml: |g|, grain density, mean diameter
LENGTH = 0.08                            # the periodic length along the flow
SLAB = 0.5 * D
FIELDS = ["method", "angle", "mu", "status", "I", "I_q1", "I_q3", "phi_bulk", "h_over_d", "u_surface",
          "u_slip", "bagnold_A", "bagnold_R2", "accel_percent", "wall_seconds"]


def slab_area(y, r, lo, hi):
    """Area of the disks (centres y, radii r) between the heights lo and hi: the integral of the
    chord 2 sqrt(r^2 - s^2) over s, F(s) = s sqrt(r^2 - s^2) + r^2 asin(s / r)."""
    def F(s):
        s = np.clip(s, -r, r)
        return s * np.sqrt(np.maximum(r * r - s * s, 0.0)) + r * r * np.arcsin(s / r)
    return F(hi - y) - F(lo - y)


def profiles(frames, top: float):
    """Time-averaged phi(z) and u(z) over the slabs from the base's top to `top`, and the mean
    velocity along the flow of each frame."""
    edges = np.arange(0.0, top + SLAB, SLAB)
    phi = np.zeros(len(edges) - 1)
    mom = np.zeros(len(edges) - 1)
    means = []
    base_top = None
    for _, vtp in frames:
        g = read_vtp(vtp)
        fixed = g["mode"] == 4
        y, r = g["position"][:, 1], g["radius"]
        if base_top is None:
            base_top = float(np.max(y[fixed] + r[fixed]))
        y, r, vx = y[~fixed] - base_top, r[~fixed], g["velocity"][~fixed, 0]
        means.append(float(np.sum(r * r * vx) / np.sum(r * r)))
        for k in range(len(edges) - 1):
            a = slab_area(y, r, edges[k], edges[k + 1])
            phi[k] += a.sum()
            mom[k] += (a * vx).sum()
    u = np.where(phi > 0, mom / np.maximum(phi, 1e-300), 0.0)
    phi /= len(frames) * LENGTH * SLAB
    return 0.5 * (edges[:-1] + edges[1:]), phi, u, means


def analyse(run_dir: Path, angle: float, end: float, average: float) -> dict:
    frames = snapshots(run_dir, end - average)
    z, phi, u, means = profiles(frames, 0.12)
    times = np.array([t for t, _ in frames])
    trend = np.polyfit(times, means, 1)[0]
    accel = 100.0 * trend * (times[-1] - times[0]) / max(abs(float(np.mean(means))), 1e-12)
    out = {"angle": angle, "mu": math.tan(math.radians(angle)), "accel_percent": accel,
           "profile": (z, phi, u)}
    if abs(means[-1]) < 1e-3 * math.sqrt(G * D):
        out["status"] = "stopped"
        return out
    out["status"] = "steady" if abs(accel) < 5.0 else ("accelerating" if accel > 0 else "decelerating")
    out.update(fit_profile(z, phi, u, angle))
    return out


def fit_profile(z, phi, u, angle: float) -> dict:
    """Flow height, bulk packing, Bagnold fit and inertial number of time-averaged slab profiles
    (z: slab centres above the base, SLAB apart)."""
    dense = phi > 0.3
    phi_bulk = float(np.median(phi[dense]))
    above = np.nonzero(phi >= 0.5 * phi_bulk)[0]
    h = float(z[above[-1]] + 0.5 * SLAB)
    th = math.radians(angle)
    load = np.cumsum((phi * SLAB)[::-1])[::-1] - 0.5 * phi * SLAB   # integral of phi from z to the top
    P = RHO * G * math.cos(th) * load
    bulk = (z > 3 * D) & (z < h - 3 * D)
    X = np.column_stack([np.ones(bulk.sum()), h ** 1.5 - np.maximum(h - z[bulk], 0.0) ** 1.5])
    (u0, A), *_ = np.linalg.lstsq(X, u[bulk], rcond=None)
    resid = u[bulk] - X @ np.array([u0, A])
    r2 = 1.0 - float(np.sum(resid ** 2) / np.sum((u[bulk] - u[bulk].mean()) ** 2))
    gdot = 1.5 * A * np.sqrt(np.maximum(h - z[bulk], 0.0))
    I = gdot * D / np.sqrt(P[bulk] / RHO)
    return {"I": float(np.median(I)), "I_q1": float(np.percentile(I, 25)), "I_q3": float(np.percentile(I, 75)),
            "phi_bulk": float(np.median(phi[bulk])), "h_over_d": h / D, "u_surface": float(u[above[-1]]),
            "u_slip": float(u0), "bagnold_A": float(A), "bagnold_R2": r2, "h": h}


def jop_fit(I, mu):
    """mu(I) = mu_s + (mu_2 - mu_s) / (I_0 / I + 1) (Jop, Forterre & Pouliquen 2006): linear least
    squares in (mu_s, mu_2 - mu_s) for each I_0 on a grid, the best I_0 kept."""
    best = None
    for I0 in np.geomspace(1e-3, 10.0, 400):
        X = np.column_stack([np.ones_like(I), I / (I0 + I)])
        c, *_ = np.linalg.lstsq(X, mu, rcond=None)
        e = float(np.sum((X @ c - mu) ** 2))
        if best is None or e < best[0]:
            best = (e, float(c[0]), float(c[0] + c[1]), float(I0))
    return {"mu_s": best[1], "mu_2": best[2], "I0": best[3]}


def plot(rows, fit, png: Path):
    plt = import_pyplot()
    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(14, 4.8))
    tdm = sorted((r for r in rows if r["method"] == "tdm" and r.get("profile") is not None), key=lambda r: r["angle"])
    cmap = plt.get_cmap("viridis")
    for k, r in enumerate(tdm):
        z, phi, u = r["profile"]
        c = cmap(k / max(len(tdm) - 1, 1))
        a2.plot(phi, z / D, "-", color=c, lw=1.2, label=f"{r['angle']:g}° ({r['status']})")
        if r["status"] == "steady":
            dense = phi > 0.05
            a1.plot(u[dense], z[dense] / D, ".", color=c, ms=4, label=f"{r['angle']:g}°, R² = {r['bagnold_R2']:.4f}")
            zz = np.linspace(0, r["h"], 100)
            a1.plot(r["u_slip"] + r["bagnold_A"] * (r["h"] ** 1.5 - (r["h"] - zz) ** 1.5), zz / D, "-", color=c, lw=1)
    a1.set_xlabel("u (m/s)")
    a1.set_ylabel("z / d (above the base)")
    a1.set_title("steady flows: velocity; lines: Bagnold fits")
    a1.legend(fontsize=7)
    a2.set_xlabel("packing fraction φ")
    a2.set_ylabel("z / d")
    a2.set_title("packing fraction (time-averaged)")
    a2.set_xlim(0, 0.9)
    a2.set_ylim(0, 40)
    a2.legend(fontsize=7, loc="upper left")
    for method, mk in (("tdm", "o"), ("hybrid", "s")):
        pts = [r for r in rows if r["method"] == method and r["status"] == "steady"]
        if pts:
            I = np.array([float(r["I"]) for r in pts])
            lo = I - np.array([float(r["I_q1"]) for r in pts])
            hi = np.array([float(r["I_q3"]) for r in pts]) - I
            a3.errorbar(I, [float(r["mu"]) for r in pts], xerr=[lo, hi], fmt=mk, ms=7 if method == "hybrid" else 5,
                        mfc="none" if method == "hybrid" else None, capsize=3,
                        label="TDM, steady" if method == "tdm" else "hybrid, steady")
    acc = [r for r in rows if r["method"] == "tdm" and r["status"] in ("accelerating", "decelerating")]
    if acc:
        a3.plot([r["I"] for r in acc], [r["mu"] for r in acc], "^", color="0.6", mfc="none",
                label="TDM, not steady (I at the end)")
    stop = [r for r in rows if r["method"] == "tdm" and r["status"] == "stopped"]
    if stop:
        a3.plot([0.0] * len(stop), [r["mu"] for r in stop], "x", color="k", label="TDM, stopped")
    if fit:
        II = np.linspace(1e-4, max(float(r["I"]) for r in rows if r["status"] == "steady") * 1.4, 200)
        a3.plot(II, fit["mu_s"] + (fit["mu_2"] - fit["mu_s"]) / (fit["I0"] / II + 1), "k-", lw=1,
                label=f"μ(I): μ_s = {fit['mu_s']:.3f}, μ_2 = {fit['mu_2']:.3f}, I_0 = {fit['I0']:.3f}")
    a3.set_xlabel("inertial number I (bulk median; bars: quartiles)")
    a3.set_ylabel("μ = τ / P = tan θ")
    a3.set_title("effective friction against I")
    a3.legend(fontsize=7, loc="lower right")
    fig.suptitle("2D chute flow over a rough base (cases/chute_flow.toml)")
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def gravity(angle: float):
    th = math.radians(angle)
    return [G * math.sin(th), -G * math.cos(th)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--matep", default=str(ROOT / "build" / "matep"))
    ap.add_argument("--angles", default="14,16,18,20,22,24,26,28")
    ap.add_argument("--methods", default="tdm,hybrid")
    ap.add_argument("--hybrid-angles", default="20,24", help="the angles also run with the hybrid")
    ap.add_argument("--end", type=float, default=10.0)
    ap.add_argument("--average", type=float, default=4.0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=2, help="runs at a time")
    ap.add_argument("--out", default=str(ROOT / "charts"))
    ap.add_argument("--runs", default=str(ROOT / "out" / "chute_mu_i"), help="folder for the runs' outputs")
    ap.add_argument("--plot-only", action="store_true", help="analyse the runs already in --runs")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    csv_path, png_path = out / "chute_mu_i.csv", out / "chute_mu_i.png"
    jobs = [("tdm", float(x)) for x in a.angles.split(",")] if "tdm" in a.methods.split(",") else []
    if "hybrid" in a.methods.split(","):
        jobs += [("hybrid", float(x)) for x in a.hybrid_angles.split(",")]

    def one(job):
        method, angle = job
        d = Path(a.runs) / f"{method}_{angle:g}"
        if a.plot_only:
            with open(d / "summary.json") as f:
                s = json.load(f)
            return job, s["status"], "", s
        run = run_matep(a.matep, SCENE, {"run.method": method, "run.end_time": a.end, "run.threads": a.threads,
                                         "run.gravity": gravity(angle)}, d)
        return job, run.status, run.message, run.summary

    rows = []
    with ThreadPoolExecutor(max_workers=max(1, a.jobs)) as pool:
        for (method, angle), status, message, summary in pool.map(one, jobs):
            if summary is None or status != "ok":
                print(f"{angle:g} deg {method}: {status} {message}", file=sys.stderr)
                continue
            r = analyse(Path(a.runs) / f"{method}_{angle:g}", angle, a.end, a.average)
            r.update({"method": method, "wall_seconds": float(summary["wall_seconds"])})
            rows.append(r)
            txt = (f"{angle:4g} deg {method:6s}: {r['status']:12s} mean-velocity trend {r['accel_percent']:+6.2f} % over the window"
                   f", {r['wall_seconds']:.1f} s wall")
            if "I" in r:
                txt += (f", I = {r['I']:.4f} [{r['I_q1']:.4f}, {r['I_q3']:.4f}], phi = {r['phi_bulk']:.3f}, "
                        f"h = {r['h_over_d']:.1f} d, u_surface = {r['u_surface']:.3f} m/s, Bagnold R^2 = {r['bagnold_R2']:.4f}")
            print(txt, flush=True)
    write_csv(csv_path, FIELDS, rows)
    steady = [r for r in rows if r["method"] == "tdm" and r["status"] == "steady"]
    fit = None
    if len(steady) >= 3:
        fit = jop_fit(np.array([r["I"] for r in steady]), np.array([r["mu"] for r in steady]))
        steady.sort(key=lambda r: r["angle"])
        mono = all(b["I"] > a_["I"] for a_, b in zip(steady, steady[1:]))
        print(f"steady TDM flows between {steady[0]['angle']:g} and {steady[-1]['angle']:g} deg; "
              f"mu(I) rises monotonically with I: {'yes' if mono else 'NO'}; "
              f"fit mu_s = {fit['mu_s']:.3f}, mu_2 = {fit['mu_2']:.3f}, I_0 = {fit['I0']:.3f}")
    for angle in sorted({r["angle"] for r in rows}):
        by = {r["method"]: r for r in rows if r["angle"] == angle}
        if "tdm" in by and "hybrid" in by and "I" in by["tdm"] and "I" in by["hybrid"]:
            print(f"{angle:g} deg: hybrid I / TDM I = {by['hybrid']['I'] / by['tdm']['I']:.4f}, "
                  f"hybrid wall time / TDM = {by['hybrid']['wall_seconds'] / by['tdm']['wall_seconds']:.3f}")
    plot(rows, fit, png_path)
    print(f"wrote {csv_path} and {png_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
