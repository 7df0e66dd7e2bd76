"""Output hashes of fixed m3c2 workloads: proof that a refactor leaves every output byte-identical.

    # the baseline, from the checkout before the refactor (cwd outside the repository):
    cd /tmp && PYTHONPATH=/path/to/before/python python /work/main/validation/output_hashes.py \\
        --write /work/main/validation/output_hashes_before.json
    # after it: rerun the same workloads and compare, exit 1 on any difference
    cd /tmp && PYTHONPATH=/work/main/python python /work/main/validation/output_hashes.py \\
        --check /work/main/validation/output_hashes_before.json
    # the table for the docs (from a stored file, or add it to --write/--check)
    python validation/output_hashes.py --markdown --from validation/output_hashes_before.json

Every workload runs the command line, ``python -m m3c2kit ...`` with this interpreter, so
PYTHONPATH chooses the checkout under test; inputs are the bundled data of ``--repo`` (default:
the repository holding this script; the data are the same in both checkouts), outputs go to a
fresh temporary folder per workload (the commands' working directory, outputs named relatively).
Seeds are fixed and every command runs with --threads 2 (results do not depend on the count).
After each workload every file it wrote is hashed (SHA-256); the test goldens of tests/data are
hashed as they are (they are inputs, they must not change). About 50 s on 2 cores.
The JSON holds, per workload, its command lines, {output: sha256} and the step that last wrote
each output, and the environment (library versions: --check notes, but does not fail on, a
change; m3c2kit's folder and commit, to show which checkout ran).

What is normalised before hashing, and why (everything else is hashed as written):

- every file: the absolute paths of the repository and of the workload's folder are replaced by
  ``<repo>`` and ``<work>`` (HTML reports, ``suggest``/``info`` text and the series store name
  their inputs), so the hashes do not depend on where the checkout or the temporary folder is;
- LAS/LAZ: header bytes 90-93 (file creation day of year and year) are zeroed: laspy stamps
  ``date.today()`` into every header it writes (laspy.LasHeader.__init__), so the same run gives
  other bytes on another day. LAZ headers are not compressed: the same offsets;
- HTML (``--report``): the id of each Plotly figure's ``<div>`` (a fresh uuid4 per run, by
  plotly's ``to_html``) becomes ``<uuid>``, and the "m3c2kit version" row's value becomes
  ``<version>`` (a release may bump it without changing any output). The PNG figures are also
  hashed on their own (``--report-png``);
- a series store (a Zarr folder) is hashed array by array, not as a folder listing:
  each array's ``zarr.json`` and chunk files (sorted by relative path), which zarr writes
  deterministically (Blosc zstd, bit shuffle, CRC-32C; checked by two runs), except
  ``source`` (the epochs' paths: hashed as decoded, path-normalised strings) and
  ``source_mtime_ns`` (the epoch files' modification times: excluded, they follow the checkout
  and the temporary files, not the computation); the root ``zarr.json`` is hashed as sorted JSON
  without the ``history`` attribute (UTC time of creation and the m3c2kit version), its
  paths normalised as above. Not hashed: ``.m3c2-lock`` (the writers' lock: host, pid, UTC start,
  command line of the last writer) and ``.m3c2-staging`` (present only while a step writes).

A derived epoch of the series is written as PLY, not LAZ: its SHA-256 is stored in the store
(``source_sha256``), and a LAZ would carry the day's date (above).
"""
from __future__ import annotations

import argparse
import hashlib
import importlib.metadata
import json
import platform
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

FORMAT = "m3c2kit-output-hashes/1"
REPO_DEFAULT = Path(__file__).resolve().parents[1]
#: Versions recorded with the hashes: each writes bytes of its own into some outputs (laspy its
#: name into LAS headers, matplotlib into PNG metadata, plotly its bundle into the report).
LIBRARIES = ("numpy", "laspy", "lazrs", "matplotlib", "plotly", "zarr", "numcodecs", "xarray", "rasterio", "scipy")

# ----------------------------------------------------------------------------------------------
# Workloads. "@/x" is the repository file x (absolute when run, "x" in the recorded command).

T15, T23 = "@/data/toronto-ttp/TTP_15.laz", "@/data/toronto-ttp/TTP_23.laz"
AUTZEN = "@/tests/data/pairs/autzen-bmx/"
THREADS = ("--threads", "2")
#: The README demo (scripts/demo.sh): the parameters `m3c2 suggest` proposes for this pair.
DEMO = ("compare", T15, T23, "--core-spacing", "5", "--normal-scale", "8:40:8", "--projection-scale", "10",
        "--max-depth", "30", *THREADS)
