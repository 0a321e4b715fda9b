#!/usr/bin/python3
"""Stability map: a small freely cooling gas swept over restitution e and packing fraction phi,
run with every method; each cell is marked stable, collapse (EDM's inelastic collapse), blow-up
(TDM's status "unstable") or refused (the CLI would not run it).

    /usr/bin/python3 tools/stability_map.py --matep build/matep --out charts/

writes charts/stability_map.csv and charts/stability_map.png (one panel per method and step).
--quick runs a 2 x 2 map of 64 particles (a second or two; the test suite's mode). --repeat N runs
each cell N times, each with a memory layout of its own (tools/matep_runs.py run_matep), and keeps
the median wall time: a single run's time varies by up to 40 % with the layout (charts/README.md).

The case: 512 unit spheres (unit mass) on a simple cubic lattice in a periodic cube sized for the
packing fraction (a lattice reaches phi = 0.5; random placement stops at 0.384), Maxwellian
velocities at T = 1, constant restitution e, linear spring-dashpot with k_n = 9e4 for the soft
methods (overlaps near 1 % of d, as cases/soft_gas.toml), no friction, run to t = 20.
Panels:
* EDM: pure event-driven hard spheres (collapse watch at its defaults);
* TDM at the default step (t_c/50);
* TDM at 0.8 x the stability limit `matep check` prints for the cell (limit
  2/(eta + sqrt(eta^2 + omega0^2)) of one pair contact; a dense or strongly damped gas may still
  blow up below it);
* TDM at 2 x the limit: the CLI refuses a run.dt above the limit (exit 2, message naming the
  limit), so these cells are "refused": no run is made and none is faked;
* hybrid at its default rule (run.method = "hybrid"): "refused" while the CLI refuses the method.
Soft runs use one thread. Every run has run.max_events = 10^6 (a legitimate run of this map needs
fewer than 40 000 events): an EDM run that stops there without reaching t = 20 is "stalled" - its
clock stopped in a burst of collisions at one instant that the collapse detection did not catch
(seen at e <= 0.2). Any other stop (escaped, a run past 300 s, a crash) is "failed".
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from matep_runs import check_soft, import_pyplot, run_repeated, write_csv  # noqa: E402

FIELDS = ["method", "setting", "e", "phi", "status", "outcome", "wall_seconds", "time_reached", "dt",
          "max_stable_dt", "max_overlap_relative", "message"]
OUTCOME = {"ok": "stable", "collapse": "collapse", "unstable": "blow-up", "refused": "refused",
           "max_events": "stalled"}
COLORS = {"stable": "#8fd18f", "collapse": "#f5b041", "stalled": "#b9770e", "blow-up": "#e74c3c",
          "refused": "#d5d8dc", "failed": "#a569bd"}
MAX_EVENTS = 1_000_000  # a legitimate run here needs < 40 000 events; see "stalled" in the module doc
# (restitutions, packing fractions, particles, end time)
FULL = ([0.1, 0.3, 0.5, 0.7, 0.9], [0.05, 0.1, 0.2, 0.3, 0.4, 0.5], 512, 20.0)
QUICK = ([0.3, 0.9], [0.1, 0.5], 64, 2.0)
RUN_TIMEOUT = 300       # seconds; a run beyond it is recorded as "timeout" (outcome "failed")
PANELS = [("edm", "exact"), ("tdm", "t_c/50"), ("tdm", "0.8 limit"), ("tdm", "2 limit"), ("hybrid", "default")]
TITLES = {("edm", "exact"): "EDM (hard spheres)", ("tdm", "t_c/50"): "TDM, dt = t_c/50 (default)",
          ("tdm", "0.8 limit"): "TDM, dt = 0.8 x stability limit", ("tdm", "2 limit"): "TDM, dt = 2 x limit",
          ("hybrid", "default"): "hybrid (default rule)"}

SCENE = """# Written by tools/stability_map.py: a freely cooling gas for the stability map.
[run]
dimension = 3
method = "edm"
end_time = {end}
seed = 7

[domain]
lower = [0.0, 0.0, 0.0]
upper = [10.0, 10.0, 10.0]
periodic = [true, true, true]

[material.grain]
density = 1.909859317102744   # unit mass for unit diameter
restitution = 0.9
contact = "linear"
stiffness = 9.0e4

[particles.gas]
material = "grain"
radius = 0.5
count = {count}
arrangement = "lattice"
temperature = 1.0

