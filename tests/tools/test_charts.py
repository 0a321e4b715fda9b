#!/usr/bin/python3
"""ctest for the chart tools: runs tools/bench_accuracy.py (its four cases), tools/stability_map.py
in --quick mode, tools/collapse_chains.py on a few systems, or tools/cooling_seeds.py on two seeds,
from the command line, as a user would, and checks the CSV behind each chart:
one row per method and setting (cell), finite wall time and error wherever a run was made, and
rows marked "refused" only where the CLI really refuses (the hybrid method while it is not
available, a TDM step above the stability limit). Also checks that each PNG was written.

    /usr/bin/python3 tests/tools/test_charts.py accuracy|map|chains|cooling --matep build/matep --work DIR
"""
from __future__ import annotations

import argparse
import csv
import math
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tools"))
import bench_accuracy  # noqa: E402
import stability_map  # noqa: E402
from matep_runs import hybrid_refusal  # noqa: E402

failures: list[str] = []


def expect(cond, what):
    if not cond:
        failures.append(what)
    return cond


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def num(s):
    try:
        return float(s)
    except (TypeError, ValueError):
        return math.nan


def check_png(path):
    if expect(path.exists(), f"{path} missing"):
        data = path.read_bytes()
        expect(data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000, f"{path}: not a PNG chart ({len(data)} bytes)")


def run_tool(args):
    cmd = ["/usr/bin/python3", *map(str, args)]
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)
    sys.stdout.write(p.stdout)
    sys.stderr.write(p.stderr)
    if p.returncode != 0:
        raise SystemExit(f"FAIL: {' '.join(cmd)} exited with {p.returncode}")


def case_rows(name, case, rows):
    """(method, setting, row) for each method and setting the case runs (EDM, then TDM's steps, then
    the hybrid's settings), checking that the CSV has exactly one row for each."""
    expected = [("edm", "exact")] + [("tdm", f"t_c/{n}") for n in case["tdm"]] + \
               [("hybrid", f"k={k}") for k in case["hybrid"]]
    found = []
    for method, setting in expected:
        got = [r for r in rows if (r["method"], r["setting"]) == (method, setting)]
        if expect(len(got) == 1, f"{name}: {len(got)} rows for {method} {setting}, expected 1"):
            found.append((method, setting, got[0]))
    return found


def check_accuracy(matep, out, hybrid_refused):
    for name, make in (("ball", bench_accuracy.ball_case), ("gas", bench_accuracy.gas_case)):
        run_tool([REPO / "tools/bench_accuracy.py", name, "--matep", matep, "--out", out, "--quick"])
        case = make(True)
        rows = read_csv(out / f"accuracy_{name}.csv")
        expect(list(rows[0].keys())[:6] == ["case", "method", "setting", "wall_seconds", "error", "status"],
               f"{name}: CSV columns {list(rows[0].keys())}")
        for method, setting, r in case_rows(name, case, rows):
            wall, err = num(r["wall_seconds"]), num(r["error"])
            if r["status"] == "refused":
                expect(method == "hybrid" and hybrid_refused,
                       f"{name}: {method} {setting} refused although the CLI runs it: {r['message']}")
                continue
            expect(math.isfinite(wall) and wall > 0, f"{name}: {method} {setting}: wall_seconds {r['wall_seconds']}")
            expect(math.isfinite(err) and err >= 0, f"{name}: {method} {setting}: error {r['error']} ({r['status']})")
            # physics, loosely: every method is within a few per cent of the analytic answer
            if math.isfinite(err):
                expect(err < 0.05, f"{name}: {method} {setting}: error {err} above 5 %")
        if name == "ball":
            edm = next(r for r in rows if r["method"] == "edm")
            # The collapse watch stops the ball 1.7e-5 s before the Zeno time (4e-6 of it).
            expect(edm["status"] == "collapse" and num(edm["error"]) < 1e-5,
                   f"ball: EDM should collapse at the Zeno time: {edm['status']} error {edm['error']}")
        check_png(out / f"accuracy_{name}.png")


