"""Proof that adding the p_value column (issue 34) changed nothing else in validation/output_hashes.py's
outputs: every output whose hash differs from the stored expectation is taken apart again without
its p_value column and hashed, which must give the stored hash.

    cd /tmp && PYTHONPATH=/work/main/python python /work/main/validation/output_hashes.py \\
        --write /tmp/hashes_p_value.json --keep /tmp/hashes_p_value
    python /work/main/validation/output_hashes_p_value.py /work/main/validation/output_hashes_after.json \\
        /tmp/hashes_p_value.json /tmp/hashes_p_value

Text tables (.csv, .txt): the p_value field is removed from every line. PLY: the p_value property
is removed from the header and each binary record. Other outputs that differ (LAS/LAZ written with
--all-fields carry p_value as an extra dimension; the HTML report gains a row on multiple testing)
are listed as such and not claimed. Exit 1 if a stripped output's hash differs from the stored one.
"""
from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

PLY_TYPES = {"char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4", "uint": "u4",
             "float": "f4", "double": "f8", "int8": "i1", "uint8": "u1", "int16": "i2", "uint16": "u2",
             "int32": "i4", "uint32": "u4", "float32": "f4", "float64": "f8"}


def strip_text(data: bytes) -> bytes | None:
    lines = data.split(b"\n")
    for sep in (b",", b" ", b"\t", b";"):
        names = lines[0].lstrip(b"/# ").split(sep)
        if b"p_value" in names:
            k = names.index(b"p_value")
            return b"\n".join(sep.join(f for j, f in enumerate(line.split(sep)) if j != k) if line else line
                              for line in lines)
    return None


def strip_ply(data: bytes) -> bytes | None:
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    if "property double p_value" not in header and "property float p_value" not in header:
        return None
    if not any(h.startswith("format binary_little_endian") for h in header):
        return None
    count = next(int(h.split()[2]) for h in header if h.startswith("element vertex"))
    props = [(h.split()[2], "<" + PLY_TYPES[h.split()[1]]) for h in header if h.startswith("property")]
    rows = np.frombuffer(data[end:], dtype=np.dtype(props), count=count)
    kept = [(n, t) for n, t in props if n != "p_value"]
    out = np.empty(count, dtype=np.dtype(kept))
    for n, _ in kept:
        out[n] = rows[n]
    new_header = "\n".join(h for h in header if not h.endswith(" p_value")) + "\n"
    return new_header.encode("ascii") + out.tobytes() + data[end + rows.nbytes:]


def main(argv: list[str]) -> int:
    stored, new, kept = json.loads(Path(argv[0]).read_text()), json.loads(Path(argv[1]).read_text()), Path(argv[2])
    folders = {p.name.split("-", 1)[1]: p for p in kept.iterdir() if p.is_dir()}  # "07-vertical-two-pass"
    failures = 0
    for name, workload in new["workloads"].items():
        before = stored["workloads"].get(name, {}).get("outputs", {})
        for file, digest in workload["outputs"].items():
            if before.get(file) == digest:
                continue
            path = folders.get(name.replace(" ", "-"), kept / "?") / file
            if not path.is_file():
                print(f"{name}: {file}: differs (not a kept file: not claimed)")
                continue
            data = path.read_bytes()
            stripped = strip_ply(data) if file.endswith(".ply") else (
                strip_text(data) if file.endswith((".csv", ".txt")) else None)
            if stripped is None:
                print(f"{name}: {file}: differs (no p_value column to strip: not claimed)")
                continue
            same = hashlib.sha256(stripped).hexdigest() == before.get(file)
            failures += not same
            print(f"{name}: {file}: {'identical' if same else 'STILL DIFFERS'} without p_value")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