[output]
thermo_interval = 0
"""


def sweep(matep, work: Path, es, phis, count, end, log, repeat=1) -> list[dict]:
    scene = work / "cooling_gas.toml"
    scene.write_text(SCENE.format(end=repr(float(end)), count=count))
    rows = []
    for e in es:
        for phi in phis:
            L = (count * math.pi / 6.0 / phi) ** (1.0 / 3.0)
            base = {"material.grain.restitution": float(e), "domain.upper": [L, L, L], "run.max_events": MAX_EVENTS}
            soft = {**base, "run.method": "tdm", "run.threads": 1}
            chk = check_soft(matep, scene, soft)
            lim, tc = chk["max_stable_dt"], chk["contact_time"]
            runs = [("edm", "exact", {**base, "run.method": "edm"}, math.nan),
                    ("tdm", "t_c/50", soft, chk["dt"]),
                    ("tdm", "0.8 limit", {**soft, "run.dt": 0.8 * lim}, 0.8 * lim),
                    ("tdm", "2 limit", {**soft, "run.dt": 2.0 * lim}, 2.0 * lim),
                    ("hybrid", "default", {**base, "run.method": "hybrid", "run.threads": 1}, math.nan)]
            for method, setting, sets, dt in runs:
                folder = work / f"{method}_{setting.replace(' ', '_').replace('/', '_')}_e{e}_phi{phi}"
                r = run_repeated(matep, scene, sets, folder, repeat, timeout=RUN_TIMEOUT)
                s = r.summary or {}
                row = {"method": method, "setting": setting, "e": float(e), "phi": float(phi), "status": r.status,
                       "outcome": OUTCOME.get(r.status, "failed"), "wall_seconds": r.wall_seconds,
                       "time_reached": r.time_reached,
                       "dt": float(s["soft"]["dt"]) if "soft" in s else dt,
                       "max_stable_dt": lim if method != "edm" else math.nan,
                       "max_overlap_relative": float(s.get("max_overlap_relative", math.nan)) if s else math.nan,
                       "message": r.message}
                rows.append(row)
                stopped = row["outcome"] in ("collapse", "blow-up", "stalled")
                log(f"e {e:<4} phi {phi:<5} {method:6s} {setting:9s} {row['outcome']:8s} "
                    f"wall {row['wall_seconds']:.3g} s" + (f"  t = {row['time_reached']:.4g}" if stopped else ""))
                if method == "tdm" and setting == "t_c/50" and not math.isnan(tc):
                    row["message"] = row["message"] or f"t_c = {tc:.6g}, stability limit {lim:.6g}"
    return rows


def cell_text(r):
    o = r["outcome"]
    if o == "stable":
        return f"ok\n{r['wall_seconds']:.2g} s"
    if o in ("collapse", "blow-up", "stalled"):
        return f"{o}\nt = {r['time_reached']:.2g}"
    return o


def plot(rows, es, phis, png: Path, subtitle: str):
    plt = import_pyplot()
    from matplotlib.patches import Patch
    fig, axes = plt.subplots(1, len(PANELS), figsize=(3.3 * len(PANELS), 3.9), sharey=True)
    for ax, key in zip(axes, PANELS):
        cells = {(r["e"], r["phi"]): r for r in rows if (r["method"], r["setting"]) == key}
        for i, phi in enumerate(phis):
            for j, e in enumerate(es):
                r = cells.get((float(e), float(phi)))
                if r is None:
                    continue
                o = r["outcome"]
                ax.add_patch(plt.Rectangle((i - 0.5, j - 0.5), 1, 1, facecolor=COLORS[o], edgecolor="white",
                                           hatch="//" if o == "refused" else None, linewidth=1.5))
                ax.text(i, j, cell_text(r), ha="center", va="center", fontsize=6.5)
        ax.set_xlim(-0.5, len(phis) - 0.5)
        ax.set_ylim(-0.5, len(es) - 0.5)
        ax.set_xticks(range(len(phis)), [f"{p:g}" for p in phis], fontsize=7)
        ax.set_yticks(range(len(es)), [f"{e:g}" for e in es], fontsize=7)
        ax.set_xlabel("packing fraction phi", fontsize=8)
        title = TITLES[key]
        refused = [r for r in cells.values() if r["outcome"] == "refused"]
        if refused and len(refused) == len(cells):
            msg = refused[0]["message"]
            title += "\nrefused: " + ("method not in this matep" if "not available" in msg else
                                      "run.dt above the limit" if "stability limit" in msg else msg[:40])
        ax.set_title(title, fontsize=8)
    axes[0].set_ylabel("restitution e", fontsize=8)
    handles = [Patch(facecolor=c, label=o, hatch="//" if o == "refused" else None) for o, c in COLORS.items()
               if any(r["outcome"] == o for r in rows) or o in ("stable", "collapse", "blow-up")]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.suptitle("stability map: " + subtitle, fontsize=9)
    fig.tight_layout(rect=(0, 0.07, 1, 0.95))
    fig.savefig(png, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--matep", default="build/matep", help="the matep executable (default build/matep)")
    ap.add_argument("--out", default="charts", help="folder for stability_map.csv and .png (default charts/)")
    ap.add_argument("--quick", action="store_true", help="a 2 x 2 map of 64 particles (the test suite's mode)")
    ap.add_argument("--work", default=None, help="keep the runs' outputs in this folder (default: a temporary one)")
    ap.add_argument("--plot-only", action="store_true", help="redraw the PNG from the CSV in --out, running nothing")
    ap.add_argument("--repeat", type=int, default=1,
                    help="runs per cell, each with a memory layout of its own; the wall time is their median "
                         "(use 3 or more to compare versions: a single run varies by up to 40 %%)")
    args = ap.parse_args(argv)
    es, phis, count, end = QUICK if args.quick else FULL
    out = Path(args.out)
    csv_path, png_path = out / "stability_map.csv", out / "stability_map.png"
    subtitle = f"freely cooling gas, {count} spheres on a lattice, T0 = 1, linear k_n = 9e4, to t = {end:g}"
    if args.plot_only:
        with open(csv_path, newline="") as f:
            rows = [{k: (v if k in ("method", "setting", "status", "outcome", "message") else
                         float(v) if v else math.nan) for k, v in row.items()} for row in csv.DictReader(f)]
        plot(rows, es, phis, png_path, subtitle)
        print(f"wrote {png_path}")
        return
    if args.repeat < 1:
        ap.error(f"--repeat {args.repeat}: must be at least 1")
    matep = Path(args.matep).resolve()
    if not matep.exists():
        ap.error(f"--matep {args.matep}: no such file (build it: cmake --build build --target matep)")
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="matep_map_") as tmp:
        work = Path(args.work) if args.work else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        rows = sweep(matep, work, es, phis, count, end, lambda s: print(s, flush=True), args.repeat)
    write_csv(csv_path, FIELDS, rows)
    plot(rows, es, phis, png_path, subtitle)
    print(f"wrote {csv_path} and {png_path}")


if __name__ == "__main__":
    main()
