#!/usr/bin/python3
"""Small chains of strongly inelastic disks: where the three methods' final states part.

The hybrid is asked to end a collapsing group where converged soft-sphere dynamics ends (issue of
the hybrid envelope; tests/analytic/test_collapse.cpp holds it to 25 % on straight lines of three
and four disks). This sweep widens that set: the same lines bent (every other disk lifted by
sin(angle) diameters, so that successive contact normals differ by about twice the angle) and two
lines of five disks, over a range of restitution coefficients, and reports for each system the final
relative velocities (x components, neighbours in the line) of pure EDM, the hybrid and TDM at its
default step against TDM at a tenth of it (the reference; a fortieth of it is run too, to show the
reference converged).

The disks: diameter 1, mass 1, linear contact k_n = 1e6 (t_c = 1.1e-3 at e = 0.03), constant
restitution r, no friction, no gravity, a periodic box 40 wide (they never reach its edges). Two
errors are written: relative to the reference's final relative velocities (the test's measure),
and relative to the initial ones (the same difference on the scale of the impacts: a final state
in which the disks end nearly at rest against each other has tiny relative velocities, and a
small absolute difference is a large relative one there).

    /usr/bin/python3 tools/collapse_chains.py --matep build/matep --out charts/

writes collapse_chains.csv and prints a summary per restitution (about a minute).
"""
from __future__ import annotations

import argparse
import csv
import math
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from matep_runs import run_matep, write_csv  # noqa: E402

# The lines of tests/analytic/test_collapse.cpp (three and four disks) and two of five: centres on
# the x axis and velocities along it.
SYSTEMS = {
    "3a": ([0, 2, 4.5], [1, 0, -1]),
    "3b": ([0, 2.3, 4.1], [1, 0.2, -1]),
    "4a": ([0, 2, 4.5, 6.2], [1, 0, 0, -1]),
    "4b": ([0, 1.5, 3.2, 5], [1, 0.3, -0.2, -1]),
    "5a": ([0, 1.6, 3.0, 4.3, 6.0], [1, 0.2, 0, -0.1, -1]),
    "5b": ([0, 1.2, 2.5, 3.7, 5.5], [1, 0.5, 0, -0.3, -1]),
}

SCENE = """[run]
dimension = 2
method = "edm"
end_time = {end}

[domain]
lower = [-20.0, -20.0]
upper = [20.0, 20.0]
periodic = [true, true]

[material.grain]
density = {density}
restitution = {r}
contact = "linear"
stiffness = 1.0e6

[particles.line]
material = "grain"
file = "{state}"

[output]
thermo_interval = {end}
"""


def write_scene(work: Path, name: str, r: float, deg: float, end: float) -> Path:
    xs, vs = SYSTEMS[name]
    dy = math.sin(math.radians(deg))
    tag = f"{name}_r{r}_d{deg}"
    state = work / f"line_{tag}.csv"
    with open(state, "w") as f:
        f.write("x,y,vx,vy,radius\n")
        for k, (x, v) in enumerate(zip(xs, vs)):
            f.write(f"{x!r},{dy if k % 2 else 0.0!r},{float(v)!r},0.0,0.5\n")
    scene = work / f"line_{tag}.toml"
    # Mass 1: density 1 / (pi 0.5^2) in 2D.
    scene.write_text(SCENE.format(end=repr(end), density=repr(1.0 / (math.pi * 0.25)), r=repr(r), state=state.name))
    return scene


def relative_velocities(run) -> list[float] | None:
    p = Path(run.out_dir) / "final_state.csv"
    if run.summary is None or not p.exists():
        return None
    with open(p, newline="") as f:
        vx = {int(row["id"]): float(row["vx"]) for row in csv.DictReader(f)}
    v = [vx[k] for k in sorted(vx)]
    return [v[k + 1] - v[k] for k in range(len(v) - 1)]


def dist(a, b) -> float:
    return math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b)))


