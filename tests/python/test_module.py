"""The Python module's suite (run by the test command through ctest): scenes built as dicts in
Python, run with each method, every output read back (the XYZ and LAMMPS snapshots also by ASE)
and the physics it shows checked against closed forms: a ball dropped on a floor (collision times, restitution, the Zeno time), a ball
resting on a linear spring (overlap m g / k, its contact force m g), grains falling out of an open face (the free-fall
time), a hybrid ball coming to rest past the Zeno time; bad scenes raise SceneError with the
CLI's message; Ctrl-C stops a run from Python with its outputs written.

    PYTHONPATH=build/python /usr/bin/python3 tests/python/test_module.py [--work DIR]
"""
from __future__ import annotations

import argparse
import math
import os
import signal
import subprocess
import sys
import time
import unittest
from pathlib import Path

import numpy as np

import matep

try:  # Debian's python3-ase, installed by tools/install-deps.sh
    import ase.io as ase_io
except ImportError:
    ase_io = None

G = 9.81
WORK = Path("/tmp/matep_python_test")


def ball_scene(method: str, end_time: float, e: float = 0.8, z0: float = 1.05, R: float = 0.05) -> dict:
    """A steel ball at rest at height z0 over a floor, in a periodic column (x, y)."""
    csv = WORK / f"ball_{method}.csv"
    csv.write_text(f"x,y,z,vx,vy,vz,radius\n0.0,0.0,{z0!r},0.0,0.0,0.0,{R!r}\n")
    return {
        "run": {"dimension": 3, "method": method, "end_time": end_time, "gravity": [0.0, 0.0, -G]},
        "domain": {"lower": [-0.5, -0.5, 0.0], "upper": [0.5, 0.5, 2.0], "periodic": [True, True, False]},
        "material": {"steel": {"density": 7800.0, "restitution": e}},
        "particles": {"ball": {"material": "steel", "file": str(csv)}},
        "wall": {"floor": {"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "material": "steel"}},
        "output": {"thermo_interval": 0.01},
    }


def drop_times(h: float, e: float, n: int) -> list[float]:
    """Impact times of a ball dropped from rest, its centre h above the contact height:
    t1 = sqrt(2 h / g), then each flight 2 e^k v1 / g."""
    v = math.sqrt(2 * G * h)
    t = [v / G]
    for k in range(1, n):
        t.append(t[-1] + 2 * (e ** k) * v / G)
    return t


class Edm(unittest.TestCase):
    def test_bouncing_ball_every_output_against_the_closed_form(self):
        e, z0, R = 0.8, 1.05, 0.05
        sc = ball_scene("edm", 3.0, e, z0, R)
        sc["output"].update({"events": True, "snapshot_interval": 0.25, "format": ["vtk", "xyz", "lammps"],
                             "contacts": True})
        info = matep.check(sc)
        self.assertEqual(info["method"], "edm")
        self.assertIn("particles    1", info["description"])
        run = matep.run(sc, out=WORK / "edm_ball")
        self.assertEqual(run.outcome["status"], "ok")
        # events.bin: the wall impacts at the closed-form times, each reversing vz times e.
        header, rec = run.events()
        self.assertEqual(header["particles"], 1)
        self.assertEqual((header["version"], header["groups"], header["materials"]), (4, ["ball"], ["steel"]))
        self.assertEqual((int(header["group"][0]), int(header["material"][0])), (0, 0))
        t_exact = drop_times(z0 - R, e, len(rec))
        self.assertEqual(len(rec), 6)  # six impacts by t = 3 s (the seventh at 3.12 s)
        np.testing.assert_allclose(rec["time"], t_exact, rtol=1e-9)
        np.testing.assert_allclose(rec["vi_after"][:, 2], -e * rec["vi_before"][:, 2], rtol=1e-12)
        self.assertEqual(run.summary["events"]["wall_collisions"], len(rec))
        # thermo.csv: energy lost at each impact is (1 - e^2) of the kinetic energy there.
        th = run.thermo()
        m = 7800.0 * 4.0 / 3.0 * math.pi * R ** 3
        total = th["kinetic_energy"] + th["potential_energy"]
        n_before = np.searchsorted(t_exact, th["time"], side="right")
        # The mechanical energy above the resting height falls by e^2 at every impact.
        np.testing.assert_allclose(total - m * G * R, m * G * (z0 - R) * e ** (2 * n_before), rtol=1e-9)
        # Snapshots: binary VTK, extended XYZ and the LAMMPS dump agree with the trajectory.
        snaps = run.snapshots()
        self.assertEqual([round(t, 12) for t, _ in snaps], [0.25 * k for k in range(13)])
        for k, (t, path) in enumerate(snaps):
            v = matep.read_vtp(path)
            z = v["position"][0, 2]
            self.assertAlmostEqual(z, ball_height(t, z0, R, e), delta=1e-9)
            self.assertEqual(v["group_names"], ["ball"])
            self.assertEqual(int(v["mode"][0]), 0)
            x = matep.read_xyz(path.with_suffix(".xyz"))
            self.assertEqual(x["pos"][0, 2], z)
            self.assertEqual(x["radius"][0], R)
            self.assertEqual(x["group"][0], "ball")
            if ase_io:  # a reader other than matep's own
                a = ase_io.read(path.with_suffix(".xyz"), format="extxyz")
                np.testing.assert_array_equal(a.positions, v["position"])
                np.testing.assert_array_equal(a.arrays["radius"], v["radius"])
                self.assertEqual(list(a.arrays["group"]), ["ball"])
            d = matep.read_lammps_dump(path.with_suffix(".lammpstrj"))
            self.assertEqual(d["z"][0], z)
            self.assertEqual(d["timestep"], k)
            self.assertAlmostEqual(d["time"], t, places=12)
        # Contacts: each interval's floor impulse (mean force times 0.25 s) changes the momentum by
        # m (v_b - v_a) + m g dt; the impacts counted are those of the closed form.
        for k in range(1, len(snaps)):
            c = run.contacts(k)
            ta, tb = snaps[k - 1][0], snaps[k][0]
            dp = m * (ball_velocity(tb, z0, R, e) - ball_velocity(ta, z0, R, e)) + m * G * (tb - ta)
            impacts = sum(1 for t in t_exact if ta < t <= tb)
            if impacts == 0:
                self.assertEqual(len(c["i"]), 0)
                continue
            self.assertEqual((list(c["kind"]), list(c["wall"]), list(c["collisions"])), ([0], [0], [impacts]))
            self.assertAlmostEqual(c["fn_z"][0] * (tb - ta), dp, delta=1e-9 * abs(dp))
        # final_state.csv and the checkpoint written at the end.
        fs = run.final_state()
        self.assertAlmostEqual(fs["z"][0], ball_height(3.0, z0, R, e), delta=1e-9)
        self.assertEqual(fs["group"][0], "ball")
        self.assertEqual(fs["material"][0], "steel")
        ck = run.checkpoint()
        self.assertEqual((ck["method"], ck["dimension"], ck["time"]), ("edm", 3, 3.0))
        self.assertIn("[particles.ball]", ck["scene"])
        # pandas, where installed.
        try:
            frame = matep.read_frame(run.dir / "thermo.csv")
            self.assertEqual(len(frame), len(th["time"]))
        except ImportError:
            pass

    @unittest.skipIf(ase_io is None, "python3-ase is not installed")
    def test_ase_reads_the_xyz_and_lammps_snapshots_of_a_mixture(self):
        """Two groups of two materials: ASE (not matep) reads the same positions, radii and groups."""
        sc = matep.load(Path(os.environ.get("MATEP_SOURCE_DIR", ".")) / "cases/elastic_gas.toml")
        sc["material"]["soft"] = dict(sc["material"]["hard"])
        sc["particles"]["gas"].update(count=300, arrangement="random")
        sc["particles"]["small"] = dict(sc["particles"]["gas"], material="soft", radius=0.3, count=200)
        sc["run"]["end_time"] = 0.05
        sc["output"].update({"events": False, "snapshot_interval": 0.05, "format": ["vtk", "xyz", "lammps"]})
        run = matep.run(sc, out=WORK / "ase_mixture")
        fs = run.final_state()
        _, last = run.snapshots()[-1]
        v = matep.read_vtp(last)
        a = ase_io.read(last.with_suffix(".xyz"), format="extxyz")
        np.testing.assert_array_equal(a.positions, v["position"])
        np.testing.assert_array_equal(a.arrays["radius"], fs["radius"])
        np.testing.assert_array_equal(a.arrays["group"], fs["group"])
        np.testing.assert_array_equal(a.arrays["material"], fs["material"])
        b = ase_io.read(last.with_suffix(".lammpstrj"), format="lammps-dump-text")
        np.testing.assert_array_equal(b.positions, v["position"])
        names = v["group_names"]
        np.testing.assert_array_equal([names[t - 1] for t in b.numbers], fs["group"])  # type = group + 1
        self.assertEqual(sorted(set(fs["group"])), ["gas", "small"])

    def test_pure_edm_collapses_at_the_zeno_time(self):
        e, z0, R = 0.8, 1.05, 0.05
        run = matep.run(ball_scene("edm", 6.0, e, z0, R), out=WORK / "edm_zeno")
        zeno = math.sqrt(2 * (z0 - R) / G) * (1 + e) / (1 - e)  # 4.064 s
        self.assertEqual(run.outcome["status"], "collapse")
        self.assertAlmostEqual(run.summary["time_reached"], zeno, delta=2e-3)

    def test_grains_leave_through_an_open_face_at_the_free_fall_time(self):
        sc = ball_scene("edm", 1.0)
        del sc["wall"]
        sc["outlet"] = {"bottom": {"type": "face", "face": "z-"}}
        run = matep.run(sc, out=WORK / "edm_outlet")
        out = run.outflow()
        self.assertEqual(len(out["time"]), 1)
        self.assertAlmostEqual(out["time"][0], math.sqrt(2 * 1.05 / G), delta=1e-9)
        self.assertAlmostEqual(out["vz"][0], -math.sqrt(2 * G * 1.05), delta=1e-8)
        self.assertEqual(run.summary["grains_at_end"], 0)

    def test_a_bad_scene_raises_scene_error_with_the_cli_message(self):
        sc = ball_scene("edm", 1.0)
        sc["run"]["end_tme"] = 2.0
        with self.assertRaises(matep.SceneError) as c:
            matep.check(sc)
        self.assertIn("run.end_tme: unknown key", str(c.exception))
        self.assertIsInstance(c.exception, ValueError)
        with self.assertRaises(matep.FileError):
            matep.read_checkpoint(WORK / "no_such_checkpoint.bin")


def ball_height(t: float, z0: float, R: float, e: float) -> float:
    """The ball's centre height at time t (closed form, before the Zeno time)."""
    h = z0 - R
    v = math.sqrt(2 * G * h)
    tk, k = v / G, 0
    if t <= tk:
        return z0 - 0.5 * G * t * t
    while True:
        vk = (e ** (k + 1)) * v
        flight = 2 * vk / G
        if t <= tk + flight:
            s = t - tk
            return R + vk * s - 0.5 * G * s * s
        tk += flight
        k += 1


def ball_velocity(t: float, z0: float, R: float, e: float) -> float:
    """The ball's vertical velocity at time t (closed form, before the Zeno time)."""
    v = math.sqrt(2 * G * (z0 - R))
    tk, k = v / G, 0
    if t <= tk:
        return -G * t
    while True:
        vk = (e ** (k + 1)) * v
        if t <= tk + 2 * vk / G:
            return vk - G * (t - tk)
        tk += 2 * vk / G
        k += 1


class Tdm(unittest.TestCase):
    def test_a_ball_rests_on_a_linear_spring_at_overlap_mg_over_k(self):
        k_n, R = 2.0e5, 0.05
        sc = ball_scene("tdm", 2.0, e=0.3, z0=0.1, R=R)
        sc["material"]["steel"].update({"contact": "linear", "stiffness": k_n})
        sc["output"].update({"snapshot_interval": 1.0, "contacts": True})
        run = matep.run(sc, out=WORK / "tdm_ball")
        self.assertEqual(run.outcome["status"], "ok")
        m = 7800.0 * 4.0 / 3.0 * math.pi * R ** 3
        fs = run.final_state()
        self.assertAlmostEqual(fs["z"][0], R - m * G / k_n, delta=1e-6 * R)
        self.assertLess(abs(fs["vz"][0]), 1e-6)
        v = run.snapshot(-1)
        self.assertEqual(int(v["mode"][0]), 1)  # soft
        c = run.contacts(-1)  # the floor's contact carries the weight at the overlap m g / k
        self.assertAlmostEqual(c["time"], 2.0, places=12)
        self.assertEqual(list(c["wall"]), [0])
        self.assertEqual(list(c["j"]), [-1])
        self.assertEqual(int(c["kind"][0]), 1)
        self.assertAlmostEqual(c["fn_z"][0], m * G, delta=1e-6 * m * G)
        self.assertAlmostEqual(c["overlap"][0], m * G / k_n, delta=1e-6 * R)
        self.assertAlmostEqual(c["z"][0], 0.0, delta=1e-9)
        self.assertEqual(run.summary["method"], "tdm")
        self.assertGreater(run.summary["soft"]["steps"], 1000)
        self.assertEqual(run.checkpoint()["method"], "tdm")


class Hybrid(unittest.TestCase):
    def test_the_hybrid_ball_comes_to_rest_past_the_zeno_time(self):
        e, z0, R = 0.8, 1.05, 0.05
        sc = ball_scene("hybrid", 5.0, e, z0, R)
        sc["material"]["steel"].update({"contact": "linear", "stiffness": 1.0e6})
        run = matep.run(sc, out=WORK / "hybrid_ball")
        self.assertEqual(run.outcome["status"], "ok")
        fs = run.final_state()
        self.assertAlmostEqual(fs["z"][0], R, delta=0.01 * R)
        th = run.thermo()
        early = th["time"] < 0.4  # before the first impact: free fall, energy conserved
        total = th["kinetic_energy"] + th["potential_energy"]
        np.testing.assert_allclose(total[early], total[0], rtol=1e-12)
        self.assertLess(th["kinetic_energy"][-1], 1e-6 * total[0])
        self.assertEqual(run.checkpoint()["method"], "hybrid")


class Interrupt(unittest.TestCase):
    def test_ctrl_c_stops_a_run_from_python_with_its_outputs_written(self):
        out = WORK / "interrupted"
        code = ("import matep, sys\n"
                f"sc = matep.load({str(Path(os.environ.get('MATEP_SOURCE_DIR', '.')) / 'cases/elastic_gas.toml')!r})\n"
                "sc['run']['end_time'] = 1e4\n"
                "sc['output']['events'] = False\n"
                "print('started', flush=True)\n"
                f"matep.run(sc, out={str(out)!r})\n")
        p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.assertEqual(p.stdout.readline().strip(), "started")
        time.sleep(1.5)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("KeyboardInterrupt: matep run interrupted", err)
        summary = matep.read_summary(out / "summary.json")
        self.assertEqual(summary["status"], "interrupted")
        self.assertGreater(summary["time_reached"], 0.0)
        self.assertTrue((out / "checkpoint.bin").exists())


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--work", type=Path, default=WORK)
    a, rest = ap.parse_known_args()
    WORK = a.work
    WORK.mkdir(parents=True, exist_ok=True)
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
