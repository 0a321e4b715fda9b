#!/usr/bin/python3
"""Stability map: a small gas of inelastic spheres swept over restitution e and packing fraction phi,
freely cooling in a periodic box and settling under gravity onto a floor, run with every method; each
cell is marked stable, collapse (EDM's inelastic collapse), blow-up (TDM's status "unstable") or
refused (the CLI would not run it), and gets each method's wall time and an accuracy figure against
the cell's reference.

    /usr/bin/python3 tools/stability_map.py --matep build/matep --out charts/

writes charts/stability_map.csv, charts/stability_map.png (one panel per method and step, a row per
gravity setting) and charts/stability_map_ratio.png (the hybrid's wall time over the better pure
method's, with its accuracy, per cell). --quick runs a 2 x 2 map of 108 particles and 2 seeds (a few
seconds; the test suite's mode). --repeat N runs each seed of EDM, TDM at t_c/50 and the hybrid, whose
times make the hybrid's ratio, N times, each with a memory layout of its own (tools/matep_runs.py
run_matep), and keeps the median wall time: a single run's time varies by up to 40 % with the layout
(charts/README.md). Their repeats alternate round by round (tools/matep_runs.py run_interleaved), and
the ratio is then the median of the ratios within a round and a seed (paired_ratio). The once-run TDM
panels and the reference (TDM at t_c/200) run once: their times make no ratio.

The case: 500 unit spheres (unit mass) on a face-centred cubic lattice (5 x 5 x 5 cells; it reaches
every packing fraction of the map, up to 0.55) sized for the packing fraction, Maxwellian velocities
at T = 1 from the seed, constant restitution e, linear spring-dashpot with k_n = 9e4 for the soft
methods (overlaps near 1 % of d, as cases/soft_gas.toml), no friction, run to t = 20.
* no gravity: a periodic cube; the gas cools freely (Haff's law, then clusters);
* gravity: periodic sideways, a floor and a lid (plane walls) one diameter beyond the lattice,
  g = 1 downwards (the thermal speed is 1: the gas falls onto the floor by t ~ 5 and settles into a
  bed of 5-11 diameters).
Methods and panels:
* EDM: pure event-driven hard spheres (collapse watch at its defaults);
* TDM at the default step (t_c/50);
* TDM at 0.8 x the stability limit `matep check` prints for the cell (limit
  2/(eta + sqrt(eta^2 + omega0^2)) of one pair contact; a dense or strongly damped gas may still
  blow up below it); first seed only;
* TDM at 2 x the limit: the CLI refuses a run.dt above the limit (exit 2, message naming the
  limit), so these cells are "refused": no run is made and none is faked; first seed only;
* hybrid at its default rule (run.method = "hybrid"): "refused" while the CLI refuses the method.
Every soft run uses one thread. Every run has run.max_events = 10^6 (a legitimate run of this map
needs far fewer): an EDM run that stops there without reaching the end is "stalled". Any other stop
(escaped, a run past 300 s, a crash) is "failed". A method's outcome in a cell is its worst over
the seeds; its wall time is the median over the seeds.

Accuracy: an observable per run, averaged over the seeds (S = 3; each seed has its own velocities):
the mean temperature over the second half of the run (no gravity) or the mean height of the grains
at the end (gravity: the settled bed). The reference is EDM where it reaches the end for every seed,
otherwise TDM at t_c/200. A method's deviation is its mean minus the reference's, in units of the
statistical floor: the standard error of that difference, from the seed-to-seed variance pooled
over the cell's methods (assess()); within 2.5 is within the floor. The ratio chart divides the hybrid's time by the faster of EDM (where it reached the
end for every seed) and TDM at its default step.
"""
from __future__ import annotations

import argparse
import csv
import math
import random
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from matep_runs import check_soft, import_pyplot, run_interleaved, run_repeated, write_csv  # noqa: E402

FIELDS = ["gravity", "method", "setting", "e", "phi", "status", "outcome", "wall_seconds", "time_reached", "dt",
          "max_stable_dt", "max_overlap_relative", "observable", "observable_se", "reference", "deviation",
          "ratio", "seeds", "message"]