#: A smaller run (about 1,900 core points) for the variants.
SMALL = ("compare", T15, T23, "--core-spacing", "10", "--normal-scale", "8:24:8", "--projection-scale", "10",
         "--max-depth", "30", *THREADS)
#: Above the least the run needs (108 MiB with the 42 MiB the process holds at the start) and below
#: one tile: two tiles of about 506 m on this 506 x 759 m pair. The tile size follows the resident
#: size at the start (run/memory.py: the budget is the limit less what the process holds), the
#: output does not (tiled runs are the same bits for any tile size, docs/scaling.md). A process that
#: starts some 14 MiB larger is refused ("--memory-limit ... is too small"): then raise this value;
#: --check notes the changed command and still compares the outputs.
MEMORY_LIMIT = "130MB"


@dataclass(frozen=True)
class Step:
    """One m3c2 command line; ``stdout``: a file that receives its standard output (for the
    commands whose output is the text they print)."""
    argv: tuple[str, ...]
    stdout: str | None = None


@dataclass(frozen=True)
class Prepare:
    """Input files the script writes itself (a params file, scan positions...): not hashed."""
    description: str
    write: Callable[[Path, Path], list[str]]  # (work folder, repo) -> the names it wrote


@dataclass(frozen=True)
class Workload:
    name: str
    steps: tuple = field(default_factory=tuple)


def m3c2(*argv: str, stdout: str | None = None) -> Step:
    return Step(tuple(argv), stdout)


def _write(folder: Path, name: str, text: str) -> str:
    (folder / name).write_text(text)
    return name


def _cloudcompare_params(folder: Path, repo: Path) -> list[str]:
    # CloudCompare's parameters for the autzen pair (tests/data/pairs/autzen-bmx/PROVENANCE.md),
    # as qM3C2 saves them (the file of tests/python/cli/test_cli.py).
    return [_write(folder, "m3c2_params.txt",
                   "[General]\nM3C2VER=1\nNormalScale=2.780864\nNormalMode=0\nNormalPreferedOri=4\n"
                   "SearchScale=5.780864\nSearchDepth=5.5\nUseSinglePass4Depth=true\nSubsampleEnabled=false\n"
                   "RegistrationErrorEnabled=false\nUseMedian=false\nUseMinPoints4Stat=false\nProjDestIndex=2\n"
                   "ExportStdDevInfo=true\nExportDensityAtProjScale=true\nMaxThreadCount=2\n")]


def _precision_clouds(folder: Path, repo: Path) -> list[str]:
    """M3C2-PM inputs: the subsampled clouds (written by m3c2 subsample) with per-point
    precisions sx, sy, sz appended. No bundled cloud has precisions; these follow the number of
    returns (a multiple return, vegetation, is less precise), a fixed rule, so the run is fixed."""
    written = []
    for name in ("pm_ref", "pm_cmp"):
        lines = (folder / f"{name}_xyz.csv").read_text().splitlines()
        header = lines[0].split(",")
        returns = header.index("number_of_returns")
        out = [",".join(header + ["sx", "sy", "sz"])]
        for line in lines[1:]:
            n = int(float(line.split(",")[returns]))
            out.append(f"{line},0.05,0.05,{0.02 + 0.03 * (n - 1):.2f}")
        written.append(_write(folder, f"{name}.csv", "\n".join(out) + "\n"))
    return written


def _error_propagation_inputs(folder: Path, repo: Path) -> list[str]:
    """M3C2-EP inputs for the Toronto pair: one scanner (point_source_id 0) 1.5 km above the park
    (an airborne survey), a near-identity transformation of the compared epoch and its covariance."""
    sps = {"0": {"origin": [634250.0, 4831675.0, 1500.0], "sigma_range": 0.02, "sigma_scan": 0.0002,
                 "sigma_yaw": 0.0002}}
    transform = "1,0.0001,0,0.05\n-0.0001,1,0,-0.03\n0,0,1,0.02\n"
    covariance = "\n".join(",".join(("1e-8" if i < 9 else "1e-4") if i == j else "0" for j in range(12))
                           for i in range(12)) + "\n"
    return [_write(folder, "sps.json", json.dumps(sps)), _write(folder, "tfM.csv", transform),
            _write(folder, "Cxx.csv", covariance)]