def check_pour(matep, out, hybrid_refused):
    """The pour's rows: EDM ends in collapse (it cannot settle a bed), the first TDM row is the
    reference (no error, the noise floor), every other run has a finite error against it."""
    run_tool([REPO / "tools/bench_accuracy.py", "pour", "--matep", matep, "--out", out, "--quick"])
    case = bench_accuracy.pour_case(True)
    rows = read_csv(out / "accuracy_pour.csv")
    ref = f"t_c/{case['tdm'][0]}"
    for method, setting, r in case_rows("pour", case, rows):
        err = num(r["error"])
        if method == "edm":
            expect(r["status"] == "collapse", f"pour: EDM should collapse in the settling bed: {r['status']}")
        elif r["status"] == "refused":
            expect(method == "hybrid" and hybrid_refused, f"pour: {method} {setting} refused: {r['message']}")
        elif (method, setting) == ("tdm", ref):
            expect(r["message"] == "the reference" and math.isfinite(num(r["noise"])) and num(r["answer"]) > 0,
                   f"pour: the reference row: {r}")
        else:
            # a 100-bead bed from 2 placements: the methods agree on its height within 15 %
            expect(r["status"] == "ok" and math.isfinite(err) and err < 0.15,
                   f"pour: {method} {setting}: error {r['error']} ({r['status']})")
    check_png(out / "accuracy_pour.png")


def check_map(matep, out, hybrid_refused):
    run_tool([REPO / "tools/stability_map.py", "--matep", matep, "--out", out, "--quick"])
    rows = read_csv(out / "stability_map.csv")
    es, phis = stability_map.QUICK[:2]
    seeds = stability_map.QUICK[4]
    for gravity in (0, 1):
        for e in es:
            for phi in phis:
                cell = [r for r in rows if int(num(r["gravity"])) == gravity and num(r["e"]) == e and num(r["phi"]) == phi]
                here = f"map: gravity {gravity} e={e} phi={phi}"
                by = {(r["method"], r["setting"]): r for r in cell}
                for method, setting in stability_map.PANELS:
                    where = f"{here} {method} {setting}"
                    got = [r for r in cell if (r["method"], r["setting"]) == (method, setting)]
                    if not expect(len(got) == 1, f"{where}: {len(got)} rows, expected 1"):
                        continue
                    r = got[0]
                    expect(r["outcome"] in stability_map.COLORS, f"{where}: outcome {r['outcome']}")
                    if r["outcome"] == "refused":
                        if method == "hybrid":
                            expect(hybrid_refused, f"{where}: refused although the CLI runs hybrid: {r['message']}")
                        else:
                            expect(setting == "2 limit" and "stability limit" in r["message"],
                                   f"{where}: refused: {r['message']}")
                        continue
                    expect(math.isfinite(num(r["wall_seconds"])) and math.isfinite(num(r["time_reached"])),
                           f"{where}: wall_seconds {r['wall_seconds']} time_reached {r['time_reached']}")
                    if method == "edm":
                        expect(r["outcome"] in ("stable", "collapse", "stalled"), f"{where}: {r['outcome']} {r['message']}")
                    if (method, setting) == ("tdm", "t_c/50"):
                        expect(r["outcome"] == "stable", f"{where}: the default step is not stable: {r['message']}")
                    if (method, setting) == ("tdm", "2 limit"):
                        expect(False, f"{where}: a step of twice the stability limit was not refused")
                    if setting in ("exact", "t_c/50", "default"):
                        expect(int(num(r["seeds"])) == seeds, f"{where}: {r['seeds']} seeds, expected {seeds}")
                    if r["outcome"] == "stable" and setting in ("exact", "t_c/50", "default"):
                        # the observable of every seed: a temperature or a height, positive, with its scatter
                        expect(num(r["observable"]) > 0 and math.isfinite(num(r["observable_se"])),
                               f"{where}: observable {r['observable']} +- {r['observable_se']}")
                # The reference: EDM where it reaches the end, else TDM at t_c/200 (a row of its own).
                edm = by.get(("edm", "exact"))
                ref = ("edm", "exact") if edm and edm["outcome"] == "stable" else stability_map.REFERENCE
                expect(ref in by and by[ref]["outcome"] == "stable", f"{here}: no stable reference {ref}")
                for r in cell:
                    expect(r["reference"] == f"{ref[0]} {ref[1]}", f"{here}: reference {r['reference']}, expected {ref}")
                if ref in by:
                    expect(num(by[ref]["deviation"]) == 0.0, f"{here}: the reference's deviation {by[ref]['deviation']}")
                hyb = by.get(("hybrid", "default"))
                if hyb and hyb["outcome"] == "stable" and ref in by:
                    # in a 108-grain gas to t = 2 every method agrees with the reference within 4 floors
                    expect(abs(num(hyb["deviation"])) < 4.0, f"{here}: hybrid deviation {hyb['deviation']}")
                    best = [num(by[("tdm", "t_c/50")]["wall_seconds"])]
                    if edm and edm["outcome"] == "stable":
                        best.append(num(edm["wall_seconds"]))
                    expect(abs(num(hyb["ratio"]) - num(hyb["wall_seconds"]) / min(best)) < 1e-3 * num(hyb["ratio"]),
                           f"{here}: ratio {hyb['ratio']} is not the hybrid's time over {min(best)}")
    check_png(out / "stability_map.png")
    check_png(out / "stability_map_ratio.png")
    # One half run again (--gravity off): the other half's rows are kept as they were.
    lines = (out / "stability_map.csv").read_text().splitlines()
    run_tool([REPO / "tools/stability_map.py", "--matep", matep, "--out", out, "--quick", "--gravity", "off"])
    again = (out / "stability_map.csv").read_text().splitlines()
    expect(again[0] == lines[0] and [x for x in again if x.startswith("1,")] == [x for x in lines if x.startswith("1,")]
           and sum(x.startswith("1,") for x in lines) > 0,
           "--gravity off: the gravity half's rows were not kept as they were")
    expect(sum(x.startswith("0,") for x in again) == sum(x.startswith("0,") for x in lines),
           "--gravity off: the free half's rows were not replaced one for one")
    # A few cells with more seeds (--cells, --seeds): their own CSV, the map's left as it was.
    before = (out / "stability_map.csv").read_bytes()
    run_tool([REPO / "tools/stability_map.py", "--matep", matep, "--out", out, "--quick", "--gravity", "off",
              "--cells", "0.3:0.1", "--seeds", "1"])
    cells = read_csv(out / "stability_map_cells.csv")
    expect({(num(r["e"]), num(r["phi"]), r["gravity"]) for r in cells} == {(0.3, 0.1, "0")},
           f"--cells 0.3:0.1: rows for {sorted({(r['e'], r['phi'], r['gravity']) for r in cells})}")
    expect(all(r["seeds"] == "1" for r in cells if r["method"] in ("edm", "hybrid")), "--seeds 1: seeds column")
    expect((out / "stability_map.csv").read_bytes() == before, "--cells rewrote the map's CSV")
    for bad, says in ((["--cells", "0.3"], "is not e:phi"), (["--cells", "1.5:0.1"], "needs 0 < e <= 1"),
                      (["--seeds", "0"], "at least 1")):
        p = subprocess.run(["/usr/bin/python3", str(REPO / "tools/stability_map.py"), "--out", str(out), *bad],
                           capture_output=True, text=True, cwd=REPO)
        expect(p.returncode == 2 and says in p.stderr, f"{bad}: exit {p.returncode}, {p.stderr.strip()[-120:]}")


