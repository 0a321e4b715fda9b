"""matep from Python: build a scene (a dict or a TOML file), check it, run it, read what it wrote.

    import matep
    scene = matep.load("cases/bouncing_ball.toml")            # or a dict of tables
    scene["run"]["end_time"] = 1.0
    run = matep.run(scene, out="out/ball")                     # a Run; Ctrl-C stops it cleanly
    t = run.thermo()["time"]                                    # numpy arrays by column
    g = run.final_state()                                       # ... and group / material names

`run` and `check` take a path, a dict or TOML text, with `set=["run.end_time=1"]` overrides as
`matep run --set`. A scene error raises SceneError (a ValueError) with the CLI's message, a file
error FileError (an OSError). The package lives in tools/python/matep; the build puts it, with
its native part, into BUILD/python (PYTHONPATH=BUILD/python).
"""
from __future__ import annotations

import math
import os
from pathlib import Path

from . import outputs
from .outputs import (read_contacts, read_csv, read_events, read_frame, read_lammps_dump, read_pvd, read_summary,
                      read_vtp, read_xyz, snapshots)

try:
    from . import _native
except ImportError as e:  # the pure-Python readers work without it
    _native = None
    _native_error = e

__all__ = ["load", "dumps", "check", "run", "Run", "SceneError", "FileError", "read_checkpoint", "outputs",
           "read_csv", "read_frame", "read_vtp", "read_pvd", "read_xyz", "read_lammps_dump", "read_events",
           "read_summary", "read_contacts", "snapshots"]

SceneError = _native.SceneError if _native else ValueError
FileError = _native.FileError if _native else OSError


def _need_native():
    if _native is None:
        raise ImportError(f"matep's native part is not built ({_native_error}); build the target _native")
    return _native


def load(path) -> dict:
    """A scene file as a dict of tables (tomllib), to change and pass to run() or check()."""
    import tomllib
    with open(path, "rb") as f:
        d = tomllib.load(f)
    d["__base_dir__"] = str(Path(path).resolve().parent)  # relative particle / mesh files resolve there
    return d


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if hasattr(v, "tolist"):  # numpy arrays and scalars
        return _value(v.tolist())
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"a scene value must be a number, string, boolean, list or table, not {type(v).__name__}")


def _key(k: str) -> str:
    return k if k and all(c.isalnum() or c in "_-" for c in k) else _value(str(k))


def dumps(scene: dict) -> str:
    """A scene dict as TOML text: top-level tables ([run], [domain]) and named ones
    ([material.NAME], [particles.NAME], ...); inline tables for dicts inside a table."""
    lines = []
    for name, table in scene.items():
        if name.startswith("__"):
            continue
        if not isinstance(table, dict):
            raise TypeError(f"scene key {name!r}: expected a table (dict), got {type(table).__name__}")
        named = all(isinstance(v, dict) for v in table.values()) and name in (
            "material", "particles", "wall", "inlet", "outlet")
        for sub, body in (table.items() if named else [(None, table)]):
            lines.append(f"[{_key(name)}{'.' + _key(sub) if sub is not None else ''}]")
            lines += [f"{_key(k)} = {_value(v)}" for k, v in body.items()]
            lines.append("")
    return "\n".join(lines)


def _scene_args(scene, name):
    """(path, text, base_dir) for the native calls."""
    if isinstance(scene, dict):
        return name or "<python scene>", dumps(scene), scene.get("__base_dir__", os.getcwd())
    if isinstance(scene, (str, os.PathLike)) and "\n" not in str(scene) and "=" not in str(scene):
        return str(scene), "", ""
    return name or "<python scene>", str(scene), os.getcwd()


def check(scene, set=(), resume=None, name=None) -> dict:
    """What `matep check` prints ('description'), the scene's warnings, method, dimension,
    end_time and output folder; raises SceneError for a bad scene."""
    path, text, base = _scene_args(scene, name)
    return _need_native().check(path, text, base, list(set), str(resume or ""))


class Run:
    """A finished run's output folder, read on demand into numpy arrays."""

    def __init__(self, out_dir, outcome: dict | None = None):
        self.dir = Path(out_dir)
        self.outcome = outcome or {}

    @property
    def summary(self) -> dict:
        return read_summary(self.dir / "summary.json")

    def thermo(self) -> dict:
        return read_csv(self.dir / "thermo.csv")

    def final_state(self) -> dict:
        return read_csv(self.dir / "final_state.csv")

    def outflow(self) -> dict:
        return read_csv(self.dir / "outflow.csv")

    def events(self):
        """(header, records) of events.bin (outputs.read_events)."""
        return read_events(self.dir / "events.bin")

    def snapshots(self) -> list:
        """(time, .vtp path) of the grains' snapshots; read_vtp(path) gives the arrays."""
        return snapshots(self.dir)

    def snapshot(self, k: int = -1) -> dict:
        return read_vtp(self.snapshots()[k][1])

    def contacts(self, k: int = -1) -> dict:
        """The contacts of snapshot k (output.contacts = true): read_contacts of its CSV."""
        files = sorted((self.dir / "snapshots").glob("contacts_*.csv"))
        if not files:
            raise FileNotFoundError(f"{self.dir}: no contacts files (set output.contacts = true)")
        return read_contacts(files[k])

    def checkpoint(self) -> dict:
        return read_checkpoint(self.dir / "checkpoint.bin")

    def __repr__(self):
        return f"Run({str(self.dir)!r}, status={self.outcome.get('status', '?')!r})"


def run(scene, out=None, set=(), resume=None, name=None) -> Run:
    """Runs a scene (a path, a dict or TOML text) into `out` (default: the scene's output.dir) and
    returns the Run. A run that stops early (status other than "ok") still returns; Ctrl-C stops
    the run, publishes its outputs and raises KeyboardInterrupt."""
    path, text, base = _scene_args(scene, name)
    o = _need_native().run(path, text, base, list(set), str(out or ""), str(resume or ""))
    if o["status"] == "interrupted":
        raise KeyboardInterrupt(f"matep run interrupted: {o['message']} (outputs in {o['out_dir']})")
    return Run(o["out_dir"], o)


def read_checkpoint(path) -> dict:
    """A checkpoint's method, dimension, time and scene (checked whole: checksum and every part)."""
    return _need_native().read_checkpoint(str(path))