def _series_lists(folder: Path, repo: Path) -> list[str]:
    # Fixed times (a list file), not the files' own: the LAS creation dates of the bundled pair
    # say nothing of the surveys, and a derived file has none.
    return [_write(folder, "epochs.txt", f"{repo / T15[2:]}, 2015-06-01\n{repo / T23[2:]}, 2023-06-01\n"),
            _write(folder, "epochs_add.txt", "epoch3.ply, 2024-06-01\n")]


OBJECTS = ("--window-width", "2", "--window-min-size", "1", "--min-period", "1", "--height-threshold", "0.5",
           "--neighbourhood-radius", "15", "--min-segments", "3", *THREADS)

#: Issue 32's list: the README demo to each format; the same tiled (--tile-size, --memory-limit);
#: 2D mode (--grid, with its GeoTIFFs); the report; LOD variants (bootstrap, Appendix B; median;
#: CloudCompare's semantics; vertical normals with a two-pass depth search, eq. (1) with z and a
#: registration error; mean normals with py4dgeo's scale rule, projected positions and PDAL names;
#: given core normals; M3C2-PM and M3C2-EP; a qM3C2 params file on the autzen pair); the other
#: commands; a three-epoch series and a py4dgeo archive import; the CANUPO classifier.
WORKLOADS: tuple[Workload, ...] = (
    Workload("demo", (m3c2(*DEMO, "-o", "demo.laz"), m3c2(*DEMO, "-o", "demo.csv"),
                      m3c2(*DEMO, "-o", "demo.ply"), m3c2(*DEMO, "-o", "demo.las"))),
    Workload("demo tiled", (m3c2(*DEMO, "-o", "tiled.laz", "--tile-size", "150"),
                            m3c2(*DEMO, "-o", "tiled.csv", "--tile-size", "150"),
                            m3c2(*DEMO, "-o", "memory.laz", "--memory-limit", MEMORY_LIMIT),
                            m3c2(*DEMO, "-o", "memory.csv", "--memory-limit", MEMORY_LIMIT))),
    Workload("grid", (m3c2("compare", T15, T23, "-o", "grid.csv", "--grid", "5", "--max-depth", "30", *THREADS),)),
    Workload("report", (m3c2(*SMALL, "-o", "report.csv", "--report", "report.html", "--report-png", "fig"),)),
    Workload("bootstrap", (m3c2(*SMALL, "-o", "bootstrap.csv", "--lod", "bootstrap", "--bootstrap", "50",
                                "--seed", "7"),)),
    Workload("median", (m3c2(*SMALL, "-o", "median.csv", "--median"),)),
    Workload("compat cloudcompare", (m3c2(*SMALL, "-o", "cloudcompare.csv", "--compat", "cloudcompare",
                                          "--median", "--field-names", "cloudcompare"),)),
    Workload("vertical two-pass", (m3c2("compare", T15, T23, "--core-spacing", "10", "--normal-source", "vertical",
                                        "--projection-scale", "10", "--max-depth", "30", "--first-pass-depth", "5",
                                        "--lod", "z", "--registration-error", "0.05", "--confidence", "0.99",
                                        *THREADS, "-o", "vertical.laz", "--all-fields", "--float64"),)),
    Workload("mean normals", (m3c2("compare", T15, T23, "--core-spacing", "10", "--normal-source", "mean",
                                   "--normal-scale", "8:24:8", "--scale-selection", "py4dgeo", "--orient",
                                   "barycentre", "--projection-scale", "10", "--max-depth", "30",
                                   "--position", "reference-or-core", "--projected", "--field-names", "pdal",
                                   "--all-fields", *THREADS, "-o", "mean.laz"),)),
    Workload("core normals", (m3c2("subsample", T15, "--spacing", "10", "-o", "core.csv"),
                              m3c2("normals", T15, "--core", "core.csv", "--normal-scale", "8:40:8", *THREADS,
                                   "-o", "normals.csv"),
                              m3c2("normals", T15, "--core", "core.csv", "--normal-scale", "8", "--orient",
                                   "away:barycentre", *THREADS, "-o", "normals.laz"),
                              m3c2("compare", T15, T23, "--core", "normals.csv", "--normal-source", "core",
                                   "--projection-scale", "10", "--max-depth", "30", *THREADS,
                                   "-o", "core_normals.csv"))),
    Workload("uncertainty pm", (m3c2("subsample", T15, "--spacing", "2", "-o", "pm_ref_xyz.csv"),
                                m3c2("subsample", T23, "--spacing", "2", "-o", "pm_cmp_xyz.csv"),
                                Prepare("sx, sy, sz appended to the subsampled clouds", _precision_clouds),
                                m3c2("compare", "pm_ref.csv", "pm_cmp.csv", "--core-spacing", "10",
                                     "--normal-scale", "8:24:8", "--projection-scale", "10", "--max-depth", "30",
                                     "--uncertainty", "pm", "--precision-rule", "all", "--precision-scales",
                                     "1,1.5", *THREADS, "-o", "pm.csv"))),
    Workload("uncertainty ep", (Prepare("scan positions, transformation and its covariance",
                                        _error_propagation_inputs),
                                m3c2(*SMALL, "--uncertainty", "ep", "--scan-positions", "sps.json",
                                     "--transform", "tfM.csv", "--alignment-covariance", "Cxx.csv",
                                     "--reduction-point", "634250,4831675,80", "-o", "ep.csv"))),
    Workload("cloudcompare params", (Prepare("qM3C2 parameter file", _cloudcompare_params),
                                     m3c2("compare", AUTZEN + "autzen-bmx-2010.las", AUTZEN + "autzen-bmx-2023.las",
                                          "--core", AUTZEN + "autzen-bmx-largersample.txt", "--params",
                                          "m3c2_params.txt", "-o", "autzen.laz"),
                                     m3c2("compare", AUTZEN + "autzen-bmx-2010.las", AUTZEN + "autzen-bmx-2023.las",
                                          "--core", AUTZEN + "autzen-bmx-largersample.txt", "--params",
                                          "m3c2_params.txt", "-o", "autzen.csv"))),
    Workload("subsample", (m3c2("subsample", T23, "--spacing", "2", "-o", "subsample.laz"),
                           m3c2("subsample", T23, "--spacing", "2", "-o", "subsample.csv"))),
    Workload("c2c", (m3c2("c2c", T15, T23, "--core-spacing", "2", "--model", "plane", *THREADS, "-o", "c2c.csv"),)),
    Workload("suggest", (m3c2("suggest", T15, T23, "--sample", "500", "--seed", "1", *THREADS,
                              stdout="suggest.txt"),)),
    Workload("info", (m3c2("info", "--json", T15, stdout="info.json"),)),
    Workload("roughness", (m3c2("roughness", T15, "--normal-scale", "2:20:2", "--core-spacing", "5", *THREADS,
                                "-o", "roughness.csv", "--plot", "roughness.png"),)),
    Workload("calibrate", (m3c2("calibrate", T15, "--projection-scales", "4,8,12", "--core-spacing", "10",
                                "--max-core", "300", "--bootstrap", "20", "--seed", "2", *THREADS,
                                "-o", "calibrate.csv", "--plot", "calibrate.png"),)),
    Workload("simplify", (m3c2("simplify", T15, "--core-spacing", "5", "--projection-scale", "6", "--median",
                               *THREADS, "-o", "simplify.laz"),)),
    Workload("classify", (m3c2("classify", "train", T15, "--label-field", "classification", "--label-values",
                               "2=ground,5=vegetation", "--scales", "2,4,8", "--max-per-class", "300",
                               "--seed", "1", *THREADS, "-o", "classifier.json", "--plot", "classifier.png"),
                          m3c2("classify", "apply", T23, "--classifier", "classifier.json", "--class-map",
                               "ground=2,vegetation=5", *THREADS, "-o", "classified.laz"),
                          m3c2(*SMALL, "--classifier", "classifier.json", "--keep", "ground",
                               "-o", "ground.csv"))),
    Workload("series", (m3c2("subsample", T23, "--spacing", "1.5", "-o", "epoch3.ply"),
                        Prepare("epoch lists with fixed times", _series_lists),
                        m3c2("series", T15, "epochs.txt", "-o", "toronto.zarr", "--core-spacing", "10",
                             "--normal-scale", "8", "--projection-scale", "10", "--max-depth", "30",
                             "--epoch-chunk", "2", *THREADS),
                        m3c2("series", "add", "toronto.zarr", "epochs_add.txt", *THREADS),
                        m3c2("series", "smooth", "toronto.zarr", "--window", "3", *THREADS),
                        m3c2("series", "objects", "toronto.zarr", "-o", "objects.csv", *OBJECTS),
                        m3c2("series", "changepoints", "toronto.zarr", "--core", "0", "--core", "963",
                             "--window-width", "2", "--window-min-size", "1", "--min-period", "1",
                             stdout="changepoints.txt"),
                        m3c2("series", "report", "toronto.zarr", "-o", "series.html", "--objects", "objects.csv"),
                        m3c2("series", "check", "toronto.zarr", stdout="check.txt"))),
    Workload("series import", (m3c2("series", "import", "@/tests/data/py4dgeo_series/analysis.zip",
                                    "-o", "imported.zarr"),
                               m3c2("series", "report", "imported.zarr", "-o", "imported.html"),
                               m3c2("series", "check", "imported.zarr", stdout="check.txt"))),
)
#: Repository files hashed as they are: the test goldens and inputs (tests/data).
GOLDENS = "tests/data"
GOLDENS_NAME = "test goldens"