def check_pressure(matep, out, hybrid_refused):
    """The elastic dense gas's rows: EDM's Z = P/(nT) near Carnahan-Starling's, every run with a
    finite Z, and the coarse soft step's systematic error standing clear of the noise (the point of
    the case: it ranks methods and steps)."""
    run_tool([REPO / "tools/bench_accuracy.py", "pressure", "--matep", matep, "--out", out, "--quick"])
    case = bench_accuracy.pressure_case(True)
    rows = read_csv(out / "accuracy_pressure.csv")
    got = {}
    for method, setting, r in case_rows("pressure", case, rows):
        if r["status"] == "refused":
            expect(method == "hybrid" and hybrid_refused, f"pressure: {method} {setting} refused: {r['message']}")
            continue
        expect(r["status"] == "ok" and num(r["answer"]) > 1.0 and math.isfinite(num(r["error_vs_edm"])),
               f"pressure: {method} {setting}: {r}")
        got[(method, setting)] = r
    edm = got.get(("edm", "exact"))
    if edm:  # 216 spheres over half a time unit, two starts: Z within 4 % of the equation of state
        expect(num(edm["error"]) < 0.04 and math.isfinite(num(edm["noise"])),
               f"pressure: EDM's Z {edm['answer']} against Carnahan-Starling {case['reference']}")
    coarse = got.get(("tdm", f"t_c/{case['tdm'][0]}"))
    if coarse:  # t_c/10: the step's error is several per cent, far above the quick run's noise
        expect(num(coarse["error_vs_edm"]) > 0.03, f"pressure: TDM at t_c/10 within 3 % of EDM: {coarse}")
    check_png(out / "accuracy_pressure.png")


