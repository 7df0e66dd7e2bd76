"""A seeded, bounded mutation fuzzer for the targets of targets.py, without dependencies.

    python3 tests/fuzz/random_fuzz.py [TARGET ...] [--runs N] [--seconds S] [--seed K]

It mutates the seeds of targets.SEEDS (bit flips, byte insertions and deletions, chunk
duplication and splicing, interesting numbers and tokens) with numpy's PCG64 seeded by --seed,
so a run is reproducible; a failing input is saved as ./crash-<target>-<n>.bin. Used when atheris
is unavailable, and by tests/python/cli/test_errors_fuzz.py.
"""
from __future__ import annotations

import argparse
import sys
import time
import traceback
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import targets  # noqa: E402

TOKENS = (b"nan", b"inf", b"-inf", b"1e309", b"-0", b"0", b"4294967296", b"18446744073709551616", b"\xff\xfe",
          b"\r\n", b"\n", b"\0", b";", b",", b"\t", b"\"", b"'", b"=", b"[", b"]", b"#", b"//", b"end_header",
          b"element vertex 99999999999", b"property list uchar int x", b"format binary_big_endian 1.0",
          b"[General]", b"M3C2VER=1", b"NormalMode=2", b"\x01\x05", b"\x01\x00", b"-9e999", b"0x10", b"1_000")


def mutate(rng: np.random.Generator, data: bytes, pool: list[bytes]) -> bytes:
    buf = bytearray(data)
    for _ in range(int(rng.integers(1, 5))):
        op = int(rng.integers(0, 7))
        pos = int(rng.integers(0, len(buf) + 1))
        if op == 0 and buf:  # flip a bit
            i = int(rng.integers(0, len(buf)))
            buf[i] ^= 1 << int(rng.integers(0, 8))
        elif op == 1:  # insert random bytes
            buf[pos:pos] = rng.integers(0, 256, int(rng.integers(1, 8)), dtype=np.uint8).tobytes()
        elif op == 2 and buf:  # delete a run
            end = min(len(buf), pos + int(rng.integers(1, 16)))
            del buf[pos:end]
        elif op == 3:  # insert an interesting token
            buf[pos:pos] = TOKENS[int(rng.integers(0, len(TOKENS)))]
        elif op == 4 and buf:  # duplicate a chunk
            start = int(rng.integers(0, len(buf)))
            buf[pos:pos] = buf[start:start + int(rng.integers(1, 64))]
        elif op == 5:  # splice with another seed
            other = pool[int(rng.integers(0, len(pool)))]
            cut = int(rng.integers(0, len(other) + 1))
            buf = buf[:pos] + bytearray(other[cut:])
        elif op == 6 and buf:  # truncate
            buf = buf[:pos]
    return bytes(buf)


def fuzz(name: str, runs: int, seconds: float, seed: int) -> list[bytes]:
    """Runs target `name` on the seeds and then on `runs` mutants (or until `seconds` pass);
    returns the inputs that raised (empty when the contract held)."""
    target = targets.TARGETS[name]
    rng = np.random.default_rng(seed)
    pool = list(targets.SEEDS[name])
    failures = []
    deadline = time.monotonic() + seconds
    inputs = iter(pool[:])
    for n in range(len(pool) + runs):
        if time.monotonic() > deadline:
            break
        data = next(inputs, None)
        if data is None:
            data = mutate(rng, pool[int(rng.integers(0, len(pool)))], pool)
        try:
            target(data)
        except Exception:  # noqa: BLE001 - any escape is a finding
            failures.append(data)
            Path(f"crash-{name}-{len(failures)}.bin").write_bytes(data)
            print(f"{name}: input {data!r:.300}\n{traceback.format_exc()}", file=sys.stderr)
            if len(failures) >= 5:
                break
        else:
            if len(pool) < 200 and rng.random() < 0.05:
                pool.append(data)  # keep some mutants as new parents
    return failures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("targets", nargs="*", default=list(targets.TARGETS))
    parser.add_argument("--runs", type=int, default=5000)
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    bad = 0
    for name in args.targets:
        start = time.monotonic()
        failures = fuzz(name, args.runs, args.seconds, args.seed)
        print(f"{name}: {'FAILED on ' + str(len(failures)) + ' inputs' if failures else 'ok'} "
              f"({time.monotonic() - start:.1f} s)")
        bad += bool(failures)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
