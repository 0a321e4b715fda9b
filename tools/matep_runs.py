"""Shared helpers of the chart scripts (tools/bench_accuracy.py, tools/stability_map.py).

They drive the matep CLI only through its documented interface: `matep run SCENE --set KEY=VALUE
--out DIR --quiet` (exit 0 ok, 2 refused input, 3 stopped early with summary.json's status) and
`matep check` (the time step, stability limit and contact time of a soft-sphere scene).
Run with /usr/bin/python3 (Debian's python3-matplotlib); nothing here needs more than the standard
library, matplotlib is imported only where a chart is drawn.
"""
from __future__ import annotations

import csv
import json
import math
import os
import re
import shutil
import statistics
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CASES = REPO / "cases"


def toml_value(v) -> str:
    """A --set value: numbers in round-trip form, vectors as TOML arrays, words as they are."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ",".join(toml_value(x) for x in v) + "]"
    return str(v)


def set_args(sets: dict) -> list[str]:
    args = []
    for k, v in sets.items():
        args += ["--set", f"{k}={toml_value(v)}"]
    return args


class Run:
    """One `matep run`: status is summary.json's status ("ok", "collapse", "unstable", "escaped",
    "max_events"), "refused" (exit 2: the CLI refused the scene or a key, nothing written),
    "timeout", or "failed" (any other exit)."""

    def __init__(self, rc, status, message, summary, out_dir):
        self.rc, self.status, self.message, self.summary, self.out_dir = rc, status, message, summary, out_dir
        self.walls = []  # run_interleaved: each round's wall time, in round order

    @property
    def wall_seconds(self) -> float:
        return float(self.summary["wall_seconds"]) if self.summary else math.nan

    @property
    def time_reached(self) -> float:
        return float(self.summary["time_reached"]) if self.summary else math.nan

    def thermo(self) -> list[dict]:
        p = Path(self.out_dir) / "thermo.csv"
        if not p.exists():
            return []
        with open(p, newline="") as f:
            return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def run_matep(matep, scene, sets: dict, out_dir, timeout=None, layout=None) -> Run:
    """layout: None, or an integer k: the run gets a memory layout of its own, the same at every
    call with the same k (address randomisation off through util-linux's setarch where it works,
    and k * 300 bytes more environment, which moves the stack). On the development machine the
    same run's wall time varied by up to 40 % with where its stack landed (charts/README.md)."""
    out_dir = Path(out_dir)
    shutil.rmtree(out_dir, ignore_errors=True)
    cmd = [str(matep), "run", str(scene), *set_args(sets), "--out", str(out_dir), "--quiet"]
    env = None
    if layout is not None:
        env = dict(os.environ, MATEP_LAYOUT_PAD="x" * (300 * int(layout)))
        if _setarch_works():
            cmd = ["setarch", "-R", *cmd]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return Run(None, "timeout", f"no result within {timeout} s", None, out_dir)
    err = " ".join(p.stderr.strip().splitlines()[-1:]) if p.stderr.strip() else ""
    err = re.sub(r"^matep: error: ", "", err).replace(f"{scene}: ", "").replace(f"({scene})", "").replace("  ", " ")
    summary_path = out_dir / "summary.json"
    if p.returncode == 2:
        return Run(2, "refused", err, None, out_dir)
    if p.returncode in (0, 3) and summary_path.exists():
        with open(summary_path) as f:
            s = json.load(f)
        return Run(p.returncode, s.get("status", "failed"), s.get("message", "") or err, s, out_dir)
    return Run(p.returncode, "failed", err or f"exit status {p.returncode}", None, out_dir)


_SETARCH = None


def _setarch_works() -> bool:
    global _SETARCH
    if _SETARCH is None:
        exe = shutil.which("setarch")
        _SETARCH = bool(exe) and subprocess.run([exe, "-R", "true"], capture_output=True).returncode == 0
    return _SETARCH