OUTCOME = {"ok": "stable", "collapse": "collapse", "unstable": "blow-up", "refused": "refused",
           "max_events": "stalled"}
COLORS = {"stable": "#8fd18f", "collapse": "#f5b041", "stalled": "#b9770e", "blow-up": "#e74c3c",
          "refused": "#d5d8dc", "failed": "#a569bd"}
# Worst first: a method's outcome in a cell is the worst of its seeds'.
SEVERITY = ["failed", "blow-up", "stalled", "collapse", "refused", "stable"]
MAX_EVENTS = 1_000_000
# restitutions, packing fractions, fcc cells per side (4 n^3 grains), end time, seeds
FULL = ([0.1, 0.3, 0.5, 0.7, 0.9, 0.95], [0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.55], 5, 20.0, 3)
QUICK = ([0.3, 0.9], [0.1, 0.5], 3, 2.0, 2)
GRAVITY = [False, True]
RUN_TIMEOUT = 300  # seconds; a run beyond it is recorded as "timeout" (outcome "failed")
PANELS = [("edm", "exact"), ("tdm", "t_c/50"), ("tdm", "0.8 limit"), ("tdm", "2 limit"), ("hybrid", "default")]
TITLES = {("edm", "exact"): "EDM (hard spheres)", ("tdm", "t_c/50"): "TDM, dt = t_c/50 (default)",
          ("tdm", "0.8 limit"): "TDM, dt = 0.8 x stability limit", ("tdm", "2 limit"): "TDM, dt = 2 x limit",
          ("hybrid", "default"): "hybrid (default rule)"}
REFERENCE = ("tdm", "t_c/200")  # where EDM does not reach the end
WITHIN = 2.5  # a deviation within this many floors is "within the statistical floor" (Student's t,
# two-sided 95 %, for the six degrees of freedom of three methods of three seeds)

SCENE = """# Written by tools/stability_map.py: a gas of the stability map.
[run]
dimension = 3
method = "edm"
end_time = {end}
gravity = {gravity}

[domain]
lower = [0.0, 0.0, 0.0]
upper = [{L}, {L}, {H}]
periodic = [true, true, {zper}]

[material.grain]
density = 1.909859317102744   # unit mass for unit diameter
restitution = 0.9
contact = "linear"
stiffness = 9.0e4

[particles.gas]
material = "grain"
file = "{state}"

[output]
thermo_interval = {thermo}
{walls}"""

WALLS = """
[wall.floor]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "grain"

[wall.lid]
type = "plane"
point = [0.0, 0.0, {H}]
normal = [0.0, 0.0, -1.0]
material = "grain"
"""


def fcc_state(n: int, phi: float, seed: int, gravity: bool):
    """Positions of 4 n^3 unit spheres on an fcc lattice at packing fraction phi, Maxwellian
    velocities at T = 1 with zero total momentum (seeded), the box side L and height H. With gravity
    the lattice sits 0.52 above the floor and the lid is 1.02 above the lattice's top."""
    a = (4.0 * math.pi / 6.0 / phi) ** (1.0 / 3.0)  # 4 spheres of volume pi/6 per cube a^3
    L = n * a
    basis = [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0), (0.5, 0.0, 0.5), (0.0, 0.5, 0.5)]
    z0 = 0.52 if gravity else 0.25 * a
    xs = [((i + bx + 0.25) * a, (j + by + 0.25) * a, z0 + (k + bz) * a)
          for i in range(n) for j in range(n) for k in range(n) for bx, by, bz in basis]
    H = (z0 + (n - 0.5) * a + 0.52) if gravity else L
    rng = random.Random(1000 + seed)
    vs = [[rng.gauss(0.0, 1.0) for _ in range(3)] for _ in xs]
    mean = [sum(v[k] for v in vs) / len(vs) for k in range(3)]
    vs = [[v[k] - mean[k] for k in range(3)] for v in vs]
    T = sum(v[k] ** 2 for v in vs for k in range(3)) / (3.0 * len(vs))
    s = 1.0 / math.sqrt(T)
    vs = [[s * c for c in v] for v in vs]
    return xs, vs, L, H


