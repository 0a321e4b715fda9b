"""Readers of matep's output files into numpy arrays (README "Outputs" gives each format).

Pure Python + numpy: read_vtp / read_pvd (snapshots, ASCII or appended raw binary), read_xyz
(extended XYZ snapshots), read_lammps_dump, read_csv (thermo.csv, final_state.csv, outflow.csv),
read_summary (summary.json) and read_events (events.bin, every version); checkpoints are read by the
native part (matep.read_checkpoint).
Binary data is read with one numpy view over the file's bytes (no second copy).
"""
from __future__ import annotations

import json
import struct
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

_VTK_TYPES = {"Float32": "<f4", "Float64": "<f8", "Int8": "<i1", "UInt8": "<u1", "Int16": "<i2", "UInt16": "<u2",
              "Int32": "<i4", "UInt32": "<u4", "Int64": "<i8", "UInt64": "<u8"}


def read_vtp(path) -> dict:
    """Every DataArray of a matep .vtp as a numpy array by Name ('position' for the points;
    n x 3 for vectors), with the cells of Polys / Lines as 'cells' (a list of index arrays),
    the snapshot's 'time' where the file gives it, and the legends 'group_names' /
    'material_names' from its header comment."""
    data = Path(path).read_bytes()
    at = data.find(b"<AppendedData")
    if at >= 0:
        raw = data.index(b"_", at) + 1
        root = ET.fromstring(data[:at] + b"</VTKFile>")
        header = np.uint64 if root.get("header_type", "UInt32") == "UInt64" else np.uint32
    else:
        raw, header = -1, np.uint32
        root = ET.fromstring(data)
    hsize = np.dtype(header).itemsize

    def array(da) -> np.ndarray:
        dt = np.dtype(_VTK_TYPES[da.get("type")])
        if da.get("format") == "appended":
            start = raw + int(da.get("offset"))
            nbytes = int(np.frombuffer(data, header, 1, start)[0])
            a = np.frombuffer(data, dt, nbytes // dt.itemsize, start + hsize)
        else:
            a = np.array((da.text or "").split(), dtype=dt)
        n = int(da.get("NumberOfComponents", "1"))
        return a.reshape(-1, n) if n > 1 else a

    piece = root.find("PolyData/Piece")
    out: dict = {}
    pts = piece.find("Points/DataArray")
    out["position"] = array(pts) if pts is not None else np.zeros((0, 3))
    pd = piece.find("PointData")
    for da in (pd.findall("DataArray") if pd is not None else []):
        out[da.get("Name")] = array(da)
    fd = root.find("PolyData/FieldData")
    if fd is not None:
        for da in fd.findall("DataArray"):
            if da.get("Name") == "TimeValue":
                out["time"] = float(array(da)[0])
    cells = []
    for kind in ("Polys", "Lines"):
        node = piece.find(kind)
        if node is None:
            continue
        arrs = {da.get("Name"): array(da) for da in node.findall("DataArray")}
        conn, offs = arrs.get("connectivity"), arrs.get("offsets")
        if conn is not None and offs is not None:
            start = 0
            for end in offs:
                cells.append(conn[start:int(end)])
                start = int(end)
    out["cells"] = cells
    head = data[:at if at >= 0 else len(data)].decode("utf-8", "replace")
    c = head.find("<!-- matep snapshot")
    if c >= 0:
        comment = head[c:head.index("-->", c)]
        for key, name in (("group:", "group_names"), ("material:", "material_names")):
            k = comment.find(key)
            if k >= 0:
                part = comment[k + len(key):].split(";")[0].split("-->")[0]
                out[name] = [p.strip().split(" ", 1)[1] for p in part.split(",") if p.strip()]
    return out


def read_pvd(run_dir) -> list[tuple[float, int, Path]]:
    """(time, part, file) of each data set in RUN_DIR/snapshots.pvd (part 0: the grains)."""
    run_dir = Path(run_dir)
    root = ET.parse(run_dir / "snapshots.pvd").getroot()
    return [(float(d.get("timestep")), int(d.get("part")), run_dir / d.get("file")) for d in root.iter("DataSet")]


def snapshots(run_dir, t_from: float = -np.inf) -> list[tuple[float, Path]]:
    """(time, .vtp of the grains) of each snapshot at or after t_from."""
    return [(t, f) for t, part, f in read_pvd(run_dir) if part == 0 and t >= t_from - 1e-9]


def read_xyz(path) -> dict:
    """An extended-XYZ snapshot written by matep: the header's key=value pairs ('Time', 'Lattice',
    'Origin', 'pbc', 'Properties') and each property column by name (numbers as numpy arrays)."""
    with open(path) as f:
        n = int(f.readline())
        info = _key_values(f.readline())
        rows = [f.readline().split() for _ in range(n)]
    props = info["Properties"].split(":")
    out: dict = {"info": info}
    col = 0
    for k in range(0, len(props), 3):
        name, kind, m = props[k], props[k + 1], int(props[k + 2])
        cols = [r[col:col + m] for r in rows]
        a = np.array(cols, dtype=float if kind == "R" else int if kind == "I" else object).reshape(n, m)
        out[name] = a[:, 0] if m == 1 else a
        col += m
    return out


def _key_values(line: str) -> dict:
    out, i = {}, 0
    while i < len(line):
        while i < len(line) and line[i].isspace():
            i += 1
        if i >= len(line):
            break
        eq = line.index("=", i)
        key = line[i:eq]
        if line[eq + 1] == '"':
            end = line.index('"', eq + 2)
            out[key], i = line[eq + 2:end], end + 1
        else:
            end = eq + 1
            while end < len(line) and not line[end].isspace():
                end += 1
            out[key], i = line[eq + 1:end], end
    return out


def read_lammps_dump(path) -> dict:
    """One LAMMPS 'dump custom' frame written by matep: 'timestep', 'time', 'box' (3 x 2) and
    each ATOMS column by name."""
    with open(path) as f:
        lines = f.read().splitlines()
    out: dict = {}
    k = 0
    while k < len(lines):
        item = lines[k]
        if item == "ITEM: TIMESTEP":
            out["timestep"] = int(lines[k + 1]); k += 2
        elif item == "ITEM: TIME":
            out["time"] = float(lines[k + 1]); k += 2
        elif item == "ITEM: NUMBER OF ATOMS":
            n = int(lines[k + 1]); k += 2
        elif item.startswith("ITEM: BOX BOUNDS"):
            out["box"] = np.array([lines[k + 1 + d].split() for d in range(3)], float); k += 4
        elif item.startswith("ITEM: ATOMS"):
            names = item.split()[2:]
            a = np.array([lines[k + 1 + i].split() for i in range(n)], float).reshape(n, len(names))
            for c, name in enumerate(names):
                out[name] = a[:, c].astype(int) if name in ("id", "type", "material", "mode") else a[:, c]
            k += 1 + n
        else:
            k += 1
    return out


def read_csv(path) -> dict:
    """A CSV output (thermo.csv, final_state.csv, outflow.csv) as {column: numpy array}; text
    columns (group, material) stay strings."""
    with open(path) as f:
        names = f.readline().strip().split(",")
        rows = [line.rstrip("\n").split(",") for line in f if line.strip()]
    out = {}
    for c, name in enumerate(names):
        col = [r[c] for r in rows]
        try:
            out[name] = np.array(col, dtype=float)
        except ValueError:
            out[name] = np.array(col, dtype=object)
    return out


def read_contacts(path) -> dict:
    """A snapshot's contacts (snapshots/contacts_NNNNNN.csv, output.contacts) as {column: numpy
    array} plus "time"; integer columns (kind, i, j, wall, collisions) as int64. kind 1: a soft
    contact's force at that time; kind 0: hard collisions' mean force since the previous snapshot."""
    with open(path) as f:
        first = f.readline()
        if not first.startswith("# time = "):
            raise ValueError(f"{path}: not a matep contacts file (no '# time = ' line)")
        names = f.readline().strip().split(",")
        data = np.loadtxt(f, delimiter=",", ndmin=2)
    if data.size == 0:
        data = np.zeros((0, len(names)))
    out = {"time": float(first[len("# time = "):])}
    for c, name in enumerate(names):
        col = data[:, c]
        out[name] = col.astype(np.int64) if name in ("kind", "i", "j", "wall", "collisions") else col
    return out


def read_frame(path):
    """read_csv as a pandas DataFrame (pandas is optional: python3-pandas)."""
    import pandas as pd
    return pd.DataFrame(read_csv(path))


def read_summary(path) -> dict:
    with open(path) as f:
        return json.load(f)


# events.bin (README "Event log"): a 64-byte header, 264-byte records; version 3 puts a 32-byte
# checksum record after every K records (header bytes 32..35).
EVENT_DTYPE = np.dtype([("time", "<f8"), ("kind", "u1"), ("pad", "u1", 3), ("i", "<u4"), ("j", "<u4"),
                        ("pad2", "u1", 4), ("mi", "<f8"), ("mj", "<f8"), ("e", "<f8"), ("normal", "<f8", 3),
                        ("vi_before", "<f8", 3), ("vj_before", "<f8", 3), ("vi_after", "<f8", 3),
                        ("vj_after", "<f8", 3), ("wi_before", "<f8", 3), ("wj_before", "<f8", 3),
                        ("wi_after", "<f8", 3), ("wj_after", "<f8", 3)])


def read_events(path) -> tuple[dict, np.ndarray]:
    """(header, records): the header's fields (version 4: also 'groups', 'materials' and each
    particle id's 'group' and 'material' index) and every record as one numpy structured array
    (fields as in EVENT_DTYPE). Checksums are not checked here: `matep log verify` does."""
    data = np.memmap(path, dtype=np.uint8, mode="r")
    if bytes(data[:8]) != b"MATEPLOG":
        raise ValueError(f"{path}: not a matep event log")
    version, dim, rec_size = struct.unpack_from("<III", data, 8)
    flags = struct.unpack_from("<I", data, 20)[0]
    particles = struct.unpack_from("<Q", data, 24)[0]
    header = {"version": version, "dimension": dim, "record_size": rec_size, "flags": flags, "particles": particles}
    if rec_size != EVENT_DTYPE.itemsize:
        raise ValueError(f"{path}: record size {rec_size}, expected {EVENT_DTYPE.itemsize}")
    start = 64
    if version >= 4:  # the identity section: group and material names, then each particle's indices
        sec = struct.unpack_from("<I", data, 36)[0]
        G, M = struct.unpack_from("<II", data, 72)
        at, names = 80, []
        for _ in range(G + M):
            n = struct.unpack_from("<H", data, at)[0]
            names.append(bytes(data[at + 2:at + 2 + n]).decode("utf-8"))
            at += 2 + n
        ids = np.frombuffer(data, "<u2", 2 * particles, at).reshape(-1, 2)
        header.update(groups=names[:G], materials=names[G:], group=ids[:, 0], material=ids[:, 1])
        start += sec
    body = data[start:]
    if version < 3:
        n = len(body) // rec_size
        return header, np.frombuffer(body, EVENT_DTYPE, n)
    k = struct.unpack_from("<I", data, 32)[0]
    header["block_records"] = k
    block = k * rec_size + 32
    full = len(body) // block
    parts = []
    if full:  # the full blocks as one strided view, without their checksum records
        view = np.lib.stride_tricks.as_strided(body, shape=(full, k * rec_size), strides=(block, 1))
        parts.append(np.ascontiguousarray(view).view(EVENT_DTYPE).reshape(-1))
    rest = len(body) - full * block
    if rest >= 32:
        parts.append(np.frombuffer(body[full * block:full * block + rest - 32], EVENT_DTYPE))
    return header, (np.concatenate(parts) if len(parts) > 1 else parts[0] if parts else np.zeros(0, EVENT_DTYPE))