# ----------------------------------------------------------------------------------------------
# Normalisation (the module docstring says what and why)

LAS_DATE = slice(90, 94)
UUID = re.compile(rb"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")
VERSION_ROW = re.compile(rb"(<td>m3c2kit version</td><td>)[^<]*(</td>)")


@dataclass(frozen=True)
class Places:
    """The absolute paths replaced by placeholders (as given and resolved), longest first so that
    a path inside the other is replaced whole."""
    pairs: tuple[tuple[bytes, bytes], ...]

    @classmethod
    def of(cls, repo: Path, work: Path) -> "Places":
        found = {}
        for path, name in ((repo, b"<repo>"), (work, b"<work>")):
            for variant in {str(path), str(path.resolve())}:
                found[variant.encode()] = name
        return cls(tuple(sorted(found.items(), key=lambda kv: -len(kv[0]))))

    def apply(self, data: bytes) -> bytes:
        for path, name in self.pairs:
            data = data.replace(path, name)
        return data


def normalised(name: str, data: bytes, places: Places) -> bytes:
    if data[:4] == b"LASF" and len(data) >= LAS_DATE.stop:
        data = data[:LAS_DATE.start] + b"\0" * 4 + data[LAS_DATE.stop:]
    if name.endswith((".html", ".htm")):
        data = VERSION_ROW.sub(rb"\1<version>\2", UUID.sub(b"<uuid>", data))
    return places.apply(data)


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