def write_scene(work: Path, n, phi, seed, gravity, end) -> Path:
    xs, vs, L, H = fcc_state(n, phi, seed, gravity)
    tag = f"{'g' if gravity else 'free'}_phi{phi}_s{seed}"
    state = work / f"state_{tag}.csv"
    with open(state, "w") as f:
        f.write("x,y,z,vx,vy,vz,radius\n")
        for x, v in zip(xs, vs):
            f.write(",".join(repr(c) for c in (*x, *v)) + ",0.5\n")
    scene = work / f"gas_{tag}.toml"
    scene.write_text(SCENE.format(end=repr(float(end)), L=repr(L), H=repr(H), zper="false" if gravity else "true",
                                  gravity="[0.0, 0.0, -1.0]" if gravity else "[0.0, 0.0, 0.0]", state=state.name,
                                  thermo=repr(end / 40.0), walls=WALLS.format(H=repr(H)) if gravity else ""))
    return scene


def observable(run, gravity: bool, end: float) -> float:
    """Mean temperature over the second half of the run (no gravity), or the grains' mean height
    at the end (gravity); NaN if the run did not reach the end."""
    if run.summary is None or run.status != "ok":
        return math.nan
    if gravity:
        p = Path(run.out_dir) / "final_state.csv"
        with open(p, newline="") as f:
            zs = [float(r["z"]) for r in csv.DictReader(f)]
        return sum(zs) / len(zs)
    ts = [r["temperature"] for r in run.thermo() if r["time"] >= 0.5 * end - 1e-12]
    return sum(ts) / len(ts) if ts else math.nan


def mean_se(xs):
    xs = [x for x in xs if math.isfinite(x)]
    if not xs:
        return math.nan, math.nan
    if len(xs) == 1:
        return xs[0], math.nan
    return statistics.fmean(xs), statistics.stdev(xs) / math.sqrt(len(xs))


def worst(outcomes):
    return min(outcomes, key=SEVERITY.index)


def sweep(matep, work: Path, es, phis, n, end, seeds, log, repeat=1, gravities=GRAVITY, only=None) -> list[dict]:
    """only: the (e, phi) cells of es x phis to run (None: every one)."""
    rows = []
    for gravity in gravities:
        for phi in phis:
            scenes = [write_scene(work, n, phi, s, gravity, end) for s in range(seeds)]
            for e in es:
                if only is not None and (e, phi) not in only:
                    continue
                base = {"material.grain.restitution": float(e), "run.max_events": MAX_EVENTS}
                soft = {**base, "run.method": "tdm", "run.threads": 1}
                chk = check_soft(matep, scenes[0], soft)
                lim, tc = chk["max_stable_dt"], chk["contact_time"]
                runs = [("edm", "exact", {**base, "run.method": "edm"}, math.nan, seeds),
                        ("tdm", "t_c/50", soft, chk["dt"], seeds),
                        ("tdm", "0.8 limit", {**soft, "run.dt": 0.8 * lim}, 0.8 * lim, 1),
                        ("tdm", "2 limit", {**soft, "run.dt": 2.0 * lim}, 2.0 * lim, 1),
                        ("hybrid", "default", {**base, "run.method": "hybrid", "run.threads": 1}, math.nan, seeds)]
                # The hybrid's ratio compares the runs of EDM, TDM at t_c/50 and the hybrid: their
                # repeats alternate (run_interleaved), seed by seed within a round, the hybrid's run
                # right after EDM's and before TDM's (the slowest), so that each pair the ratio is
                # taken from ran seconds apart at most; the once-run TDM panels follow.
                timed = sorted((r for r in runs if r[4] == seeds), key=lambda r: r[0] == "tdm")
                order = [(k, s) for s in range(seeds) for k in range(len(timed))]
                jobs = [(scenes[s], timed[k][2], run_folder(work, gravity, timed[k][0], timed[k][1], e, phi, s))
                        for k, s in order]
                results = dict(zip(order, run_interleaved(matep, jobs, repeat, timeout=RUN_TIMEOUT)))
                done = {}
                for k, (method, setting, sets, dt, nseeds) in enumerate(timed):
                    done[(method, setting)] = summarize([results[(k, s)] for s in range(seeds)], gravity, e, phi,
                                                        method, setting, dt, lim, end)
                # The rest run once whatever --repeat says (run_method): no ratio is taken from their
                # times (the reference is most of a gravity cell's time: 24 of the gravity half's 37
                # minutes a round), and their results do not depend on the memory layout.
                cell = []
                for method, setting, sets, dt, nseeds in runs:
                    cell.append(done.get((method, setting)) or
                                run_method(matep, work, scenes[:nseeds], gravity, e, phi, method, setting, sets, dt,
                                           lim, end))
                edm_ok = cell[0]["outcome"] == "stable"
                if not edm_ok:  # the reference: TDM at t_c/200
                    cell.append(run_method(matep, work, scenes, gravity, e, phi, *REFERENCE,
                                           {**soft, "run.dt": chk["dt"] / 4.0}, chk["dt"] / 4.0, lim, end))
                assess(cell)
                if not math.isnan(tc):
                    cell[1]["message"] = cell[1]["message"] or f"t_c = {tc:.6g}, stability limit {lim:.6g}"
                for r in cell:
                    stopped = r["outcome"] in ("collapse", "blow-up", "stalled")
                    log(f"{'g' if gravity else '-'} e {e:<4} phi {phi:<5} {r['method']:6s} {r['setting']:9s} "
                        f"{r['outcome']:8s} wall {r['wall_seconds']:.3g} s"
                        + (f"  t = {r['time_reached']:.4g}" if stopped else "")
                        + (f"  dev {r['deviation']:+.2f}" if math.isfinite(r['deviation']) else "")
                        + (f"  ratio {r['ratio']:.2f}" if math.isfinite(r.get('ratio', math.nan)) else ""))
                rows += cell
    return rows


