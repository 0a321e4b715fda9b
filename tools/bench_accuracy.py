#!/usr/bin/python3
"""Speed-accuracy chart: one case run with pure EDM, pure TDM at several time steps and the hybrid
at several settings of its stability rule; wall time against error from an analytic answer.

    /usr/bin/python3 tools/bench_accuracy.py ball --matep build/matep --out charts/
    /usr/bin/python3 tools/bench_accuracy.py gas  --matep build/matep --out charts/
    /usr/bin/python3 tools/bench_accuracy.py pour --matep build/matep --out charts/
    /usr/bin/python3 tools/bench_accuracy.py pressure --matep build/matep --out charts/

writes charts/accuracy_CASE.csv (case, method, setting, wall_seconds, error, status, ...) and
charts/accuracy_CASE.png (relative error against wall seconds, log-log). --quick runs tiny
versions (a few seconds in all; used by the test suite).

Cases and their error measures (README: "Speed and accuracy"):
* ball: cases/bouncing_ball.toml (e = 0.8, dropped from h = 1 m) with steel's elastic constants
  (E = 200 GPa, nu = 0.3, Hertz-Mindlin) so that TDM can run it. Reference: the hard-sphere rest
  time sqrt(2h/g)(1+e)/(1-e) = 4.0637 s (the Zeno time). A run that stops with status "collapse"
  (pure EDM) answers with the time of collapse; any other run answers with the rest time read
  from thermo.csv sampled every 1e-4 s: the time of the first row after the last row in flight,
  where "in flight" means no stored elastic energy and a gap to the floor (z - R, from the
  potential energy) above 1e-12 R. error = |answer - reference| / reference. Missing flights
  shorter than the sampling interval moves the answer by less than 1e-4 s / (1 - e) = 5e-4 s.
* gas: cases/soft_gas.toml (4096 spheres, e = 0.9, phi = 0.0998, T0 = 1, to t = 5) with random
  placement instead of the lattice (a lattice start delays the first collisions and adds the same
  +1.7 % to every method), run from 4 random starts (run.seed = 1..4) per point: <T>(t) is their
  mean, wall_seconds their median. Reference: Haff's law T(t) = T0/(1 + t/t0)^2 with
  1/t0 = (1 - e^2) omega_E(T0)/(2d), omega_E the Enskog collision rate with the Carnahan-Starling
  g(sigma) (docs/references.md §2.1, §2.4): t0 = 17.94. error = root mean square of <T>(t)/T_Haff(t) - 1
  over the thermo rows (every 0.25, t > 0). Also written: error_vs_edm, the same RMS against the
  EDM mean from the same four starts (the hard-sphere answer, free of Haff's mean-field error),
  and noise, the standard error of the seed mean (the statistical floor of both measures; the
  chart draws EDM's as a dashed line).
* pour: cases/pour_settle.toml (2000 beads poured into a box and settled, Hertz-Mindlin with
  friction, the hybrid's rest rule on) from 3 random placements (run.seed = 1..3) per point. The
  observable is deterministic in the sense the gas's is not: the settled bed's mean height 2<z>
  (twice the grains' mean centre height at t = 1.5 s), a macroscopic average whose scatter between
  placements is about 0.1 %, while the methods and steps differ by more. Reference: TDM at the
  finest step (t_c/200; the first TDM row, not plotted), its seed mean. error = |<2<z>> /
  reference - 1|; noise = the standard error of the reference's seed mean, relative (the chart's
  dashed line).
  EDM cannot settle a bed: it ends in collapse (a row with that status).
* pressure: an elastic dense gas in equilibrium, cases/soft_gas.toml with e = 1 at packing
  fraction 0.4 (4096 spheres on its simple cubic lattice, Maxwellian at T = 1 from run.seed = 1..3;
  the lattice melts within the first time unit), to t = 10. The observable is a property of the
  ensemble, not of one trajectory: the compressibility factor Z = P/(n T), each thermo row's
  pressure over n times its temperature (rows every 0.05), averaged over t >= 2 and over the
  seeds. Hard spheres have one answer, which EDM measures exactly up to its statistical error
  (about 0.1 % here); soft spheres answer with the pressure of their softness and of their step.
  error = |Z / Z_CS - 1| against the Carnahan-Starling equation of state (docs/references.md
  §2.2: Z_CS(0.4) = 6.9259, itself within a few tenths of a percent of hard-sphere simulations
  there); error_vs_edm = |Z / Z_EDM - 1| against EDM's seed mean (the hard-sphere answer of the
  same starts); noise = the standard error of EDM's seed mean, relative (the chart's dashed line).

wall_seconds is summary.json's wall time (setup and outputs included): for the ball the median of
--repeat runs (default 5) made without thermo rows (45 000 rows cost more than a coarse TDM run;
one more run writes them for the answer), for the gas the median over the starts. TDM and hybrid
runs use one thread (run.threads = 1), as EDM does. TDM steps are t_c/n with t_c the contact
time `matep check` reports for the TDM version of the scene. Hybrid rows use run.method =
"hybrid" with hybrid.stability = k (default dt and other keys); while the CLI refuses the method
they are written with status "refused" and no numbers (nothing is run), and the chart lists them
below the plot. A run that fails (unstable, escaped, ...) is a row with its status and no error.
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
from matep_runs import (CASES, Run, check_soft, hybrid_refusal, import_pyplot, run_matep,  # noqa: E402
                        run_repeated, write_csv)

FIELDS = ["case", "method", "setting", "wall_seconds", "error", "status", "answer", "reference", "dt",
          "time_reached", "runs", "error_vs_edm", "noise", "message"]
TDM_DIVISORS = [10, 20, 50, 100, 200]
HYBRID_K = [2, 5, 10, 20]


# ---------------------------------------------------------------------------------------------
# The bouncing ball


def ball_case(quick: bool) -> dict:
    scene = CASES / "bouncing_ball.toml"
    with open(CASES / "bouncing_ball.csv", newline="") as f:
        ball = next(csv.DictReader(f))
    z0, radius = float(ball["z"]), float(ball["radius"])
    g, e = 9.81, 0.8  # cases/bouncing_ball.toml
    h = z0 - radius
    sets = {"output.events": False, "run.end_time": 4.5, "output.thermo_interval": 1e-4,
            "material.steel.young": 2.0e11, "material.steel.poisson": 0.3}
    return {"name": "ball", "scene": scene, "sets": sets, "z0": z0, "radius": radius, "g": g,
            # timed runs write no thermo rows (45 000 rows cost more than a coarse TDM run itself);
            # one more run with them gives the answer
            "timing": {"output.thermo_interval": 0.0},
            "reference": math.sqrt(2.0 * h / g) * (1.0 + e) / (1.0 - e),
            "tdm": [10, 50] if quick else TDM_DIVISORS, "hybrid": [10] if quick else HYBRID_K,
            "title": "bouncing ball (e = 0.8, h = 1 m, steel Hertz-Mindlin): rest time vs Zeno time 4.0637 s",
            "measure": ball_answer}


def ball_answer(case, runs):
    """(answer, error, {}) of one run; answer NaN when the ball never comes to rest."""
    run = runs[0]
    ref = case["reference"]
    if run.status == "collapse":
        t = run.time_reached
        return t, abs(t - ref) / ref, {}
    if run.status != "ok":
        return math.nan, math.nan, {}
    rows = run.thermo()
    if not rows:
        return math.nan, math.nan, {}
    mg = rows[0]["potential_energy"] / case["z0"]  # PE = m g z, the ball starts at rest at z0
    R = case["radius"]

    def in_flight(r):
        return r["elastic_energy"] == 0.0 and r["potential_energy"] / mg - R > 1e-12 * R

    last = max((i for i, r in enumerate(rows) if in_flight(r)), default=None)
    if last is None or last + 1 >= len(rows):
        return math.nan, math.nan, {}  # still bouncing at the end (or never left the start)
    t = rows[last + 1]["time"]
    return t, abs(t - ref) / ref, {}


# ---------------------------------------------------------------------------------------------
# The freely cooling gas


def haff_t0(phi, e, n_density, sigma, mass, T0, d=3):
    """docs/references.md §2.4: 1/t0 = (1 - e^2) omega_E(T0) / (2d), omega_E (3D) = 4 sqrt(pi) n sigma^2 g sqrt(T/m),
    g(sigma) = (1 - phi/2)/(1 - phi)^3 (Carnahan-Starling)."""
    g = (1.0 - phi / 2.0) / (1.0 - phi) ** 3
    omega = 4.0 * math.sqrt(math.pi) * n_density * sigma ** 2 * g * math.sqrt(T0 / mass)
    return 2.0 * d / ((1.0 - e * e) * omega)


def gas_case(quick: bool) -> dict:
    scene = CASES / "soft_gas.toml"
    # cases/soft_gas.toml: unit diameter and mass, e = 0.9, T0 = 1, box 27.8, 4096 spheres.
    e, sigma, mass, T0 = 0.9, 1.0, 1.0, 1.0
    N, L, end = (4096, 27.8, 5.0) if not quick else (256, 11.0316, 2.0)  # same phi in quick mode
    n = N / L ** 3
    phi = n * math.pi * sigma ** 3 / 6.0
    sets = {"particles.gas.arrangement": "random", "particles.gas.count": N, "domain.upper": [L, L, L],
            "run.end_time": end, "output.thermo_interval": 0.25 if not quick else 0.5}
    t0 = haff_t0(phi, e, n, sigma, mass, T0)
    return {"name": "gas", "scene": scene, "sets": sets, "t0": t0, "T0": T0, "end": end,
            # independent random starts: T(t) is averaged over them, wall time is their median
            "seeds": [1, 2] if quick else [1, 2, 3, 4],
            "reference": T0 / (1.0 + end / t0) ** 2,
            "tdm": [10, 50] if quick else TDM_DIVISORS, "hybrid": [10] if quick else HYBRID_K,
            "title": f"cooling gas ({N} spheres, e = 0.9, phi = {phi:.4f}): T(t) vs Haff's law, t0 = {t0:.2f}",
            "measure": gas_answer}


def mean_temperature(runs):
    """[(t, T)] averaged over the runs row by row (equal steps give equal row times), or []."""
    series = [[(r["time"], r["temperature"]) for r in run.thermo() if r["time"] > 0.0] for run in runs]
    if not series or any(len(x) != len(series[0]) or not x for x in series):
        return []
    return [(statistics.fmean(x[i][0] for x in series), statistics.fmean(x[i][1] for x in series))
            for i in range(len(series[0]))]


def standard_error(runs):
    """RMS over the rows of the standard error of the seed mean of T, relative to the mean: the
    statistical floor of the error measure (NaN with one seed)."""
    series = [[r["temperature"] for r in run.thermo() if r["time"] > 0.0] for run in runs]
    if len(series) < 2 or any(len(x) != len(series[0]) for x in series):
        return math.nan
    rel = [statistics.stdev(col) / math.sqrt(len(col)) / statistics.fmean(col) for col in zip(*series)]
    return math.sqrt(sum(x * x for x in rel) / len(rel))


def gas_answer(case, runs):
    """(mean T at the end, RMS of mean T / T_Haff - 1 over the thermo rows with t > 0); the mean is
    over the seeds. Also stores the RMS deviation from the EDM mean (error_vs_edm)."""
    if any(r.status != "ok" for r in runs):
        return math.nan, math.nan, {}
    T = mean_temperature(runs)
    if not T:
        return math.nan, math.nan, {}
    t0, T0 = case["t0"], case["T0"]
    dev = [Ti / (T0 / (1.0 + t / t0) ** 2) - 1.0 for t, Ti in T]
    extra = {"noise": standard_error(runs)}
    ref = case.get("edm_series")
    if ref:
        def interp(t):
            for (ta, Ta), (tb, Tb) in zip(ref, ref[1:]):
                if ta <= t <= tb:
                    return Ta + (Tb - Ta) * (t - ta) / (tb - ta)
            return ref[-1][1] if t > ref[-1][0] else ref[0][1]
        d = [Ti / interp(t) - 1.0 for t, Ti in T]
        extra["error_vs_edm"] = math.sqrt(sum(x * x for x in d) / len(d))
    else:
        case["edm_series"] = T  # the first method measured is EDM: the hard-sphere reference
        extra["error_vs_edm"] = 0.0
    return T[-1][1], math.sqrt(sum(x * x for x in dev) / len(dev)), extra


# ---------------------------------------------------------------------------------------------
# The poured and settled bed


def pour_case(quick: bool) -> dict:
    scene = CASES / "pour_settle.toml"
    sets = {"output.thermo_interval": 0.05}
    if quick:  # 100 beads from a lower column (0.1-0.3 m), landed and mostly settled by 0.4 s
        sets.update({"particles.beads.count": 100, "run.end_time": 0.4,
                     "particles.beads.region.upper": [0.15, 0.15, 0.3]})
    return {"name": "pour", "scene": scene, "sets": sets, "seeds": [1, 2] if quick else [1, 2, 3],
            "reference": math.nan,  # TDM at the finest step, set by its row
            "tdm": [50, 10] if quick else [200, 100, 50, 20, 10], "hybrid": [10] if quick else HYBRID_K,
            "title": "pour and settle (2000 beads, Hertz-Mindlin, mu = 0.5, e = 0.5): bed height 2<z> "
                     "vs TDM at the finest step",
            "measure": pour_answer}


def bed_height(run) -> float:
    """Twice the mean centre height of the grains in final_state.csv."""
    with open(Path(run.out_dir) / "final_state.csv", newline="") as f:
        z = [float(r["z"]) for r in csv.DictReader(f)]
    return 2.0 * statistics.fmean(z)


def pour_answer(case, runs):
    """(seed mean of 2<z>, its relative deviation from the reference, {noise}); the first TDM row
    (the finest step) is the reference."""
    if any(r.status != "ok" for r in runs):
        return math.nan, math.nan, {}
    h = [bed_height(r) for r in runs]
    mean = statistics.fmean(h)
    noise = statistics.stdev(h) / math.sqrt(len(h)) / mean if len(h) > 1 else math.nan
    if case["_method"] == "tdm" and not math.isfinite(case["reference"]):
        case["reference"] = mean
        # the reference row: not plotted (its error is zero by construction); it carries the floor
        return mean, math.nan, {"noise": noise, "message": "the reference"}
    ref = case["reference"]
    return mean, abs(mean / ref - 1.0) if math.isfinite(ref) else math.nan, {}


# ---------------------------------------------------------------------------------------------
# The pressure of an elastic dense gas


def carnahan_starling(phi: float) -> float:
    """docs/references.md §2.2: P/(nT) = (1 + phi + phi^2 - phi^3)/(1 - phi)^3 (3D hard spheres)."""
    return (1.0 + phi + phi * phi - phi ** 3) / (1.0 - phi) ** 3


def pressure_case(quick: bool) -> dict:
    scene = CASES / "soft_gas.toml"
    # cases/soft_gas.toml: unit diameter and mass, linear k = 9e4, a simple cubic lattice at T = 1.
    phi = 0.4
    N, end, start = (4096, 10.0, 2.0) if not quick else (216, 1.0, 0.5)
    L = (N * math.pi / 6.0 / phi) ** (1.0 / 3.0)
    sets = {"particles.gas.count": N, "domain.upper": [L, L, L], "material.grain.restitution": 1.0,
            "run.end_time": end, "output.thermo_interval": 0.05}
    return {"name": "pressure", "scene": scene, "sets": sets, "n": N / L ** 3, "start": start,
            "seeds": [1, 2] if quick else [1, 2, 3], "reference": carnahan_starling(phi),
            "tdm": [10, 50] if quick else TDM_DIVISORS, "hybrid": [10] if quick else HYBRID_K,
            "title": f"elastic dense gas ({N} spheres, e = 1, phi = {phi}): Z = P/(nT) over t = {start:g}-{end:g} "
                     f"vs Carnahan-Starling {carnahan_starling(phi):.4f}",
            "measure": pressure_answer}


def compressibility(case, run) -> float:
    """The mean over the thermo rows with t >= start of P/(n T)."""
    z = [r["pressure"] / (case["n"] * r["temperature"]) for r in run.thermo()
         if r["time"] >= case["start"] - 1e-12 and r["temperature"] > 0.0]
    return statistics.fmean(z) if z else math.nan


def pressure_answer(case, runs):
    """(seed mean of Z, |Z / Z_CS - 1|, {error_vs_edm, noise}); the first method measured (EDM)
    gives the hard-sphere answer and the floor."""
    if any(r.status != "ok" for r in runs):
        return math.nan, math.nan, {}
    z = [compressibility(case, r) for r in runs]
    mean = statistics.fmean(z)
    extra = {}
    if "edm_z" not in case:
        case["edm_z"] = mean
        extra["noise"] = statistics.stdev(z) / math.sqrt(len(z)) / mean if len(z) > 1 else math.nan
    extra["error_vs_edm"] = abs(mean / case["edm_z"] - 1.0)
    return mean, abs(mean / case["reference"] - 1.0), extra


# ---------------------------------------------------------------------------------------------


def run_case(case, matep, work: Path, repeat: int, log) -> list[dict]:
    rows = []
    base = dict(case["sets"])

    refusal = hybrid_refusal(matep)

    def record(method, setting, sets, dt=math.nan):
        folder = work / f"{method}_{setting.replace('/', '_')}"
        if method == "hybrid" and refusal:
            runs = [Run(2, "refused", refusal, None, folder)]  # the CLI refuses the method itself: not run
        elif case.get("seeds"):
            runs = [run_matep(matep, case["scene"], {**sets, "run.seed": seed}, f"{folder}_seed{seed}")
                    for seed in case["seeds"]]
            walls = [x.wall_seconds for x in runs]
            if all(x.summary is not None for x in runs):
                runs[0].summary = {**runs[0].summary, "wall_seconds": statistics.median(walls)}
        elif case.get("timing"):
            runs = [run_matep(matep, case["scene"], sets, folder)]
            r = runs[0]
            timed = run_repeated(matep, case["scene"], {**sets, **case["timing"]}, str(folder) + "_timed", repeat) \
                if r.summary is not None else r
            if timed.summary is not None and r.summary is not None:
                r.summary = {**r.summary, "wall_seconds": timed.wall_seconds}
        else:
            runs = [run_repeated(matep, case["scene"], sets, folder, repeat)]
        r = next((x for x in runs if x.status != "ok"), runs[0])  # the first failure speaks for the row
        case["_method"] = method
        answer, error, extra = case["measure"](case, runs)
        row = {"case": case["name"], "method": method, "setting": setting, "wall_seconds": r.wall_seconds,
               "error": error, "status": r.status, "answer": answer, "reference": case["reference"],
               "dt": dt if r.summary is None or "soft" not in r.summary else float(r.summary["soft"]["dt"]),
               "time_reached": r.time_reached, "runs": len(runs), "message": r.message, **extra}
        if r.status == "refused":
            row["wall_seconds"] = row["error"] = math.nan
        rows.append(row)
        log(f"{case['name']:5s} {method:6s} {setting:8s} status {r.status:9s} wall {row['wall_seconds']:.4g} s "
            f"error {error:.3g}" + (f" (vs EDM {extra['error_vs_edm']:.3g})" if "error_vs_edm" in extra else "")
            + (f"  ({r.message})" if r.status not in ("ok", "collapse") else ""))

    record("edm", "exact", {**base, "run.method": "edm"})
    soft = {**base, "run.method": "tdm", "run.threads": 1}
    tc = check_soft(matep, case["scene"], soft)["contact_time"]
    for n in case["tdm"]:
        record("tdm", f"t_c/{n}", {**soft, "run.dt": tc / n}, tc / n)
    for k in case["hybrid"]:
        record("hybrid", f"k={k}", {**base, "run.method": "hybrid", "run.threads": 1, "hybrid.stability": k})
    return rows


STYLE = {"edm": ("EDM (event-driven hard spheres)", "*", "tab:red", 14),
         "tdm": ("TDM (soft spheres), dt = t_c/n", "o", "tab:blue", 7),
         "hybrid": ("hybrid, stability rule k", "s", "tab:green", 7)}


def draw(ax, rows, field, ylabel, title, methods):
    """Error `field` against wall time, one line per method; returns the rows left out."""
    skipped = []
    for method in methods:
        label, marker, color, size = STYLE[method]
        pts = [r for r in rows if r["method"] == method]
        ok = [r for r in pts if math.isfinite(r.get(field, math.nan)) and math.isfinite(r["wall_seconds"])]
        skipped += [r for r in pts if r not in ok]
        if not ok:
            st = sorted({r["status"] for r in pts})
            ax.plot([], [], marker=marker, color=color, linestyle="none", markersize=size,
                    label=f"{label}: {', '.join(st)} (not plotted)")
            continue
        if method == "hybrid":
            ok.sort(key=lambda r: r["wall_seconds"])  # k does not order the cost
        xs = [r["wall_seconds"] for r in ok]
        ys = [max(r[field], 1e-16) for r in ok]
        ax.plot(xs, ys, marker=marker, color=color, markersize=size, linestyle="-" if len(ok) > 1 else "none",
                label=label)
        for i, (r, x, y) in enumerate(zip(ok, xs, ys)):
            text = r["setting"] if method != "edm" else ("collapse at the Zeno time" if r["status"] == "collapse"
                                                         else r["status"])
            if method == "hybrid":  # below the points, staggered: settings often cost about the same
                ax.annotate(text, (x, y), textcoords="offset points", xytext=(4 + 12 * i, -16 - 11 * i), fontsize=8,
                            color=color, arrowprops={"arrowstyle": "-", "color": color, "lw": 0.5})
            else:
                ax.annotate(text, (x, y), textcoords="offset points", xytext=(6, 5), fontsize=8, color=color)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time per run (s, one core)")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    # The reference method's row carries the floor (the gas: EDM's; the pour: the finest TDM's).
    ref = next((r for r in rows if math.isfinite(r.get("noise", math.nan))), None)
    if ref:
        ax.axhline(ref["noise"] * (math.sqrt(2.0) if field == "error_vs_edm" else 1.0), color="gray", ls="--", lw=1,
                   label="statistical floor (standard error of the seed mean)")
    ax.legend(fontsize=7.5, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, frameon=False)
    return skipped


def plot(case, rows, png: Path):
    plt = import_pyplot()
    if case["name"] == "ball":
        fig, ax = plt.subplots(figsize=(8.0, 6.2))
        skipped = draw(ax, rows, "error", "relative error of the rest time", case["title"], STYLE)
    elif case["name"] == "pour":
        fig, ax = plt.subplots(figsize=(8.0, 6.2))
        seeds = len(case["seeds"])
        skipped = draw(ax, rows, "error", "|<2<z>> / reference - 1|", case["title"] +
                       f"\n<2<z>>: mean of {seeds} random placements; reference: TDM at t_c/{case['tdm'][0]}",
                       STYLE)
    elif case["name"] == "pressure":
        fig, (ax, bx) = plt.subplots(1, 2, figsize=(13.0, 6.2))
        seeds = len(case["seeds"])
        skipped = draw(ax, rows, "error", "|Z / Z_CS - 1|", case["title"] + f"\nZ: mean of {seeds} starts", STYLE)
        draw(bx, rows, "error_vs_edm", "|Z / Z_EDM - 1|",
             "the same against EDM from the same starts (the hard-sphere answer)", ["tdm", "hybrid"])
    else:
        fig, (ax, bx) = plt.subplots(1, 2, figsize=(13.0, 6.2))
        seeds = len(case["seeds"])
        skipped = draw(ax, rows, "error", "RMS of <T>/T_Haff - 1", case["title"] +
                       f"\n<T>: mean of {seeds} random start{'s' if seeds > 1 else ''}", STYLE)
        draw(bx, rows, "error_vs_edm", "RMS of <T>/<T_EDM> - 1",
             "the same against EDM from the same starts (the hard-sphere answer)", ["tdm", "hybrid"])
    if skipped:
        groups = {}
        for r in skipped:
            groups.setdefault((r["method"], r["status"], r["message"]), []).append(r["setting"])
        lines = [f"not plotted: {m} {', '.join(s)}: {st}" + (f" ({msg[:100]})" if msg else "")
                 for (m, st, msg), s in groups.items()]
        fig.text(0.01, 0.005, "\n".join(lines), fontsize=7, va="bottom", ha="left", color="dimgray")
        fig.tight_layout(rect=(0, 0.03 * len(lines), 1, 1))
    else:
        fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("case", choices=["ball", "gas", "pour", "pressure"])
    ap.add_argument("--matep", default="build/matep", help="the matep executable (default build/matep)")
    ap.add_argument("--out", default="charts", help="folder for accuracy_CASE.csv and .png (default charts/)")
    ap.add_argument("--quick", action="store_true", help="tiny versions, a few seconds (the test suite's mode)")
    ap.add_argument("--repeat", type=int, default=None,
                    help="ball: timed runs per point, median wall time (default 5, quick 1)")
    ap.add_argument("--work", default=None, help="keep the runs' outputs in this folder (default: a temporary one)")
    ap.add_argument("--plot-only", action="store_true", help="redraw the PNG from the CSV in --out, running nothing")
    args = ap.parse_args(argv)
    case = {"ball": ball_case, "gas": gas_case, "pour": pour_case, "pressure": pressure_case}[args.case](args.quick)
    out = Path(args.out)
    csv_path, png_path = out / f"accuracy_{args.case}.csv", out / f"accuracy_{args.case}.png"
    if args.plot_only:
        with open(csv_path, newline="") as f:
            rows = [{k: (v if k in ("case", "method", "setting", "status", "message") else
                         float(v) if v else math.nan) for k, v in row.items()} for row in csv.DictReader(f)]
        plot(case, rows, png_path)
        print(f"wrote {png_path}")
        return
    matep = Path(args.matep).resolve()
    if not matep.exists():
        ap.error(f"--matep {args.matep}: no such file (build it: cmake --build build --target matep)")
    repeat = args.repeat or (1 if args.quick else 5)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="matep_bench_") as tmp:
        work = Path(args.work) if args.work else Path(tmp)
        rows = run_case(case, matep, work, repeat, lambda s: print(s, flush=True))
    write_csv(csv_path, FIELDS, rows)
    plot(case, rows, png_path)
    print(f"wrote {csv_path} and {png_path}")


if __name__ == "__main__":
    main()
