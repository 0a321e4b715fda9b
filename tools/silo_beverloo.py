#!/usr/bin/python3
"""Silo discharge against Beverloo's law: W = C rho_b sqrt(g) (D - k d)^(5/2).

  tools/silo_beverloo.py [--matep build/matep] [--sizes 4,5,6,7,8] [--methods tdm,hybrid]
                         [--end 1.0] [--window 0.2,1.0] [--threads 1] [--out charts] [--plot-only]
                         [--fill] [--friction MU --tag NAME] [--seed N]
  tools/silo_beverloo.py --combine TAG,TAG,... [--out charts]

Starts from the shipped bed (cases/silo_bed.csv, the bed cases/silo_fill.toml settles; --fill runs
that scene again and starts from its final state; --friction MU sets the beads' and walls' friction
in both scenes and settles a new bed, --tag names the outputs apart), then for each orifice diameter D (in grain diameters d) and method runs cases/silo_discharge.toml with
wall.floor.hole.radius = D d / 2 to --end seconds. The mass flow rate W of a run is the least-squares
slope of the cumulative mass in outflow.csv against time over --window (the start-up transient
excluded; the bin stays more than one diameter full), its uncertainty the spread of the slopes of
the window's four quarters over sqrt(4). The rate of the window's first half against its second
tests that W does not depend on the fill height (Janssen).

Realizations: --seed N settles a new bed with the fill's run.seed = N (another random cloud, so
another packing of the same statistics) and names the outputs silo_beverloo_seedN unless --tag
says otherwise. --combine reads the CSVs of several realizations (their tags; "" is the shipped
bed's silo_beverloo.csv) and states C and k over them: each realization's own fit, their mean
and the standard error of the mean (the scatter between beds, which one run's error bars do not
see), and the fit through each orifice's mean rate; it writes OUT/silo_beverloo_realizations.csv
and .png.

Beverloo (docs/references.md §7): W^(2/5) = (C rho_b sqrt(g))^(2/5) (D - k d) is a straight line in D;
the least-squares line through the TDM points gives k from its intercept and C from its slope, with
their standard errors from the fit's covariance. rho_b is the settled bed's bulk density (grains
between z = 2 cm and 12 cm in the bin). Writes OUT/silo_beverloo.csv (one row per run) and
OUT/silo_beverloo.png (W^(2/5) against D, with the fit), and prints C, k, the residuals and the
hybrid's W and wall time against TDM's.
"""
from __future__ import annotations

import argparse
import csv
import math
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from matep_runs import import_pyplot, run_matep, write_csv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
D_GRAIN, R_BIN, G, RHO = 0.005, 0.05, 9.81, 2500.0  # cases/silo_fill.toml


def slope(ts, ms):
    n = len(ts)
    tm, mm = sum(ts) / n, sum(ms) / n
    stt = sum((t - tm) ** 2 for t in ts)
    return sum((t - tm) * (m - mm) for t, m in zip(ts, ms)) / stt


def flow_rate(outflow: Path, t0: float, t1: float):
    """W over [t0, t1] from the cumulative mass, its error, and W of the first and second halves."""
    ts, ms, cum = [], [], 0.0
    with open(outflow) as f:
        for r in csv.DictReader(f):
            cum += float(r["mass"])
            t = float(r["time"])
            if t0 <= t <= t1:
                ts.append(t)
                ms.append(cum)
    if len(ts) < 8:
        return math.nan, math.nan, math.nan, math.nan
    W = slope(ts, ms)

    def part(a, b):
        sel = [(t, m) for t, m in zip(ts, ms) if a <= t <= b]
        return slope([s[0] for s in sel], [s[1] for s in sel]) if len(sel) >= 4 else math.nan

    q = (t1 - t0) / 4
    quarters = [part(t0 + i * q, t0 + (i + 1) * q) for i in range(4)]
    err = statistics.stdev(quarters) / 2 if all(math.isfinite(x) for x in quarters) else math.nan
    return W, err, part(t0, 0.5 * (t0 + t1)), part(0.5 * (t0 + t1), t1)


def bulk_density(state: Path) -> float:
    m = 0.0
    with open(state) as f:
        for r in csv.DictReader(f):
            if 0.02 <= float(r["z"]) <= 0.12:
                R = float(r["radius"])
                m += RHO * 4.0 / 3.0 * math.pi * R ** 3
    return m / (math.pi * R_BIN ** 2 * 0.10)