def assess(cell):
    """The reference, each method's deviation from it and the hybrid's time ratio in one cell (its
    rows). The floor is the standard error of a difference of two seed means, from the seed-to-seed
    variance pooled over the methods with a mean (the reference, EDM, TDM at t_c/50, the hybrid:
    three seeds give each only two degrees of freedom, too few to judge a method by its own)."""
    by = {(r["method"], r["setting"]): r for r in cell}
    edm = by.get(("edm", "exact"))
    edm_ok = edm is not None and edm["outcome"] == "stable"
    ref = edm if edm_ok else by.get(REFERENCE)
    pool = [r for r in cell if r["seeds"] >= 2 and math.isfinite(r["observable_se"])]
    dof = sum(r["seeds"] - 1 for r in pool)
    var = sum((r["seeds"] - 1) * r["seeds"] * r["observable_se"] ** 2 for r in pool) / dof if dof else math.nan
    for r in cell:
        r["reference"] = f"{ref['method']} {ref['setting']}" if ref else ""
        if ref is None:
            r["deviation"] = math.nan
        elif r is ref:
            r["deviation"] = 0.0
        elif math.isfinite(r["observable"]) and math.isfinite(ref["observable"]) and var > 0:
            floor = math.sqrt(var * (1.0 / r["seeds"] + 1.0 / ref["seeds"]))
            r["deviation"] = (r["observable"] - ref["observable"]) / floor
        else:
            r["deviation"] = math.nan
    hyb, tdm = by.get(("hybrid", "default")), by.get(("tdm", "t_c/50"))
    if hyb is not None and tdm is not None:
        best = min([tdm] + ([edm] if edm_ok else []), key=lambda r: r["wall_seconds"])
        hyb["ratio"] = paired_ratio(hyb, best) if hyb["outcome"] == "stable" else math.nan


def paired_ratio(a, b) -> float:
    """a's wall time over b's. With repeats (--repeat, run_interleaved), the median of the ratios of
    the runs of one seed in one round, which ran one after the other: a drift of the host's speed
    between rounds cancels in each, where a ratio of the two medians kept it (three runs of 15
    rounds of the dilute cell e = 0.1, phi = 0.05: 1.29-1.36 paired, 1.12-1.37 as a ratio of medians).
    Otherwise the ratio of the medians over the seeds."""
    ra, rb = a.get("round_walls") or [], b.get("round_walls") or []
    pairs = [x / y for wa, wb in zip(ra, rb) if len(wa) == len(wb) > 1 for x, y in zip(wa, wb)
             if math.isfinite(x) and math.isfinite(y) and y > 0]
    if pairs and len(ra) == len(rb):
        return statistics.median(pairs)
    return a["wall_seconds"] / b["wall_seconds"]