# ----------------------------------------------------------------------------------------------
# A series store (Zarr v3 folder), array by array

STORE_SKIPPED = (".m3c2-lock", ".m3c2-staging")
ARRAYS_AS_VALUES = ("source",)        # paths: decoded and normalised
ARRAYS_EXCLUDED = ("source_mtime_ns",)  # input files' modification times
ROOT_ATTRIBUTES_EXCLUDED = ("history",)  # UTC time of the step and the m3c2kit version


def is_store(folder: Path) -> bool:
    return (folder / "zarr.json").is_file()


def store_hashes(store: Path, places: Places) -> dict[str, str]:
    out = {}
    root = json.loads((store / "zarr.json").read_text())
    for key in ROOT_ATTRIBUTES_EXCLUDED:
        root.get("attributes", {}).pop(key, None)
    out["zarr.json"] = sha256(places.apply(json.dumps(root, sort_keys=True).encode()))
    for array in sorted(p for p in store.iterdir() if p.is_dir() and p.name not in STORE_SKIPPED):
        if array.name in ARRAYS_EXCLUDED:
            continue
        if array.name in ARRAYS_AS_VALUES:
            import zarr  # the series extra; present wherever a store was written
            values = [str(v) for v in zarr.open_array(str(array), mode="r")[...].tolist()]
            out[array.name] = sha256(places.apply(json.dumps(values).encode()))
            continue
        digest = hashlib.sha256()
        for path in sorted(p for p in array.rglob("*") if p.is_file()):
            rel = path.relative_to(array).as_posix().encode()
            data = path.read_bytes()
            digest.update(b"%s\0%d\0" % (rel, len(data)) + data)
        out[array.name] = digest.hexdigest()
    return out


# ----------------------------------------------------------------------------------------------
# Running

def resolved(arg: str, repo: Path) -> str:
    return str(repo / arg[2:]) if arg.startswith("@/") else arg