def linfit(xs, ys):
    """y = a x + b: a, b and their standard errors."""
    n = len(xs)
    xm, ym = sum(xs) / n, sum(ys) / n
    sxx = sum((x - xm) ** 2 for x in xs)
    a = sum((x - xm) * (y - ym) for x, y in zip(xs, ys)) / sxx
    b = ym - a * xm
    s2 = sum((y - a * x - b) ** 2 for x, y in zip(xs, ys)) / max(n - 2, 1)
    sa = math.sqrt(s2 / sxx)
    sb = math.sqrt(s2 * (1.0 / n + xm * xm / sxx))
    cov = -xm * s2 / sxx
    return a, b, sa, sb, cov


def beverloo(rows, rho_b):
    pts = sorted((float(r["D_over_d"]), float(r["W"])) for r in rows if r["method"] == "tdm" and float(r["W"]) > 0)
    if len(pts) < 3:
        return None
    xs = [p[0] * D_GRAIN for p in pts]
    ys = [p[1] ** 0.4 for p in pts]
    a, b, sa, sb, cov = linfit(xs, ys)
    k = -b / (a * D_GRAIN)
    # k = -b / (a d): first-order error propagation with the covariance of a and b.
    dk_da, dk_db = b / (a * a * D_GRAIN), -1.0 / (a * D_GRAIN)
    sk = math.sqrt(dk_da ** 2 * sa ** 2 + dk_db ** 2 * sb ** 2 + 2 * dk_da * dk_db * cov)
    C = a ** 2.5 / (rho_b * math.sqrt(G))
    sC = 2.5 * C * sa / a
    resid = [(C * rho_b * math.sqrt(G) * max(x - k * D_GRAIN, 0.0) ** 2.5 - w) / w for x, (_, w) in zip(xs, pts)]
    return {"C": C, "sC": sC, "k": k, "sk": sk, "a": a, "b": b, "resid": resid, "pts": pts}


def plot(rows, fit, png: Path, friction: float = 0.5):
    plt = import_pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for method, style in (("tdm", "o"), ("hybrid", "s")):
        pts = sorted((float(r["D_over_d"]), float(r["W"]) ** 0.4) for r in rows if r["method"] == method)
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], style, mfc="none" if method == "hybrid" else None,
                    label=method.upper() if method == "tdm" else "hybrid")
    if fit:
        fit_line(ax, fit, f"Beverloo fit: C = {fit['C']:.3f} ± {fit['sC']:.3f}, k = {fit['k']:.2f} ± {fit['sk']:.2f}")
    finish_plot(fig, ax, f"Silo discharge (cases/silo_discharge.toml), friction μ = {friction:g}", png)


def fit_line(ax, fit, label):
    """Beverloo's straight line in W^(2/5) from its intercept D = k d to beyond the largest orifice."""
    x0, x1 = fit["k"], max(p[0] for p in fit["pts"]) + 0.5
    ax.plot([x0, x1], [fit["a"] * x * D_GRAIN + fit["b"] for x in (x0, x1)], "k-", lw=0.8, label=label)