def run_folder(work, gravity, method, setting, e, phi, s) -> Path:
    return work / (f"{'g' if gravity else 'free'}_{method}_{setting.replace(' ', '_').replace('/', '_')}"
                   f"_e{e}_phi{phi}_s{s}")


def run_method(matep, work, scenes, gravity, e, phi, method, setting, sets, dt, lim, end) -> dict:
    """A method whose time makes no ratio (the reference, the once-run TDM panels): one run a seed."""
    results = [run_repeated(matep, scene, sets, run_folder(work, gravity, method, setting, e, phi, s),
                            timeout=RUN_TIMEOUT) for s, scene in enumerate(scenes)]
    return summarize(results, gravity, e, phi, method, setting, dt, lim, end)


def summarize(results, gravity, e, phi, method, setting, dt, lim, end) -> dict:
    """One method's row of a cell from its runs, one per seed."""
    outcomes = [OUTCOME.get(r.status, "failed") for r in results]
    w = worst(outcomes)
    first_bad = next((r for r, o in zip(results, outcomes) if o == w), results[0])
    walls = [r.wall_seconds for r in results if math.isfinite(r.wall_seconds)]
    obs, se = mean_se([observable(r, gravity, end) for r in results]) if w == "stable" else (math.nan, math.nan)
    s0 = results[0].summary or {}
    return {"gravity": int(gravity), "method": method, "setting": setting, "e": float(e), "phi": float(phi),
            "status": first_bad.status, "outcome": w,
            "wall_seconds": statistics.median(walls) if walls else math.nan,
            "time_reached": min((r.time_reached for r in results), default=math.nan),
            "dt": float(s0["soft"]["dt"]) if "soft" in s0 else dt,
            "max_stable_dt": lim if method != "edm" else math.nan,
            "max_overlap_relative": max((float((r.summary or {}).get("max_overlap_relative", math.nan))
                                         for r in results), default=math.nan),
            "observable": obs, "observable_se": se, "reference": "", "deviation": math.nan, "ratio": math.nan,
            "seeds": len(results), "message": first_bad.message, "round_walls": [r.walls for r in results]}


def cell_text(r):
    o = r["outcome"]
    if o == "stable":
        return f"ok\n{r['wall_seconds']:.2g} s"
    if o in ("collapse", "blow-up", "stalled"):
        return f"{o}\nt = {r['time_reached']:.2g}"
    return o


def grid(ax, es, phis):
    ax.set_xlim(-0.5, len(phis) - 0.5)
    ax.set_ylim(-0.5, len(es) - 0.5)
    ax.set_xticks(range(len(phis)), [f"{p:g}" for p in phis], fontsize=7)
    ax.set_yticks(range(len(es)), [f"{e:g}" for e in es], fontsize=7)
    ax.set_xlabel("packing fraction phi", fontsize=8)


def plot(rows, es, phis, png: Path, subtitle: str):
    plt = import_pyplot()
    from matplotlib.patches import Patch
    gravities = sorted({int(r["gravity"]) for r in rows})
    fig, axes = plt.subplots(len(gravities), len(PANELS), figsize=(3.3 * len(PANELS), 3.7 * len(gravities)),
                             sharey=True, squeeze=False)
    for row_axes, g in zip(axes, gravities):
        for ax, key in zip(row_axes, PANELS):
            cells = {(r["e"], r["phi"]): r for r in rows if (r["method"], r["setting"]) == key and int(r["gravity"]) == g}
            for i, phi in enumerate(phis):
                for j, e in enumerate(es):
                    r = cells.get((float(e), float(phi)))
                    if r is None:
                        continue
                    o = r["outcome"]
                    ax.add_patch(plt.Rectangle((i - 0.5, j - 0.5), 1, 1, facecolor=COLORS[o], edgecolor="white",
                                               hatch="//" if o == "refused" else None, linewidth=1.5))
                    ax.text(i, j, cell_text(r), ha="center", va="center", fontsize=6)
            grid(ax, es, phis)
            title = TITLES[key] + (" - gravity" if g else " - free cooling")
            refused = [r for r in cells.values() if r["outcome"] == "refused"]
            if refused and len(refused) == len(cells):
                msg = refused[0]["message"]
                title += "\nrefused: " + ("method not in this matep" if "not available" in msg else
                                          "run.dt above the limit" if "stability limit" in msg else msg[:40])
            ax.set_title(title, fontsize=8)
        row_axes[0].set_ylabel("restitution e", fontsize=8)
    handles = [Patch(facecolor=c, label=o, hatch="//" if o == "refused" else None) for o, c in COLORS.items()
               if any(r["outcome"] == o for r in rows) or o in ("stable", "collapse", "blow-up")]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.suptitle("stability map: " + subtitle, fontsize=9)
    fig.tight_layout(rect=(0, 0.05, 1, 0.96))
    fig.savefig(png, dpi=100)
    plt.close(fig)