def shown(step) -> str:
    """The command as recorded: repository files relative to the repository, as in the README."""
    if isinstance(step, Prepare):
        return f"(prepared: {step.description})"
    text = "m3c2 " + " ".join(a[2:] if a.startswith("@/") else a for a in step.argv)
    return text + (f" > {step.stdout}" if step.stdout else "")


def snapshot(folder: Path) -> dict[str, tuple]:
    return {p.relative_to(folder).as_posix(): (st.st_ino, st.st_size, st.st_mtime_ns)
            for p in folder.rglob("*") if p.is_file() for st in [p.stat()]}


def run_workload(workload: Workload, repo: Path, work: Path) -> tuple[dict[str, str], dict[str, int]]:
    """Runs the steps in `work`; returns {output: sha256} and {output: index of the step that
    last wrote it}."""
    prepared: set[str] = set()
    writer: dict[str, int] = {}
    for index, step in enumerate(workload.steps):
        before = snapshot(work)
        if isinstance(step, Prepare):
            prepared.update(step.write(work, repo))
            continue
        argv = [sys.executable, "-m", "m3c2kit", *(resolved(a, repo) for a in step.argv)]
        done = subprocess.run(argv, cwd=work, capture_output=True)
        if done.returncode != 0:
            raise SystemExit(f"{workload.name}: step {index} failed (exit {done.returncode}): {shown(step)}\n"
                             + done.stderr.decode(errors="replace")[-3000:])
        if step.stdout:
            (work / step.stdout).write_bytes(done.stdout)
        for name, signature in snapshot(work).items():
            if before.get(name) != signature:
                writer[name] = index
    return hashes_of(work, prepared, Places.of(repo, work), writer)


def hashes_of(work: Path, prepared: set[str], places: Places, writer: dict[str, int]):
    hashes: dict[str, str] = {}
    writers: dict[str, int] = {}
    for entry in sorted(work.iterdir()):
        if entry.is_dir() and is_store(entry):
            for name, digest in store_hashes(entry, places).items():
                # an array's writer: the last step that changed one of its files (create, add,
                # smooth and objects each write their own arrays, all of them the root zarr.json)
                key = f"{entry.name}/{name}"
                hashes[key] = digest
                writers[key] = max((i for n, i in writer.items() if n == key or n.startswith(key + "/")),
                                   default=-1)
            continue
        for path in ([entry] if entry.is_file() else sorted(p for p in entry.rglob("*") if p.is_file())):
            name = path.relative_to(work).as_posix()
            if name in prepared:
                continue
            hashes[name] = sha256(normalised(name, path.read_bytes(), places))
            writers[name] = writer.get(name, -1)
    return hashes, writers


def golden_hashes(repo: Path) -> dict[str, str]:
    root = repo / GOLDENS
    return {p.relative_to(repo).as_posix(): sha256(p.read_bytes())
            for p in sorted(root.rglob("*")) if p.is_file()}


def environment() -> dict:
    probe = subprocess.run([sys.executable, "-c", "import m3c2kit; print(m3c2kit.__file__)"],
                           capture_output=True, text=True, cwd=tempfile.gettempdir())
    package = Path(probe.stdout.strip()).parent if probe.returncode == 0 else None
    commit = None
    if package is not None:
        git = subprocess.run(["git", "-C", str(package), "rev-parse", "HEAD"], capture_output=True, text=True)
        commit = git.stdout.strip() if git.returncode == 0 else None
    versions = {}
    for name in LIBRARIES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = None
    return {"python": platform.python_version(), "libraries": versions,
            "m3c2kit": str(package) if package else None, "commit": commit}


def run_all(repo: Path, only: list[str] | None, keep: Path | None) -> dict:
    workloads = {}
    chosen = [w for w in WORKLOADS if not only or w.name in only]
    with tempfile.TemporaryDirectory(prefix="m3c2-output-hashes-") as tmp:
        base = keep or Path(tmp)
        for number, workload in enumerate(chosen):
            work = base / f"{number:02d}-{workload.name.replace(' ', '-')}"
            work.mkdir(parents=True)
            start = time.monotonic()
            hashes, writers = run_workload(workload, repo, work)
            print(f"{workload.name}: {len(hashes)} output(s) in {time.monotonic() - start:.1f} s", file=sys.stderr)
            workloads[workload.name] = {"commands": [shown(s) for s in workload.steps], "outputs": hashes,
                                        "written_by": writers}
    if not only or GOLDENS_NAME in only:
        workloads[GOLDENS_NAME] = {"commands": [f"(files in the repository under {GOLDENS}/)"],
                                   "outputs": golden_hashes(repo),
                                   "written_by": {}}
    return {"format": FORMAT, "environment": environment(), "workloads": workloads}


