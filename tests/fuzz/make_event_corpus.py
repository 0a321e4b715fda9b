#!/usr/bin/env python3
"""Writes the event-log corpus of the fuzz target Fuzz.EventLogReader... (tests/fuzz/corpus/*.bin).

Three small EDM runs with output.events = true (cases/disks_in_a_box.toml in 2D, elastic_gas.toml in
3D, and heap.toml in 2D as EDM: fixed grains, so the fixed-grain flag and mj = +inf, and an inlet's
inflow records) give their first 200 records (264 bytes each, so every file stays under 64 KiB),
written again in the layouts readers take: version 4 (with each particle's group and material, as
runs write it) with K = 1024 and K = 64 (several blocks), version 3 (no identity section) and
version 1 (no checksums). Deterministic: the runs are seeded.

Usage: tests/fuzz/make_event_corpus.py [path/to/matep]   (default build/matep)
"""
import os
import struct
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CORPUS = os.path.join(ROOT, "tests", "fuzz", "corpus")
HEADER, RECORD, TRAILER = 64, 264, 32
KEEP = 200


def _table():
    t = []
    for n in range(256):
        c = n
        for _ in range(8):
            c = (c >> 1) ^ 0x82F63B78 if c & 1 else c >> 1
        t.append(c)
    return t


TABLE = _table()


def crc32c(data: bytes, crc: int = 0) -> int:
    crc ^= 0xFFFFFFFF
    for b in data:
        crc = TABLE[(crc ^ b) & 0xFF] ^ (crc >> 8)
    return crc ^ 0xFFFFFFFF


assert crc32c(b"123456789") == 0xE3069283


def read_log(path):
    """(dimension, particles, fixed flag, identity section, records) of a version-3 or 4 log."""
    with open(path, "rb") as f:
        b = f.read()
    version = struct.unpack_from("<I", b, 8)[0]
    assert b[:8] == b"MATEPLOG" and version in (3, 4), path
    dim, size, flags = struct.unpack_from("<III", b, 12)
    particles, k, sec = struct.unpack_from("<QII", b, 24)
    assert size == RECORD
    section = b[HEADER:HEADER + sec] if version == 4 else b""
    records, off = [], HEADER + len(section)
    while off < len(b):
        n = struct.unpack_from("<I", b, off + min(k, (len(b) - off - TRAILER) // RECORD) * RECORD + 8)[0]
        records += [b[off + i * RECORD:off + (i + 1) * RECORD] for i in range(n)]
        off += n * RECORD + TRAILER
    return dim, particles, flags & 1, section, records


def write_log(path, dim, particles, fixed, section, records, k):
    """Version 4 with an identity section, version 3 without."""
    h = bytearray(HEADER)
    h[:8] = b"MATEPLOG"
    struct.pack_into("<IIIIQII", h, 8, 4 if section else 3, dim, RECORD, fixed, particles, k, len(section))
    struct.pack_into("<I", h, 60, crc32c(bytes(h[:60])))
    out = bytearray(h) + section
    blocks = [records[i:i + k] for i in range(0, len(records), k)]
    if not blocks or len(blocks[-1]) == k:
        blocks.append([])  # the last block has 0..K-1 records
    total = 0
    for n, blk in enumerate(blocks):
        body = b"".join(blk)
        total += len(blk)
        t = bytearray(TRAILER)
        t[:8] = b"MATEPBLK"
        struct.pack_into("<IIQ", t, 8, len(blk), 1 if n == len(blocks) - 1 else 0, total)
        struct.pack_into("<I", t, 24, crc32c(bytes(t[:24]), crc32c(body)))
        out += body + t
    with open(path, "wb") as f:
        f.write(out)


def write_v1(path, dim, particles, records):
    h = bytearray(HEADER)
    h[:8] = b"MATEPLOG"
    struct.pack_into("<IIIIQ", h, 8, 1, dim, RECORD, 0, particles)
    with open(path, "wb") as f:
        f.write(bytes(h) + b"".join(records))


def run(matep, case, sets, tmp):
    out = os.path.join(tmp, os.path.basename(case))
    args = [matep, "run", os.path.join(ROOT, "cases", case), "--quiet", "--out", out, "--set", "output.events=true"]
    for s in sets:
        args += ["--set", s]
    subprocess.run(args, check=False, capture_output=True)  # a collapse still leaves its log
    dim, particles, fixed, section, records = read_log(os.path.join(out, "events.bin"))
    assert len(records) >= KEEP, f"{case}: only {len(records)} records"
    return dim, particles, fixed, section, records[:KEEP]


def main():
    matep = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "matep")
    with tempfile.TemporaryDirectory() as tmp:
        d2 = run(matep, "disks_in_a_box.toml", ["run.end_time=0.2"], tmp)
        d3 = run(matep, "elastic_gas.toml", ["run.end_time=0.5"], tmp)
        heap = run(matep, "heap.toml", ["run.method=edm", "run.tc=1e-4", "run.end_time=0.6"], tmp)
    write_log(os.path.join(CORPUS, "events_2d.bin"), *d2, k=1024)
    write_log(os.path.join(CORPUS, "events_3d.bin"), *d3, k=1024)
    write_log(os.path.join(CORPUS, "events_3d_blocks.bin"), *d3[:3], b"", d3[4], k=64)
    write_log(os.path.join(CORPUS, "events_heap_2d_fixed.bin"), *heap, k=64)
    write_v1(os.path.join(CORPUS, "events_2d_v1.bin"), d2[0], d2[1], d2[4])
    for name in sorted(os.listdir(CORPUS)):
        if name.endswith(".bin"):
            print(name, os.path.getsize(os.path.join(CORPUS, name)))


if __name__ == "__main__":
    main()