def plot_ratio(rows, es, phis, png: Path, subtitle: str):
    """The hybrid's wall time over the better pure method's per cell (colour, log scale) and its
    accuracy (deviation from the reference in statistical floors)."""
    plt = import_pyplot()
    from matplotlib.colors import LogNorm
    gravities = sorted({int(r["gravity"]) for r in rows})
    fig, axes = plt.subplots(1, len(gravities), figsize=(5.2 * len(gravities), 4.6), sharey=True, squeeze=False)
    norm = LogNorm(vmin=0.1, vmax=10.0)
    cmap = plt.get_cmap("RdYlGn_r")
    for ax, g in zip(axes[0], gravities):
        cells = {(r["e"], r["phi"]): r for r in rows if (r["method"], r["setting"]) == ("hybrid", "default")
                 and int(r["gravity"]) == g}
        for i, phi in enumerate(phis):
            for j, e in enumerate(es):
                r = cells.get((float(e), float(phi)))
                if r is None:
                    continue
                ratio, dev = r["ratio"], r["deviation"]
                if math.isfinite(ratio):
                    face = cmap(norm(min(max(ratio, 0.1), 10.0)))
                    text = f"{ratio:.2g}x"
                else:
                    face, text = COLORS.get(r["outcome"], "#cccccc"), r["outcome"]
                if math.isfinite(dev):
                    text += f"\n{dev:+.1f} sd"
                ax.add_patch(plt.Rectangle((i - 0.5, j - 0.5), 1, 1, facecolor=face, edgecolor="white", linewidth=1.5,
                                           hatch="xx" if math.isfinite(dev) and abs(dev) > WITHIN else None))
                ax.text(i, j, text, ha="center", va="center", fontsize=6.5)
        grid(ax, es, phis)
        ax.set_title("hybrid time / better pure method's - " + ("gravity, floor" if g else "free cooling"), fontsize=8)
    axes[0][0].set_ylabel("restitution e", fontsize=8)
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, ax=axes[0].tolist(), shrink=0.8, label="hybrid / min(EDM if it ends, TDM t_c/50)")
    fig.suptitle(f"hybrid against the better pure method ({subtitle}); second line: accuracy, "
                 f"deviation from the reference in statistical floors (hatched beyond {WITHIN:g})", fontsize=8)
    fig.savefig(png, dpi=100, bbox_inches="tight")
    plt.close(fig)