def check_chains(matep, out, hybrid_refused):
    """tools/collapse_chains.py at r = 0.06 on the straight lines: a row per system, the reference
    converged (TDM at h/10 against h/40 within 2 %), EDM's verdict against McNamara and Young's
    threshold for three disks (r = 0.06 < 7 - 4 sqrt 3 = 0.0718: `collapse`), and the hybrid within
    the collapse tests' 25 % on the three- and four-disk lines (tests/analytic/test_collapse.cpp)."""
    if hybrid_refused:
        print("chains: skipped (the hybrid is refused by this matep)")
        return
    run_tool([REPO / "tools/collapse_chains.py", "--matep", matep, "--out", out, "--r", "0.06", "--angles", "0"])
    rows = read_csv(out / "collapse_chains.csv")
    expect(sorted(r["system"] for r in rows) == ["3a", "3b", "4a", "4b", "5a", "5b"], f"chains: systems {rows}")
    for r in rows:
        where = f"chains: {r['system']}"
        expect(num(r["ref_converged"]) < 0.02, f"{where}: TDM at h/10 and h/40 differ by {r['ref_converged']}")
        for k in ("edm_err", "hybrid_err", "tdm_err", "edm_err_initial", "hybrid_err_initial"):
            expect(math.isfinite(num(r[k])), f"{where}: {k} = {r[k]}")
        if r["system"].startswith("3"):
            expect(r["edm_status"] == "collapse", f"{where}: EDM {r['edm_status']} below the three-disk threshold")
            expect(num(r["edm_err"]) > 0.9, f"{where}: EDM's collapsed state within {r['edm_err']} of the soft one")
        if r["system"][0] in "34":
            expect(num(r["hybrid_err"]) <= 0.25 and int(r["hybrid_switches"]) > 0,
                   f"{where}: hybrid {r['hybrid_err']} off converged TDM ({r['hybrid_switches']} switches)")


def check_cooling(matep, out, hybrid_refused):
    """tools/cooling_seeds.py on the shipped seed and one more, two rounds: a row per seed, EDM's end
    (its collapse before t = 100, or t = 100), the hybrid reaching that end, having turned grains soft
    wherever EDM collapsed (the stability rule hands the collapsing cluster to the soft set instead of
    ending the run), the ratio the median of its rounds; bad input refused with the option named."""
    if hybrid_refused:
        print("cooling: skipped (the hybrid is refused by this matep)")
        return
    for bad, word in ((["--seeds", "x"], "--seeds"), (["--rounds", "0"], "--rounds")):
        p = subprocess.run(["/usr/bin/python3", REPO / "tools/cooling_seeds.py", "--matep", matep, "--out", out, *bad],
                           capture_output=True, text=True)
        expect(p.returncode == 2 and word in p.stderr and not (out / "cooling_seeds.csv").exists(),
               f"cooling: {bad} gave exit {p.returncode}: {p.stderr.strip()}")
    run_tool([REPO / "tools/cooling_seeds.py", "--matep", matep, "--out", out, "--seeds", "5,9", "--rounds", "2"])
    rows = read_csv(out / "cooling_seeds.csv")
    expect([r["seed"] for r in rows] == ["5", "9"], f"cooling: seeds {[r['seed'] for r in rows]}")
    for r in rows:
        where = f"cooling: seed {r['seed']}"
        end = num(r["edm_end"])
        expect(0.0 < end <= 100.0, f"{where}: EDM's end {end}")
        expect((r["edm_status"] == "collapse") == (end < 100.0), f"{where}: EDM {r['edm_status']} at t = {end}")
        expect(r["hybrid_status"] == "ok", f"{where}: the hybrid ended {r['hybrid_status']} before EDM's end")
        if r["edm_status"] == "collapse":
            expect(int(r["soft_particle_steps"]) > 0 and int(r["to_soft"]) > 0,
                   f"{where}: EDM collapsed, the hybrid turned nothing soft")
        lo, mid, hi = num(r["ratio_min"]), num(r["ratio"]), num(r["ratio_max"])
        expect(0.0 < lo <= mid <= hi and math.isfinite(hi), f"{where}: ratio {lo} {mid} {hi}")
    check_png(out / "cooling_seeds.png")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("which", choices=["accuracy", "map", "chains", "cooling"])
    ap.add_argument("--matep", required=True)
    ap.add_argument("--work", required=True)
    args = ap.parse_args()
    out = Path(args.work) / args.which
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    matep = Path(args.matep).resolve()
    hybrid_refused = hybrid_refusal(matep) is not None
    print(f"hybrid: {'refused by this matep' if hybrid_refused else 'available'}")
    if args.which == "accuracy":
        check_accuracy(matep, out, hybrid_refused)
        check_pour(matep, out, hybrid_refused)
        check_pressure(matep, out, hybrid_refused)
    elif args.which == "chains":
        check_chains(matep, out, hybrid_refused)
    elif args.which == "cooling":
        check_cooling(matep, out, hybrid_refused)
    else:
        check_map(matep, out, hybrid_refused)
    if failures:
        print("FAIL:\n  " + "\n  ".join(failures))
        return 1
    print(f"OK: {args.which} CSVs and charts checked")
    return 0


if __name__ == "__main__":
    sys.exit(main())