# ----------------------------------------------------------------------------------------------
# Comparing and printing

def compare(before: dict, after: dict) -> int:
    """Prints workload | file | before | after | same; returns the number of differences."""
    rows, differences = [], 0
    for name in sorted(set(before["workloads"]) | set(after["workloads"]), key=_order):
        b = before["workloads"].get(name, {})
        a = after["workloads"].get(name, {})
        if b and a and b.get("commands") != a.get("commands"):
            # a note, not a difference: the outputs decide (e.g. a --memory-limit raised because the
            # process starts larger gives other tiles and, by design, the same bytes)
            print(f"note: {name}: the commands differ from the stored ones", file=sys.stderr)
        for file in sorted(set(b.get("outputs", {})) | set(a.get("outputs", {}))):
            hb, ha = b.get("outputs", {}).get(file), a.get("outputs", {}).get(file)
            same = hb is not None and hb == ha
            differences += not same
            rows.append((name, file, (hb or "-")[:16], (ha or "-")[:16], "yes" if same else "NO"))
    header = ("workload", "file", "before", "after", "same")
    widths = [max(len(r[i]) for r in rows + [header]) for i in range(5)]
    for row in [header] + rows:
        print(" | ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip())
    for key in ("python", "libraries"):
        if before["environment"].get(key) != after["environment"].get(key):
            print(f"note: {key} differ: before {before['environment'].get(key)}, "
                  f"after {after['environment'].get(key)}", file=sys.stderr)
    print(f"{len(rows)} row(s), {differences} difference(s)")
    return differences


def _order(name: str) -> int:
    names = [w.name for w in WORKLOADS] + [GOLDENS_NAME]
    return names.index(name) if name in names else len(names)


def markdown(table: dict) -> str:
    lines = ["| workload | command | file | sha256 (first 16 hex) |", "|---|---|---|---|"]
    for name in sorted(table["workloads"], key=_order):
        entry = table["workloads"][name]
        last = None
        writers = entry.get("written_by", {})
        for file, digest in sorted(entry["outputs"].items(), key=lambda kv: (writers.get(kv[0], -1), kv[0])):
            step = writers.get(file, -1)
            command = entry["commands"][step] if 0 <= step < len(entry["commands"]) else entry["commands"][0]
            cell = f"`{command}`" if command != last else ""
            last = command
            lines.append(f"| {name} | {cell.replace('|', '&#124;')} | `{file}` | `{digest[:16]}` |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    action = parser.add_mutually_exclusive_group()
    action.add_argument("--write", type=Path, metavar="FILE.json", help="run and write the hashes")
    action.add_argument("--check", type=Path, metavar="FILE.json",
                        help="run and compare with FILE; exit 1 on a difference")
    action.add_argument("--from", dest="stored", type=Path, metavar="FILE.json",
                        help="no run: print FILE's table (with --markdown)")
    parser.add_argument("--markdown", action="store_true",
                        help="print the markdown table for the docs (of this run, or of --from FILE)")
    parser.add_argument("--repo", type=Path, default=REPO_DEFAULT,
                        help="repository whose data/ and tests/data/ are the inputs (default: this script's)")
    parser.add_argument("--only", action="append", metavar="WORKLOAD", help="run only this workload (repeatable)")
    parser.add_argument("--keep", type=Path, metavar="DIR", help="run in DIR (new) and keep the outputs")
    args = parser.parse_args(argv)
    repo = args.repo.resolve()
    if not (args.write or args.check or args.stored or args.markdown):
        parser.error("one of --write, --check, --from or --markdown is needed")
    if args.stored:
        print(markdown(json.loads(args.stored.read_text())))
        return 0
    table = run_all(repo, args.only, args.keep)
    status = 0
    if args.write:
        args.write.write_text(json.dumps(table, indent=1) + "\n")
        print(f"wrote {args.write}: {sum(len(w['outputs']) for w in table['workloads'].values())} hashes")
    else:
        before = json.loads(args.check.read_text())
        if args.only:
            before["workloads"] = {k: v for k, v in before["workloads"].items() if k in args.only}
        status = 1 if compare(before, table) else 0
    if args.markdown:
        print(markdown(table))
    return status


if __name__ == "__main__":
    sys.exit(main())
