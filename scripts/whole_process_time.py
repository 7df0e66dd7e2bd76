"""CPU time (user + sys, all threads) of each phase of one `m3c2 compare` process (issue 19).

    python scripts/whole_process_time.py REF CMP CORE OUT [compare options...]

Runs m3c2kit.cli.main.main in this process with the reading (cli.inputs.read_input), engine (api.compare) and
writing (cli.compare.write_compare_outputs) steps wrapped in getrusage counters, and prints one line:
imports (m3c2kit.cli.main), laspy (its import as the `m3c2` command imports it, m3c2kit.io.laspy_local,
which the first LAS read would otherwise pay inside reading), reading, engine, writing, rest and total in seconds, and the process's wall time. CPU time, not wall time: on a
shared machine the wall clock measures the other processes too.
"""
import resource
import sys
import time


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main() -> None:
    wall, start = time.perf_counter(), _cpu()
    from m3c2kit.cli import compare, inputs  # noqa: the import itself is the first phase
    from m3c2kit.cli import main as cli

    spent = {"imports": _cpu() - start}
    t = _cpu()
    from m3c2kit.io import laspy_local

    laspy_local.import_laspy_for_local_files()  # as the `m3c2` command imports it

    spent.update(laspy=_cpu() - t, reading=0.0, engine=0.0, writing=0.0)

    def timed(phase, fn):
        def wrapper(*args, **kwargs):
            t = _cpu()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[phase] += _cpu() - t
        return wrapper

    inputs.read_input = compare.read_input = timed("reading", inputs.read_input)
    compare.api.compare = timed("engine", compare.api.compare)
    compare.write_compare_outputs = timed("writing", compare.write_compare_outputs)
    ref, cmp, core, out, *options = sys.argv[1:]
    rc = cli.main(["compare", ref, cmp, "--core", core, "-o", out, "--quiet", *options])
    total = _cpu() - start
    spent["rest"] = total - sum(spent.values())
    print(" ".join(f"{k} {v:.3f}" for k, v in spent.items()), f"total {total:.3f} wall {time.perf_counter() - wall:.2f} "
          f"rc {rc}")


if __name__ == "__main__":
    main()
