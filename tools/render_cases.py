#!/usr/bin/env python3
"""One picture per shipped case: runs every scene in cases/ and draws its last snapshot with
tools/render.py (ParaView), coloured by speed.

    tools/render_cases.py [--quick] [--out DIR] [--matep build/matep] [--cases NAME ...]

--quick (the test suite's mode) runs each case only a short way past its start (run.end_time =
start + a few contact times or events), enough to draw its grains and walls; without it each case
runs to --fraction of its own end_time (default 1: the whole case; the README's gallery). Writes
DIR/NAME.png (default charts/cases/) and prints one line per case; exits 0 only if every case gave a
picture with grains on it. Without ParaView it says so and exits with status 3 (what the test
suite's tools.render, CMakeLists.txt, reads as "skipped").
"""
from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))
from render import virtual_display  # noqa: E402


def quick_end(scene: dict) -> float:
    """A short stretch past the start: 2 ms of a soft-sphere run (hundreds of steps), 1 % of the
    end time otherwise (at most 5 ms), at least one snapshot interval's worth of nothing."""
    run = scene.get("run", {})
    start = float(run.get("start_time", 0.0))
    end = float(run.get("end_time", 1.0))
    span = min(0.002 if run.get("method", "edm") != "edm" else 0.005, end - start)
    return start + span


def painted(png: Path) -> float:
    """The fraction of the picture's pixels that are not the white background."""
    from PIL import Image
    img = Image.open(png).convert("RGB")
    px = img.getdata()
    return sum(1 for p in px if min(p) < 235) / max(1, len(px))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--fraction", type=float, default=1.0)
    ap.add_argument("--out", type=Path, default=ROOT / "charts" / "cases")
    ap.add_argument("--matep", default=str(ROOT / "build" / "matep"))
    ap.add_argument("--cases", nargs="*")
    ap.add_argument("--size", type=int, nargs=2, default=[640, 480])
    a = ap.parse_args()
    if not shutil.which("pvbatch"):
        print("render_cases.py: ParaView is not installed (no pvbatch); skipped", file=sys.stderr)
        return 3
    a.out.mkdir(parents=True, exist_ok=True)
    names = a.cases or sorted(p.stem for p in (ROOT / "cases").glob("*.toml"))
    failed = 0
    # One private virtual display for every picture when there is none (render.py starts its own
    # again should drawing through this one fail).
    with tempfile.TemporaryDirectory() as tmp, \
            (virtual_display() if not os.environ.get("DISPLAY") else contextlib.nullcontext()) as display:
        env = dict(os.environ, DISPLAY=display) if display else None
        for name in names:
            path = ROOT / "cases" / f"{name}.toml"
            with open(path, "rb") as f:
                scene = tomllib.load(f)
            run = scene.get("run", {})
            start, end = float(run.get("start_time", 0.0)), float(run.get("end_time", 1.0))
            stop = quick_end(scene) if a.quick else start + a.fraction * (end - start)
            out = Path(tmp) / name
            t0 = time.monotonic()
            r = subprocess.run([a.matep, "run", str(path), "--quiet", "--out", str(out), "--set", f"run.end_time={stop!r}",
                                "--set", f"output.snapshot_interval={stop - start!r}", "--set", "output.format=vtk"],
                               capture_output=True, text=True)
            if not (out / "snapshots.pvd").exists():  # a run that stopped early still publishes its outputs
                print(f"{name}: the run wrote no snapshots (status {r.returncode}): {r.stdout[-300:]}{r.stderr[-300:]}")
                failed += 1
                continue
            png = a.out / f"{name}.png"
            v = subprocess.run([sys.executable, str(ROOT / "tools" / "render.py"), str(out), "--png", str(png),
                                "--size", str(a.size[0]), str(a.size[1])], capture_output=True, text=True, env=env)
            if v.returncode != 0 or not png.exists():
                print(f"{name}: render.py failed (status {v.returncode}): {v.stderr[:800]}")
                failed += 1
                continue
            share = painted(png)
            ok = share > 0.005
            failed += not ok
            print(f"{name}: {png} ({share * 100:.1f} % of the picture drawn, t = {stop:.4g} s, "
                  f"{time.monotonic() - t0:.1f} s){'' if ok else ' -- EMPTY'}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
