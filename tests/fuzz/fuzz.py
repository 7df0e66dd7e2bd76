"""atheris (libFuzzer) driver for the targets of targets.py.

    python3 tests/fuzz/fuzz.py TARGET [libFuzzer flags, e.g. -atheris_runs=20000 -max_total_time=25]

The seeds of targets.SEEDS are the starting corpus (written to a scratch directory). A crash
writes the input to ./crash-<sha1> and exits non-zero; reproduce with
``python3 tests/fuzz/fuzz.py TARGET crash-<sha1>``. Without atheris, use random_fuzz.py.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import atheris

sys.path.insert(0, str(Path(__file__).resolve().parent))

with atheris.instrument_imports(include=["m3c2kit"]):
    import targets  # noqa: E402  (imports m3c2, instrumented for coverage)


def main() -> None:
    if len(sys.argv) < 2 or sys.argv[1] not in targets.TARGETS:
        sys.exit(f"usage: {sys.argv[0]} {{{','.join(targets.TARGETS)}}} [libFuzzer flags] [corpus or crash files]")
    name = sys.argv[1]
    target = targets.TARGETS[name]
    argv = [sys.argv[0]] + sys.argv[2:]
    if not any(not a.startswith("-") for a in sys.argv[2:]):  # no corpus given: start from the seeds
        corpus = Path(tempfile.mkdtemp(prefix=f"m3c2-corpus-{name}-"))
        for k, seed in enumerate(targets.SEEDS[name]):
            (corpus / f"seed{k}").write_bytes(seed)
        argv.append(str(corpus))
    atheris.Setup(argv, target)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