def norm(a) -> float:
    return math.sqrt(sum(x * x for x in a))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--matep", default="build/matep")
    ap.add_argument("--out", default="charts/")
    ap.add_argument("--r", default="0.03,0.06,0.09,0.15,0.2,0.3,0.4")
    ap.add_argument("--angles", default="0,2,4,7,12")
    ap.add_argument("--keep", action="store_true", help="keep the runs' folders (their path is printed)")
    args = ap.parse_args(argv)
    matep = Path(args.matep).resolve()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="collapse_chains_"))
    try:
        return sweep(matep, out, work, args)
    finally:
        if args.keep:
            print(f"runs kept in {work}")
        else:
            shutil.rmtree(work, ignore_errors=True)


def sweep(matep: Path, out: Path, work: Path, args) -> int:
    rs = [float(x) for x in args.r.split(",")]
    angles = [float(x) for x in args.angles.split(",")]
    rows = []
    for r in rs:
        for name, (xs, vs) in SYSTEMS.items():
            v0 = [vs[k + 1] - vs[k] for k in range(len(vs) - 1)]
            end = 8.0
            for deg in angles:
                scene = write_scene(work, name, r, deg, end)
                base = work / f"o_{name}_{r}_{deg}"
                hyb = run_matep(matep, scene, {"run.method": "hybrid", "run.threads": 1}, f"{base}_h", timeout=600)
                if hyb.summary is None:
                    print(f"{name} r={r} {deg} deg: the hybrid failed: {hyb.message}", file=sys.stderr)
                    return 1
                h = float(hyb.summary["soft"]["default_dt"])
                res = {"hybrid": hyb}
                res["edm"] = run_matep(matep, scene, {"run.method": "edm"}, f"{base}_e", timeout=600)
                for label, f in (("tdm", 1.0), ("tdm10", 0.1), ("tdm40", 0.025)):
                    res[label] = run_matep(matep, scene, {"run.method": "tdm", "run.threads": 1, "run.dt": h * f},
                                           f"{base}_{label}", timeout=600)
                dv = {k: relative_velocities(v) for k, v in res.items()}
                ref = dv["tdm10"]
                if ref is None or dv["tdm40"] is None:
                    print(f"{name} r={r} {deg} deg: TDM failed", file=sys.stderr)
                    return 1
                row = {"system": name, "restitution": r, "bend_deg": deg, "ref_norm": norm(ref),
                       "ref_converged": dist(ref, dv["tdm40"]) / max(norm(dv["tdm40"]), 1e-300),
                       "edm_status": res["edm"].status, "hybrid_switches": hyb.summary["hybrid"]["to_soft"]}
                for k in ("edm", "hybrid", "tdm"):
                    d = dv[k]
                    row[f"{k}_err"] = dist(d, ref) / norm(ref) if d is not None else math.nan
                    row[f"{k}_err_initial"] = dist(d, ref) / norm(v0) if d is not None else math.nan
                rows.append(row)
    fields = list(rows[0].keys())
    write_csv(out / "collapse_chains.csv", fields, rows)
    print(f"{'r':>5} {'systems':>7} {'EDM>25%':>8} {'hybrid>25%':>10} {'worst hybrid (ref / initial)':>30} "
          f"{'worst EDM (ref / initial)':>27} {'ref conv.':>9}")
    for r in rs:
        sel = [x for x in rows if x["restitution"] == r]
        he = max(sel, key=lambda x: x["hybrid_err"])
        ee = max(sel, key=lambda x: x["edm_err"])
        print(f"{r:5.2f} {len(sel):7d} {sum(x['edm_err'] > 0.25 for x in sel):8d} "
              f"{sum(x['hybrid_err'] > 0.25 for x in sel):10d} "
              f"{100 * he['hybrid_err']:9.0f} % / {100 * he['hybrid_err_initial']:4.1f} % ({he['system']}, {he['bend_deg']:g} deg) "
              f"{100 * ee['edm_err']:8.0f} % / {100 * ee['edm_err_initial']:4.1f} % ({ee['system']}, {ee['bend_deg']:g}) "
              f"{100 * max(x['ref_converged'] for x in sel):8.2f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
