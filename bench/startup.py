"""Startup time of the command line (issue 45: `m3c2 --version` and `--help` under 0.15 s): the
median wall time of fresh processes for `m3c2 --version`, `m3c2 --help`, a subcommand's own
help, `import m3c2kit` and, beside them, `import py4dgeo` in py4dgeo's environment. Prints
figures, asserts nothing.

    .venv/bin/python bench/startup.py [--python-py4dgeo /tmp/p4d/bin/python] [--runs 15]
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

CASES = {
    "python -c pass (the interpreter alone)": ["-c", "pass"],
    "m3c2 --version": ["-m", "m3c2kit", "--version"],
    "m3c2 --help": ["-m", "m3c2kit", "--help"],
    "m3c2 info --help": ["-m", "m3c2kit", "info", "--help"],
    "m3c2 compare --help": ["-m", "m3c2kit", "compare", "--help"],
    "import m3c2kit": ["-c", "import m3c2kit"],
}


def median_seconds(command: list[str], runs: int) -> float:
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--python-py4dgeo", help="a Python with py4dgeo installed, for `import py4dgeo` beside ours")
    ap.add_argument("--runs", type=int, default=15)
    args = ap.parse_args(argv)
    print(f"median of {args.runs} fresh processes each")
    for name, words in CASES.items():
        print(f"{name:42s} {median_seconds([sys.executable, *words], args.runs) * 1e3:7.1f} ms")
    if args.python_py4dgeo:
        for name, words in (("py4dgeo's interpreter alone", ["-c", "pass"]), ("import py4dgeo", ["-c", "import py4dgeo"])):
            print(f"{name:42s} {median_seconds([args.python_py4dgeo, *words], args.runs) * 1e3:7.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