def read_rows(csv_path):
    words = ("method", "setting", "status", "outcome", "message", "reference")
    with open(csv_path, newline="") as f:
        return [{k: (v if k in words else float(v) if v else math.nan) for k, v in row.items()}
                for row in csv.DictReader(f)]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--matep", default="build/matep", help="the matep executable (default build/matep)")
    ap.add_argument("--out", default="charts", help="folder for stability_map.csv and the PNGs (default charts/)")
    ap.add_argument("--quick", action="store_true", help="a 2 x 2 map of 108 particles, 2 seeds (the test suite's mode)")
    ap.add_argument("--work", default=None, help="keep the runs' outputs in this folder (default: a temporary one)")
    ap.add_argument("--plot-only", action="store_true", help="redraw the PNGs from the CSV in --out, running nothing")
    ap.add_argument("--gravity", choices=["both", "off", "on"], default="both",
                    help="which half of the map to run (the other half's rows in --out's CSV are kept)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="runs per seed of EDM, TDM at t_c/50 and the hybrid (the reference and the other TDM "
                         "panels run once), each with a memory layout of its own; the wall time is their median "
                         "(use 3 or more to compare versions: a single run varies by up to 40 %%)")
    ap.add_argument("--cells", default=None,
                    help="only these cells, as e:phi pairs separated by commas (e.g. 0.3:0.05,0.5:0.55), "
                         "written to stability_map_cells.csv in --out (the map's CSV and PNGs are left as they "
                         "are): a check of a few cells with more seeds")
    ap.add_argument("--seeds", type=int, default=None, help="seeds per cell (default 3; 2 with --quick)")
    args = ap.parse_args(argv)
    es, phis, n, end, seeds = QUICK if args.quick else FULL
    if args.seeds is not None:
        if args.seeds < 1:
            ap.error(f"--seeds {args.seeds}: must be at least 1")
        seeds = args.seeds
    only = None
    if args.cells is not None and args.plot_only:
        ap.error("--cells: runs cells; --plot-only runs nothing (give one of them)")
    if args.cells is not None:
        only = set()
        for item in args.cells.split(","):
            try:
                e_s, phi_s = item.split(":")
                cell = (float(e_s), float(phi_s))
            except ValueError:
                ap.error(f"--cells {args.cells}: '{item}' is not e:phi (e.g. 0.3:0.05)")
            if not (0.0 < cell[0] <= 1.0 and 0.0 < cell[1] < 0.74):
                ap.error(f"--cells {args.cells}: '{item}' needs 0 < e <= 1 and 0 < phi < 0.74")
            only.add(cell)
        es = sorted({c[0] for c in only})
        phis = sorted({c[1] for c in only})
    out = Path(args.out)
    csv_path = out / "stability_map.csv"
    png_path, ratio_path = out / "stability_map.png", out / "stability_map_ratio.png"
    subtitle = f"{4 * n ** 3} spheres, fcc start, T0 = 1, linear k_n = 9e4, to t = {end:g}, {seeds} seeds"
    if args.plot_only:
        rows = read_rows(csv_path)
        for g in {r["gravity"] for r in rows}:
            for e in es:
                for phi in phis:
                    assess([r for r in rows if r["gravity"] == g and r["e"] == e and r["phi"] == phi])
        write_csv(csv_path, FIELDS, rows)
        plot(rows, es, phis, png_path, subtitle)
        plot_ratio(rows, es, phis, ratio_path, subtitle)
        print(f"wrote {png_path} and {ratio_path}")
        return
    if args.repeat < 1:
        ap.error(f"--repeat {args.repeat}: must be at least 1")
    matep = Path(args.matep).resolve()
    if not matep.exists():
        ap.error(f"--matep {args.matep}: no such file (build it: cmake --build build --target matep)")
    out.mkdir(parents=True, exist_ok=True)
    gravities = {"both": GRAVITY, "off": [False], "on": [True]}[args.gravity]
    with tempfile.TemporaryDirectory(prefix="matep_map_") as tmp:
        work = Path(args.work) if args.work else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        rows = sweep(matep, work, es, phis, n, end, seeds, lambda s: print(s, flush=True), args.repeat, gravities,
                     only)
    if only is not None:
        cells_path = out / "stability_map_cells.csv"
        write_csv(cells_path, FIELDS, rows)
        print(f"wrote {cells_path}")
        return
    if args.gravity != "both" and csv_path.exists():
        # One half run: the other half's rows in the CSV are kept, so the map stays whole.
        ran = {int(g) for g in gravities}
        kept = [r for r in read_rows(csv_path) if int(r["gravity"]) not in ran]
        rows = sorted(kept + rows, key=lambda r: int(r["gravity"]))
        if kept:
            print(f"kept the other half's {len(kept)} rows of {csv_path}")
    write_csv(csv_path, FIELDS, rows)
    plot(rows, es, phis, png_path, subtitle)
    plot_ratio(rows, es, phis, ratio_path, subtitle)
    print(f"wrote {csv_path}, {png_path} and {ratio_path}")


if __name__ == "__main__":
    main()
