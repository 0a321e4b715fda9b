#!/usr/bin/python3
"""ctest for the analysis behind the flow charts (tools/silo_beverloo.py, tools/chute_mu_i.py,
tools/column_collapse.py, tools/heap_repose.py): each measuring function is fed synthetic data built from a closed form
with known parameters, and must give those parameters back.

    /usr/bin/python3 tests/tools/test_flow_analysis.py
"""
from __future__ import annotations

import contextlib
import csv
import io
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tools"))
import chute_mu_i  # noqa: E402
import column_collapse  # noqa: E402
import heap_repose  # noqa: E402
import silo_beverloo  # noqa: E402

failures: list[str] = []


def close(got, want, rel, what):
    if not (math.isfinite(got) and abs(got - want) <= rel * abs(want)):
        failures.append(f"{what}: got {got!r}, expected {want!r} within {rel:.0e} (relative)")


def test_beverloo():
    # W = C rho_b sqrt(g) (D - k d)^(5/2) exactly at five sizes: the fit returns C and k with zero
    # residuals; with +-1 % noise on W it stays within a few per cent.
    C, k, rho_b, d = 0.58, 1.5, 1500.0, silo_beverloo.D_GRAIN
    sizes = [4.0, 5.0, 6.0, 7.0, 8.0]
    rows = [{"method": "tdm", "D_over_d": s, "W": C * rho_b * math.sqrt(silo_beverloo.G) * ((s - k) * d) ** 2.5}
            for s in sizes]
    fit = silo_beverloo.beverloo(rows, rho_b)
    close(fit["C"], C, 1e-9, "Beverloo C (exact data)")
    close(fit["k"], k, 1e-9, "Beverloo k (exact data)")
    close(max(abs(r) for r in fit["resid"]) + 1.0, 1.0, 1e-9, "Beverloo residuals (exact data)")
    noisy = [dict(r, W=r["W"] * (1 + 0.01 * (-1) ** i)) for i, r in enumerate(rows)]
    fit = silo_beverloo.beverloo(noisy, rho_b)
    close(fit["C"], C, 0.05, "Beverloo C (1 % noise)")
    close(fit["k"], k, 0.1, "Beverloo k (1 % noise)")
    if not (0 < fit["sk"] < 0.5 and 0 < fit["sC"] < 0.05):
        failures.append(f"Beverloo standard errors with 1 % noise: sC = {fit['sC']}, sk = {fit['sk']}")