def finish_plot(fig, ax, title, png: Path):
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.set_xlabel("orifice diameter D / d")
    ax.set_ylabel("W^(2/5)  (kg/s)^(2/5)")
    ax.set_title(title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def combine(out: Path, tags) -> int:
    """C and k over realizations (one CSV each): their own fits, mean and standard error."""
    reals = []
    for tag in tags:
        path = out / f"silo_beverloo{tag}.csv"
        try:
            with open(path) as f:
                rows = [r for r in csv.DictReader(f) if r["method"] == "tdm"]
        except OSError as e:
            print(f"silo_beverloo.py: --combine: cannot read {path}: {e.strerror}", file=sys.stderr)
            return 2
        if not rows:
            print(f"silo_beverloo.py: --combine: {path} holds no TDM rows", file=sys.stderr)
            return 2
        rho_b = float(rows[0]["rho_b"])
        fit = beverloo(rows, rho_b)
        if fit is None:
            print(f"silo_beverloo.py: --combine: {path} has fewer than 3 orifice sizes", file=sys.stderr)
            return 2
        reals.append({"tag": tag, "rows": rows, "rho_b": rho_b, "fit": fit})
    if len(reals) < 2:
        print("silo_beverloo.py: --combine needs at least two realizations", file=sys.stderr)
        return 2
    n = len(reals)

    def mean_se(xs):
        m = sum(xs) / len(xs)
        return m, statistics.stdev(xs) / math.sqrt(len(xs))

    C, sC = mean_se([r["fit"]["C"] for r in reals])
    k, sk = mean_se([r["fit"]["k"] for r in reals])
    rho, srho = mean_se([r["rho_b"] for r in reals])
    sizes = sorted(set.intersection(*({float(x["D_over_d"]) for x in r["rows"]} for r in reals)))
    table, mean_rows = [], []
    for s in sizes:
        ws = [next(float(x["W"]) for x in r["rows"] if float(x["D_over_d"]) == s) for r in reals]
        m, se = mean_se(ws)
        mean_rows.append({"method": "tdm", "D_over_d": s, "W": m})
        table.append({"D_over_d": s, "W_mean": m, "W_se": se, "W_spread": statistics.stdev(ws) / m,
                      **{f"W{r['tag'] or '_shipped'}": w for r, w in zip(reals, ws)}})
    pooled = beverloo(mean_rows, rho)
    for r in reals:
        f = r["fit"]
        print(f"realization {r['tag'] or '(shipped bed)'}: rho_b = {r['rho_b']:.1f} kg/m^3, C = {f['C']:.3f} +- "
              f"{f['sC']:.3f}, k = {f['k']:.2f} +- {f['sk']:.2f}; residuals "
              f"{', '.join(f'{100 * x:+.1f}%' for x in f['resid'])}")
    for row in table:
        print(f"D = {row['D_over_d']:g} d: W = {row['W_mean']:.4f} +- {row['W_se']:.4f} kg/s "
              f"(spread between beds {100 * row['W_spread']:.1f} %)")
    print(f"over {n} realizations: C = {C:.3f} +- {sC:.3f}, k = {k:.2f} +- {sk:.2f} (mean +- standard error); "
          f"rho_b = {rho:.1f} +- {srho:.1f} kg/m^3")
    if pooled:
        print(f"fit through the mean rates: C = {pooled['C']:.3f}, k = {pooled['k']:.2f}; residuals "
              f"{', '.join(f'{100 * x:+.1f}%' for x in pooled['resid'])}")
    csv_path, png_path = out / "silo_beverloo_realizations.csv", out / "silo_beverloo_realizations.png"
    fields = ["D_over_d", "W_mean", "W_se", "W_spread"] + [f"W{r['tag'] or '_shipped'}" for r in reals]
    write_csv(csv_path, fields, table)
    plt = import_pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for r, mk in zip(reals, "osd^v<>"):
        pts = sorted((float(x["D_over_d"]), float(x["W"]) ** 0.4) for x in r["rows"])
        f = r["fit"]
        ax.plot([p[0] for p in pts], [p[1] for p in pts], mk, mfc="none",
                label=f"bed {r['tag'] or '(shipped)'}: C = {f['C']:.3f}, k = {f['k']:.2f}")
    if pooled:
        fit_line(ax, pooled, f"fit through the mean rates: C = {pooled['C']:.3f}, k = {pooled['k']:.2f}\n"
                             f"mean of the {n} beds' fits: C = {C:.3f} ± {sC:.3f}, k = {k:.2f} ± {sk:.2f}")
    finish_plot(fig, ax, f"Silo discharge, {n} beds (realizations), TDM", png_path)
    print(f"wrote {csv_path} and {png_path}")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--matep", default=str(ROOT / "build" / "matep"))
    ap.add_argument("--sizes", default="4,5,6,7,8")
    ap.add_argument("--methods", default="tdm,hybrid")
    ap.add_argument("--end", type=float, default=1.0)
    ap.add_argument("--window", default="0.2,1.0")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", default=str(ROOT / "charts"))
    ap.add_argument("--runs", default=str(ROOT / "out" / "silo_beverloo"), help="folder for the runs' outputs")
    ap.add_argument("--fill", action="store_true", help="settle the bed again (cases/silo_fill.toml)")
    ap.add_argument("--friction", type=float, default=None,
                    help="the beads' (and walls') friction coefficient instead of the scenes' 0.5; settles a new bed")
    ap.add_argument("--tag", default="", help="suffix of the CSV and PNG names (silo_beverloo TAG .csv)")
    ap.add_argument("--seed", type=int, default=None,
                    help="settle a new bed with this run.seed (a realization); outputs tagged _seedN by default")
    ap.add_argument("--combine", default=None,
                    help="tags of realizations' CSVs to combine (comma-separated; an empty tag is the shipped bed's)")
    ap.add_argument("--plot-only", action="store_true")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    if a.combine is not None:
        return combine(out, a.combine.split(","))
    if a.seed is not None:
        if not a.tag:
            a.tag = f"_seed{a.seed}"
        if a.runs == ap.get_default("runs"):
            a.runs = str(Path(a.runs) / f"seed{a.seed}")
    csv_path, png_path = out / f"silo_beverloo{a.tag}.csv", out / f"silo_beverloo{a.tag}.png"
    extra = {} if a.friction is None else {"material.glass.friction": a.friction}
    fill_extra = extra if a.seed is None else {**extra, "run.seed": a.seed}
    a.fill = a.fill or a.friction is not None or a.seed is not None  # a new bed
    t0, t1 = (float(x) for x in a.window.split(","))
    bed = ROOT / "cases" / "silo_bed.csv"
    if a.fill and a.plot_only:
        bed = Path(a.runs) / "fill" / "final_state.csv"
    elif a.fill:
        fill = Path(a.runs) / "fill"
        run = run_matep(a.matep, ROOT / "cases" / "silo_fill.toml", {"run.threads": a.threads, **fill_extra}, fill)
        if run.status != "ok":
            print(f"silo fill: {run.status} {run.message}", file=sys.stderr)
            return 1
        bed = fill / "final_state.csv"
    rho_b = bulk_density(bed)
    rows = []
    if a.plot_only:
        with open(csv_path) as f:
            rows = list(csv.DictReader(f))
    else:
        for s in (float(x) for x in a.sizes.split(",")):
            for method in a.methods.split(","):
                run = run_matep(a.matep, ROOT / "cases" / "silo_discharge.toml",
                                {"run.method": method, "run.end_time": a.end, "run.threads": a.threads,
                                 "wall.floor.hole.radius": 0.5 * s * D_GRAIN,
                                 "particles.bed.file": str(bed), **extra},
                                Path(a.runs) / f"{method}_D{s:g}")
                if run.summary is None or run.status != "ok":
                    print(f"D = {s:g} d {method}: {run.status} {run.message}", file=sys.stderr)
                    continue
                W, err, W1, W2 = flow_rate(Path(run.out_dir) / "outflow.csv", t0, t1)
                rows.append({"method": method, "D_over_d": s, "W": W, "W_err": err, "W_first_half": W1,
                             "W_second_half": W2, "grains_out": run.summary["outflow"]["grains"],
                             "wall_seconds": run.summary["wall_seconds"], "rho_b": rho_b})
                print(f"D = {s:g} d {method}: W = {W:.5g} +- {err:.2g} kg/s (halves {W1:.4g}, {W2:.4g}), "
                      f"{run.summary['outflow']['grains']} grains out, {run.summary['wall_seconds']:.1f} s wall",
                      flush=True)
        write_csv(csv_path, ["method", "D_over_d", "W", "W_err", "W_first_half", "W_second_half", "grains_out",
                             "wall_seconds", "rho_b"], rows)
    fit = beverloo(rows, rho_b)
    print(f"bulk density of the settled bed: {rho_b:.1f} kg/m^3")
    if fit:
        print(f"Beverloo (TDM): C = {fit['C']:.3f} +- {fit['sC']:.3f}, k = {fit['k']:.2f} +- {fit['sk']:.2f}; "
              f"residuals {', '.join(f'{100 * r:+.1f}%' for r in fit['resid'])}")
    for s in sorted({float(r["D_over_d"]) for r in rows}):
        by = {r["method"]: r for r in rows if float(r["D_over_d"]) == s}
        if "tdm" in by and "hybrid" in by:
            wt, wh = float(by["tdm"]["W"]), float(by["hybrid"]["W"])
            tt, th = float(by["tdm"]["wall_seconds"]), float(by["hybrid"]["wall_seconds"])
            print(f"D = {s:g} d: hybrid W / TDM W = {wh / wt:.4f}, hybrid wall time / TDM = {th / tt:.3f}")
    plot(rows, fit, png_path, 0.5 if a.friction is None else a.friction)
    print(f"wrote {csv_path} and {png_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