def run_repeated(matep, scene, sets, out_dir, repeat=1, timeout=None) -> Run:
    """Runs `repeat` times (same deterministic scene) and keeps the last run with the median of
    the wall times: the machines are shared and noisy. With repeat > 1 each run has a memory
    layout of its own (run_matep's `layout`), the same ones for every scene and version."""
    return run_interleaved(matep, [(scene, sets, out_dir)], repeat, timeout)[0]


def run_interleaved(matep, jobs, repeat=1, timeout=None) -> list[Run]:
    """run_repeated for several runs (jobs: (scene, sets, out_dir) each) whose times are compared:
    round k runs every job once, in the list's order, before round k + 1, so that a drift of the
    host's speed over the rounds enters every job alike instead of the jobs run last (a job run
    `repeat` times in a row, then the next, put a 6 ms cell's EDM and hybrid runs 20 % apart on a
    drifting host where alternated rounds agree; charts/README.md). A job whose first run gave no
    summary is not repeated. Each job keeps its last run, with the median of its wall times."""
    lay = (lambda k: k) if repeat > 1 else (lambda k: None)
    runs = [[] for _ in jobs]
    for k in range(repeat):
        for j, (scene, sets, out_dir) in enumerate(jobs):
            if k == 0 or runs[j][0].summary is not None:
                runs[j].append(run_matep(matep, scene, sets, out_dir, timeout, lay(k)))
    out = []
    for rs in runs:
        r = rs[-1]
        r.walls = [x.wall_seconds for x in rs]
        if r.summary is not None and len(rs) > 1:
            r.summary = dict(r.summary)
            r.summary["wall_seconds"] = statistics.median(x.wall_seconds for x in rs)
        out.append(r)
    return out


def check_soft(matep, scene, sets: dict) -> dict:
    """Parses `matep check` for a soft-sphere scene: the step it would use, the stability limit
    of velocity Verlet for the stiffest contact and the contact time (README, matep check)."""
    cmd = [str(matep), "check", str(scene), *set_args(sets)]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"matep check failed: {p.stderr.strip()}")
    out = p.stdout
    num = r"([0-9.]+(?:e[+-]?[0-9]+)?|inf)"
    m_dt = re.search(r"time step\s+" + num + r".*?stability limit " + num, out)
    m_tc = re.search(r"contact time " + num, out)
    if not (m_dt and m_tc):
        raise RuntimeError(f"cannot read the time step / contact time from `matep check`:\n{out}")
    return {"dt": float(m_dt.group(1)), "max_stable_dt": float(m_dt.group(2)), "contact_time": float(m_tc.group(1))}


def hybrid_refusal(matep) -> str | None:
    """None when `matep run` accepts run.method = "hybrid", else the CLI's message. Probed on a
    one-particle scene written to a scratch folder (a refused scene writes nothing)."""
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "probe.toml"
        scene.write_text(
            '[run]\ndimension = 3\nmethod = "hybrid"\nend_time = 0.001\n'
            '[domain]\nlower = [0.0, 0.0, 0.0]\nupper = [4.0, 4.0, 4.0]\nperiodic = [true, true, true]\n'
            '[material.m]\ndensity = 1.0\nrestitution = 0.9\ncontact = "linear"\nstiffness = 1.0e4\n'
            '[particles.p]\nmaterial = "m"\nradius = 0.5\ncount = 1\nvelocity = [0.1, 0.0, 0.0]\n')
        r = run_matep(matep, scene, {}, Path(tmp) / "out", timeout=60)
        return r.message if r.status == "refused" else None


def write_csv(path, fields, rows):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore", lineterminator="\n")
        w.writeheader()
        for row in rows:
            w.writerow({k: fmt(row.get(k, "")) for k in fields})


def fmt(v):
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.6g}"
    return v


def import_pyplot():
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        return plt
    except ImportError as exc:  # pragma: no cover - depends on the machine
        raise SystemExit(f"matplotlib is missing ({exc}): run tools/install-deps.sh (Debian's python3-matplotlib) "
                         f"and use /usr/bin/python3")