def test_beverloo_realizations():
    # Three beds whose exact Beverloo rates have C = 0.55, 0.58, 0.61 and k = 1.4, 1.5, 1.6 (each bed
    # its own rho_b): --combine must fit each bed back, give the mean C = 0.58, k = 1.5 and their
    # standard errors (the sample standard deviation over sqrt 3: 0.03 / sqrt 3 and 0.1 / sqrt 3),
    # write one row per orifice size, and refuse a missing CSV or a single realization (exit 2).
    d, g = silo_beverloo.D_GRAIN, silo_beverloo.G
    beds = [("", 0.55, 1.4, 1450.0), ("_seed6", 0.58, 1.5, 1460.0), ("_seed7", 0.61, 1.6, 1470.0)]
    sizes = [5.0, 6.0, 7.0, 8.0]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        for tag, C, k, rho in beds:
            with open(out / f"silo_beverloo{tag}.csv", "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=["method", "D_over_d", "W", "rho_b"])
                w.writeheader()
                for s in sizes:
                    w.writerow({"method": "tdm", "D_over_d": s, "W": C * rho * math.sqrt(g) * ((s - k) * d) ** 2.5,
                                "rho_b": rho})
                w.writerow({"method": "hybrid", "D_over_d": 6.0, "W": 1.0, "rho_b": rho})  # not fitted
        text = io.StringIO()
        with contextlib.redirect_stdout(text):
            rc = silo_beverloo.combine(out, ["", "_seed6", "_seed7"])
        if rc != 0:
            failures.append(f"combine: exit {rc}")
            return
        printed = text.getvalue()
        for want in ("C = 0.580 +- 0.017, k = 1.50 +- 0.06", "C = 0.550 +- 0.000, k = 1.40 +- 0.00"):
            if want not in printed:
                failures.append(f"combine: {want!r} not printed in:\n{printed}")
        with open(out / "silo_beverloo_realizations.csv") as f:
            rows = list(csv.DictReader(f))
        if [float(r["D_over_d"]) for r in rows] != sizes:
            failures.append(f"combine: sizes {[r['D_over_d'] for r in rows]}")
        else:
            mean6 = sum(C * rho * math.sqrt(g) * ((6.0 - k) * d) ** 2.5 for _, C, k, rho in beds) / 3
            close(float(rows[1]["W_mean"]), mean6, 1e-5, "combine: mean W at 6 d")
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            missing = silo_beverloo.combine(out, ["", "_seed9"])
            single = silo_beverloo.combine(out, ["_seed6"])
        if missing != 2 or "silo_beverloo_seed9.csv" not in err.getvalue():
            failures.append(f"combine with a missing CSV: exit {missing}, said {err.getvalue()!r}")
        if single != 2 or "at least two" not in err.getvalue():
            failures.append(f"combine with one realization: exit {single}, said {err.getvalue()!r}")


def test_flow_rate():
    # A steady 0.25 kg/s outflow of 1 g grains: the slope of the cumulative mass is 0.25, and so
    # are both halves.
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "outflow.csv"
        with open(p, "w") as f:
            f.write("time,id,outlet,mass,x,y,z,vx,vy,vz\n")
            for i in range(1000):
                f.write(f"{0.004 * i},{i},hole,0.001,0,0,0,0,0,0\n")
        W, err, W1, W2 = silo_beverloo.flow_rate(p, 0.5, 3.5)
    close(W, 0.25, 1e-9, "flow rate")
    close(W1, 0.25, 1e-9, "flow rate, first half")
    close(W2, 0.25, 1e-9, "flow rate, second half")


def test_slab_area():
    # A disk split into slabs: the pieces sum to pi r^2; half a disk is pi r^2 / 2; a slab beyond
    # the disk is empty; the cap above y = r/2 is r^2 (pi/3 - sqrt(3)/4).
    r, y = np.array([0.7]), np.array([0.2])
    edges = np.linspace(-1.0, 1.5, 26)
    total = sum(float(chute_mu_i.slab_area(y, r, lo, hi)[0]) for lo, hi in zip(edges[:-1], edges[1:]))
    close(total, math.pi * 0.49, 1e-12, "slab areas of a disk")
    close(float(chute_mu_i.slab_area(y, r, -5.0, 0.2)[0]), math.pi * 0.49 / 2, 1e-12, "half a disk")
    close(float(chute_mu_i.slab_area(y, r, 0.9, 3.0)[0]) + 1.0, 1.0, 1e-12, "slab beyond the disk")
    close(float(chute_mu_i.slab_area(y, r, 0.55, 3.0)[0]), 0.49 * (math.pi / 3 - math.sqrt(3) / 4), 1e-12, "cap")


def test_bagnold_and_inertial_number():
    # A Bagnold flow built from mu(I) (docs/references.md §7): phi uniform, u(z) = u0 + A (h^1.5 -
    # (h - z)^1.5) with A = (2/3) (I / d) sqrt(phi g cos theta). The analysis must find h, A, u0,
    # R^2 = 1 and the inertial number I.
    D, theta, I, phi, h, u0 = chute_mu_i.D, 22.0, 0.2, 0.75, 0.046, 0.05
    A = (2 / 3) * (I / D) * math.sqrt(phi * chute_mu_i.G * math.cos(math.radians(theta)))
    z = np.arange(0.5 * chute_mu_i.SLAB, 0.06, chute_mu_i.SLAB)
    phis = np.where(z < h, phi, 0.0)
    u = np.where(z < h, u0 + A * (h ** 1.5 - np.maximum(h - z, 0.0) ** 1.5), 0.0)
    r = chute_mu_i.fit_profile(z, phis, u, theta)
    close(r["h"], h, 1e-9, "flow height")
    close(r["bagnold_A"], A, 1e-9, "Bagnold A")
    close(r["u_slip"], u0, 1e-9, "slip velocity")
    close(r["bagnold_R2"], 1.0, 1e-12, "Bagnold R^2")
    close(r["I"], I, 1e-9, "inertial number")
    close(r["phi_bulk"], phi, 1e-12, "bulk packing fraction")


def test_jop_fit():
    # mu(I) = mu_s + (mu_2 - mu_s) / (I_0 / I + 1) sampled at six I: the fit returns its constants
    # (to the I_0 grid's spacing).
    mu_s, mu_2, I0 = 0.38, 0.64, 0.279
    I = np.array([0.02, 0.05, 0.1, 0.2, 0.4, 0.8])
    fit = chute_mu_i.jop_fit(I, mu_s + (mu_2 - mu_s) / (I0 / I + 1))
    close(fit["mu_s"], mu_s, 1e-2, "mu_s")
    close(fit["mu_2"], mu_2, 1e-2, "mu_2")
    close(fit["I0"], I0, 3e-2, "I_0")


def test_column():
    # The published law is continuous where its two regimes meet; the deposit's front is where it
    # thins below one grain, its tail ends at the first gap wider than a mean diameter; the column
    # height is the mean strip top above the base.
    a = (1.9 / 1.2) ** 3
    close(column_collapse.published(a * (1 - 1e-12)), column_collapse.published(a * (1 + 1e-12)), 1e-9,
          "runout law continuous at the crossover")
    close(column_collapse.published(1.0), 1.2, 1e-12, "runout at a = 1")
    close(column_collapse.published(8.0), 1.9 * 4.0, 1e-12, "runout at a = 8")
    # A deposit 3 d thick up to x = 0.06 (30 strips), then a tail of single grains sitting in the
    # base's hollows (tops 0.75 d above the base) to 0.08, then a grain beyond a gap of 1.25 d.
    grains = [{"x": 0.001 + 0.002 * i, "y": column_collapse.BASE_TOP + 0.005, "radius": 0.001} for i in range(30)]
    grains += [{"x": 0.061 + 0.002 * i, "y": column_collapse.BASE_TOP + 0.0005, "radius": 0.001} for i in range(10)]
    grains.append({"x": 0.0835, "y": column_collapse.BASE_TOP + 0.0005, "radius": 0.001})
    close(column_collapse.front(grains), 0.060, 1e-9, "deposit front")
    close(column_collapse.farthest(grains), 0.080, 1e-12, "front with the tail")
    strips = [{"x": (k + 0.5) * column_collapse.L_I / 4, "y": 0.05 + 0.001 * k, "radius": 0.001} for k in range(4)]
    close(column_collapse.column_height(strips), 0.0515 + 0.001 - column_collapse.BASE_TOP, 1e-12, "column height")
    # The slot of spheres: the same deposit with z up (y across the slot) gives the same front and
    # height; the grain count fills L_i x W x H_i at the settled packing.
    slot = [{"x": g["x"], "y": 0.006, "z": g["y"], "radius": g["radius"]} for g in grains]
    close(column_collapse.front(slot, "z"), 0.060, 1e-9, "deposit front in the slot")
    close(column_collapse.column_height([{**g, "z": g["y"], "y": 0.0} for g in strips], up="z"),
          0.0515 + 0.001 - column_collapse.BASE_TOP, 1e-12, "column height in the slot")
    geo = column_collapse.Geometry("slot")
    close(geo.width, 0.012, 1e-12, "slot width from cases/column_slot_fill.toml")
    n = geo.count(2.0, column_collapse.L_I)
    close(n * column_collapse.MEAN_VOLUME / (2.0 * column_collapse.L_I ** 2 * geo.width), geo.phi_settled, 1e-3,
          "grain count at the settled packing")
    close(column_collapse.MEAN_VOLUME, 4 / 3 * math.pi * 1.04e-9, 1e-9, "E[4/3 pi r^3], r uniform in [0.8, 1.2] mm")
    # The periodic slice: spheres 6 d deep with no panes; its collapse scene keeps the fill's period
    # (the panes' gap of the slot is not added) and its own scenes and outputs.
    sl = column_collapse.Geometry("slice")
    assert sl.slot and sl.periodic and not geo.periodic
    close(sl.width, 0.012, 1e-12, "slice depth from cases/column_slice_fill.toml")
    assert sl.tall(0.3, 0.0001)["domain.upper"] == [sl.length, 0.012, 0.3]
    assert geo.tall(0.3, 0.0001)["domain.upper"][1] == 0.012 + 0.0001
    assert sl.collapse.name == "column_slice.toml" and sl.fill.name == "column_slice_fill.toml"
    assert sl.tag == "_slice" and geo.tag == "_slot" and column_collapse.Geometry("2d").tag == ""


def test_heap_angle():
    # A symmetric heap surface at 27 degrees on a plate 60 d wide (strip heights sampled at each
    # strip's centre): both flanks give 27 degrees; a 20-degree left flank against a 30-degree right
    # one gives each.
    lo, hi = heap_repose.PLATE
    axis = 0.5 * (lo + hi)
    for left, right in ((27.0, 27.0), (20.0, 30.0)):
        xs = np.arange(lo + 0.5 * heap_repose.D, hi, heap_repose.D)
        top = 0.03
        hs = np.where(xs < axis, top - (axis - xs) * math.tan(math.radians(left)),
                      top - (xs - axis) * math.tan(math.radians(right)))
        got = heap_repose.flank_angles(xs, hs, axis, lo, hi)
        close(got[0], left, 1e-9, f"left flank at {left} degrees")
        close(got[1], right, 1e-9, f"right flank at {right} degrees")
    # surface(): the highest grain top per strip, strips without grains left out.
    x = np.array([0.041, 0.0415, 0.047])
    xs, hs = heap_repose.surface(x, np.array([0.003, 0.005, 0.002]), 0.04, 0.05)
    close(float(xs[0]), 0.041, 1e-12, "first strip centre")
    close(float(hs[0]), 0.005, 1e-12, "highest top of the first strip")
    if len(xs) != 2:
        failures.append(f"surface: {len(xs)} strips with grains, expected 2")


def main():
    for t in (test_beverloo, test_beverloo_realizations, test_flow_rate, test_slab_area, test_bagnold_and_inertial_number, test_jop_fit,
              test_column, test_heap_angle):
        t()
    if failures:
        print("\n".join("FAIL: " + f for f in failures))
        return 1
    print("flow analysis: all checks passed")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
