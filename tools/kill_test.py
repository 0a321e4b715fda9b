#!/usr/bin/env python3
"""Kills matep runs of each method at random moments and checks the output folder after every kill.

Each trial starts a run into a folder that already holds a previous run's complete set (a
different end_time, so the two sets can be told apart), sends SIGINT, SIGTERM or SIGKILL at a
random moment between the start and a little after the run's usual end, and then checks that the
folder holds exactly one complete set: the previous one, or the new one (finished, or
"interrupted" after SIGINT / SIGTERM) -- never a mix, never none. A set is complete when
summary.json parses, its time_reached is the last thermo.csv row's time, final_state.csv has one
row per grain and events.bin reads whole (matep log stats: every block checks).

The new runs keep checkpoints (output.checkpoint_interval: an eighth of the run). After every kill
that leaves one -- in the new set after SIGINT / SIGTERM, in DIR.running after SIGKILL -- the run
is continued with --resume, and the continued set must equal, byte for byte (thermo.csv,
final_state.csv, events.bin), the set of the same run left alone.

  tools/kill_test.py [--kills 300] [--matep build/matep] [--seed 1]

Prints the counts per method and signal; exit status 1 on the first folder that is not one
complete set.
"""
import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Scenes and the end times of the previous (A) and new (B) runs; B runs take ~0.1-0.5 s.
METHODS = {
    "edm": ("elastic_gas.toml", 0.05, 2.0),
    "tdm": ("soft_gas.toml", 0.002, 0.05),
    "hybrid": ("cooling_clusters.toml", 0.05, 1.5),
}
MATEP = None
SIGNALS = {"SIGINT": signal.SIGINT, "SIGTERM": signal.SIGTERM, "SIGKILL": signal.SIGKILL}


def complete_set(d):
    """The set's (end_time, status), or raises AssertionError saying what is wrong."""
    with open(os.path.join(d, "summary.json")) as f:
        s = json.load(f)
    with open(os.path.join(d, "thermo.csv")) as f:
        rows = f.read().splitlines()
    assert len(rows) >= 2, "thermo.csv has no rows"
    last = float(rows[-1].split(",")[0])
    assert last == s["time_reached"], f"thermo.csv ends at {last}, summary.json says {s['time_reached']}"
    with open(os.path.join(d, "final_state.csv")) as f:
        n = len(f.read().splitlines()) - 1
    assert n == s["grains_at_end"], f"final_state.csv has {n} rows, summary.json says {s['grains_at_end']} grains"
    ev = os.path.join(d, "events.bin")
    if os.path.exists(ev):
        r = subprocess.run([MATEP, "log", "stats", ev], capture_output=True, text=True)
        assert r.returncode == 0, "events.bin: " + r.stderr.strip()
    assert not os.path.exists(d + ".running") or os.path.isdir(d + ".running")
    return s["end_time"], s["status"]


def run(matep, scene, end, out, extra=()):
    return subprocess.Popen([matep, "run", scene, "--set", f"run.end_time={end}", "--set",
                             "output.snapshot_interval=0", "--quiet", "--out", out, *extra],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def checkpointing(end):
    return ("--set", f"output.checkpoint_interval={end / 8}")


def same_outputs(a, b):
    """Raises AssertionError naming the first output of folder b that differs from a's."""
    for f in ("thermo.csv", "final_state.csv", "events.bin"):
        pa, pb = os.path.join(a, f), os.path.join(b, f)
        assert os.path.exists(pa) == os.path.exists(pb), f"{f}: in one set only"
        if os.path.exists(pa):
            with open(pa, "rb") as x, open(pb, "rb") as y:
                assert x.read() == y.read(), f"{f} of the resumed run differs from the run left alone"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kills", type=int, default=300)
    ap.add_argument("--matep", default=os.path.join(ROOT, "build", "matep"))
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    global MATEP
    MATEP = a.matep
    rng = random.Random(a.seed)
    work = tempfile.mkdtemp(prefix="matep_kill_")
    counts = {}
    bad = 0
    try:
        durations = {}
        for m, (scene, end_a, end_b) in METHODS.items():
            out = os.path.join(work, m)
            path = os.path.join(ROOT, "cases", scene)
            assert run(a.matep, path, end_a, out).wait() == 0, f"{m}: the first run failed"
            t0 = time.perf_counter()
            assert run(a.matep, path, end_b, out, checkpointing(end_b)).wait() == 0, f"{m}: the timing run failed"
            durations[m] = time.perf_counter() - t0
            shutil.copytree(out, out + ".alone")  # the new run left alone: what a resumed one must give
            assert run(a.matep, path, end_a, out).wait() == 0
        for k in range(a.kills):
            m = list(METHODS)[k % len(METHODS)]
            sname = list(SIGNALS)[(k // len(METHODS)) % len(SIGNALS)]
            scene, end_a, end_b = METHODS[m]
            out = os.path.join(work, m)
            path = os.path.join(ROOT, "cases", scene)
            p = run(a.matep, path, end_b, out, checkpointing(end_b))
            time.sleep(rng.uniform(0.0, 1.2 * durations[m]))
            p.send_signal(SIGNALS[sname])
            code = p.wait()
            try:
                end, status = complete_set(out)
                if end == end_a:
                    outcome = "previous set"
                elif end == end_b:
                    outcome = "new set, " + ("interrupted" if status == "interrupted" else "complete")
                else:
                    raise AssertionError(f"a set with end_time {end}")
                # A checkpoint the kill left: it continues to the set of the run left alone.
                ck = None
                if outcome == "new set, interrupted":
                    ck = os.path.join(out, "checkpoint.bin")
                elif outcome == "previous set" and os.path.exists(os.path.join(out + ".running", "checkpoint.bin")):
                    ck = os.path.join(out + ".running", "checkpoint.bin")
                if ck:
                    r = run(a.matep, path, end_b, out, checkpointing(end_b) + ("--resume", ck)).wait()
                    assert r == 0, f"--resume {ck} exited with {r}"
                    same_outputs(out + ".alone", out)
                    outcome += " + resumed"
                    shutil.rmtree(out + ".killed", ignore_errors=True)
            except (AssertionError, OSError, ValueError, KeyError) as e:
                outcome = "NOT ONE COMPLETE SET" if "resum" not in str(e) else "RESUME DIFFERS"
                bad += 1
                print(f"kill {k}: {m} {sname} (exit {code}): {e}", file=sys.stderr)
            key = (m, sname, outcome)
            counts[key] = counts.get(key, 0) + 1
            # The next trial starts from the previous set again.
            if outcome != "previous set":
                run(a.matep, path, end_a, out).wait()
        print(f"{a.kills} kills (seed {a.seed}); run lengths: "
              + ", ".join(f"{m} {d:.2f} s" for m, d in durations.items()))
        print("method   signal   outcome                                  count")
        for (m, s, o), c in sorted(counts.items()):
            print(f"{m:8} {s:8} {o:40} {c}")
        print("every folder held one complete set" if bad == 0 else f"{bad} folders did not hold one complete set")
    finally:
        shutil.rmtree(work, ignore_errors=True)
        for m in METHODS:
            shutil.rmtree(os.path.join(work, m) + ".running", ignore_errors=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
