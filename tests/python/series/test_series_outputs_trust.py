"""Issue 31, item 3 (docs/errors.md, "A monitoring archive's trust"): `series report -o` and
`series objects -o` go through the atomic writer and the rule that no output is an input (the
store, every path inside it, its reference, its epochs' sources, the objects tables); the report's
objects table is read with clean errors; `series import` of a malformed py4dgeo archive is one
clean line, leaves no half store, and a large archive is committed in chunks."""
from __future__ import annotations

import io
import json
import os
import zipfile
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("xarray")
pytest.importorskip("zarr")
pytest.importorskip("matplotlib")

from m3c2kit.cli.main import main  # noqa: E402

PARAMS = ["--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1", "--quiet"]


def tree(folder: Path) -> dict:
    """Every file below `folder` and its bytes."""
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def series(tmp_path_factory):
    """A store of 3 epochs (seeded) and the objects tables of `series objects`."""
    folder = tmp_path_factory.mktemp("series")
    rng = np.random.default_rng(7)
    xy = rng.uniform(0, 6, (400, 2))
    paths = []
    for k, name in enumerate(("ref.xyz", "ep1.xyz", "ep2.xyz", "obj_members.xyz")):
        path = folder / name
        np.savetxt(path, np.column_stack([xy, 0.01 * k + rng.normal(0, 0.005, len(xy))]))
        paths.append(path)
    store = folder / "st.zarr"
    assert main(["series", *map(str, paths), "-o", str(store), *PARAMS]) == 0
    table = folder / "objects.csv"
    assert main(["series", "objects", str(store), "-o", str(table), "--min-period", "1", "--window-width", "2",
                 "--window-min-size", "1", "--min-segments", "1", "--quiet"]) == 0
    return folder, store, paths, table


def refused(capsys, argv, code=2) -> str:
    assert main(argv) == code
    err = capsys.readouterr().err
    assert err.startswith("m3c2: error: ") and err.count("\n") == 1, err
    return err


@pytest.mark.parametrize("action", ["report", "objects"])
@pytest.mark.parametrize("where", ["zarr.json", "distance/zarr.json", "new-folder-inside/out.csv", "."])
def test_an_output_inside_the_store_is_refused(series, capsys, action, where):
    """`report -o STORE/zarr.json` destroyed the store."""
    folder, store, _, _ = series
    before = tree(store)
    target = store / where
    err = refused(capsys, ["series", action, str(store), "-o", str(target)])
    assert ("inside the series store" in err or "is the store" in err), err
    assert tree(store) == before


@pytest.mark.parametrize("action", ["report", "objects"])
@pytest.mark.parametrize("which", ["reference", "epoch"])
def test_the_stores_reference_and_epoch_sources_are_inputs(series, capsys, action, which):
    """`report -o ref.xyz` overwrote the store's reference (its path is in the store's attributes)."""
    folder, store, paths, _ = series
    target = paths[0] if which == "reference" else paths[2]
    before = target.read_bytes()
    err = refused(capsys, ["series", action, str(store), "-o", str(target)])
    assert f"is the store's {which}" in err and str(target) in err, err
    assert target.read_bytes() == before


def test_the_objects_members_table_is_checked_too(series, capsys):
    """-o obj.csv writes obj_members.csv beside it, which here is an epoch of the store (renamed so)."""
    folder, store, paths, _ = series
    members = folder / "obj_members.csv"
    members.symlink_to(paths[3])
    try:
        err = refused(capsys, ["series", "objects", str(store), "-o", str(folder / "obj.csv")])
        assert "-o's members table" in err and "epoch" in err, err
    finally:
        members.unlink()
    assert not (folder / "obj.csv").exists()


@pytest.mark.parametrize("which", ["table", "members"])
def test_the_reports_objects_tables_are_inputs(series, capsys, which):
    folder, store, _, table = series
    target = table if which == "table" else folder / "objects_members.csv"
    before = target.read_bytes()
    err = refused(capsys, ["series", "report", str(store), "-o", str(target), "--objects", str(table)])
    assert "is the objects" in err, err
    assert target.read_bytes() == before


def test_links_to_inputs_are_refused_and_a_planted_link_is_replaced_not_followed(series, capsys, tmp_path):
    folder, store, paths, _ = series
    via_link = tmp_path / "report.html"
    via_link.symlink_to(store / "zarr.json")
    refused(capsys, ["series", "report", str(store), "-o", str(via_link)])
    hard = tmp_path / "hard.html"
    chunk = next(p for p in sorted((store / "distance").rglob("*")) if p.is_file() and p.name != "zarr.json")
    os.link(chunk, hard)
    err = refused(capsys, ["series", "report", str(store), "-o", str(hard)])
    assert "inside the series store" in err
    # A link planted at the output to a file that is no input: the link is replaced, its target kept.
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    planted = tmp_path / "planted.html"
    planted.symlink_to(victim)
    assert main(["series", "report", str(store), "-o", str(planted)]) == 0
    assert victim.read_text() == "precious"
    assert not planted.is_symlink() and planted.read_text().startswith("<!doctype html>")


def test_the_report_of_a_store_with_objects(series, tmp_path):
    folder, store, _, table = series
    out = tmp_path / "r.html"
    assert main(["series", "report", str(store), "-o", str(out), "--objects", str(table)]) == 0
    assert "4D objects-by-change" in out.read_text()
    assert [p.name for p in tmp_path.iterdir()] == ["r.html"]  # no temporary left


def test_a_table_not_written_with_the_stores_labels_is_refused(series, capsys, tmp_path):
    """Hostile round 2: `series report --objects` drew another store's objects table over this
    store's core points. The labels record their tables' SHA-256 (series/outputs.py)."""
    import shutil
    folder, store, _, table = series
    other = tmp_path / "other.csv"  # a well-formed table, as another store's objects run writes it
    other.write_text("object,start_epoch,end_epoch\n0,0,1\n")
    (tmp_path / "other_members.csv").write_text("object,core,dtw\n0,1,0.1\n")
    edited = tmp_path / "edited.csv"  # this store's table, edited since
    edited.write_text(table.read_text() + "\n")
    shutil.copy(folder / "objects_members.csv", tmp_path / "edited_members.csv")
    for given, why in ((other, "another store's"), (edited, "or edited since")):
        out = tmp_path / f"r_{given.stem}.html"
        err = refused(capsys, ["series", "report", str(store), "-o", str(out), "--objects", str(given)])
        assert f"--objects {given}: not the objects table written with {store}'s object labels" in err, err
        assert why in err and not out.exists()
    assert main(["series", "report", str(store), "-o", str(tmp_path / "r.html"), "--objects", str(table)]) == 0


BAD_TABLES = {
    "no columns": ("a,b\n1,2\n", None, "not a table of m3c2 series objects: no column object, start_epoch, end_epoch"),
    "not an integer": ("object,start_epoch,end_epoch\n0,x,1\n", None, "line 2: start_epoch 'x' is not an integer"),
    "epoch out of range": ("object,start_epoch,end_epoch\n0,0,99\n", None, "line 2: end_epoch 99 is outside"),
    "core out of range": ("object,start_epoch,end_epoch\n0,0,1\n", "object,core,dtw\n0,100000,0.1\n",
                          "line 2: core 100000 is outside 0..399"),
    "binary": (b"\xff\xfe\x00garbage", None, "cannot read the table"),
    "members missing": ("object,start_epoch,end_epoch\n0,0,1\n", False, "_members.csv: no such file"),
}


@pytest.mark.parametrize("case", list(BAD_TABLES))
def test_a_malformed_objects_table_is_a_clean_error(series, capsys, tmp_path, case):
    folder, store, _, _ = series
    text, members, message = BAD_TABLES[case]
    table = tmp_path / "t.csv"
    table.write_bytes(text if isinstance(text, bytes) else text.encode())
    if members is not False:
        (tmp_path / "t_members.csv").write_text(members or "object,core,dtw\n0,1,0.1\n")
    out = tmp_path / "r.html"
    out.write_text("older report")
    err = refused(capsys, ["series", "report", str(store), "-o", str(out), "--objects", str(table)], code=1)
    assert message in err and str(tmp_path) in err, err
    assert out.read_text() == "older report"


def test_a_fifo_as_the_objects_table_is_refused_without_blocking(series, capsys, tmp_path):
    folder, store, _, _ = series
    fifo = tmp_path / "t.csv"
    os.mkfifo(fifo)
    err = refused(capsys, ["series", "report", str(store), "-o", str(tmp_path / "r.html"), "--objects", str(fifo)],
                  code=1)
    assert err == f"m3c2: error: {fifo}: not a regular file\n"


# --- series import of untrusted py4dgeo archives -------------------------------------------------

REPO = Path(__file__).resolve().parents[3]
GOOD = REPO / "tests" / "data" / "py4dgeo_series" / "analysis.zip"


def good_members() -> dict:
    with zipfile.ZipFile(GOOD) as zf:
        return {name: zf.read(name) for name in zf.namelist()}


def zipped(members: dict) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return buffer.getvalue()


def npz(array) -> bytes:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, array)
    return buffer.getvalue()


def npy(array, **kw) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array, **kw)
    return buffer.getvalue()


def good_array(name: str):
    return np.load(io.BytesIO(good_members()[f"{name}.npz"]))["arr_0"]


def replaced(**changes) -> bytes:
    """The good archive with members replaced (bytes), removed (None) or added."""
    members = good_members()
    for name, data in changes.items():
        name = name.replace("__", ".")
        if data is None:
            members.pop(name, None)
        else:
            members[name] = data
    return zipped(members)


def inner(member: str, **changes) -> bytes:
    with zipfile.ZipFile(io.BytesIO(good_members()[member])) as zf:
        members = {name: zf.read(name) for name in zf.namelist()}
    for name, data in changes.items():
        members[name.replace("__", ".")] = data
    return zipped(members)


def huge_header_npy() -> bytes:
    """A .npy whose header declares 10**9 x 10**6 float64 (8 PB) over 48 bytes of data."""
    header = "{'descr': '<f8', 'fortran_order': False, 'shape': (1000000000, 1000000), }"
    header += " " * (63 - (len(header) + 10) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header.encode() + bytes(48)


def malformed() -> dict:
    good = GOOD.read_bytes()
    d = good_array("distances")
    u = good_array("uncertainties")
    inf = d.copy()
    inf[3, 2] = np.inf
    return {
        "truncated zip": (good[: len(good) // 2], "not a zip archive"),
        "not a zip": (b"PK\x05\x06 not really" * 40, "not a zip archive"),
        "no format file": (replaced(SEGMENTATION_FILE_FORMAT=None), "no SEGMENTATION_FILE_FORMAT"),
        "unknown format": (replaced(SEGMENTATION_FILE_FORMAT=b"7"), "SEGMENTATION_FILE_FORMAT: format version '7'"),
        "no core points": (replaced(corepoints__zip=None), "no corepoints.zip"),
        "no distances": (replaced(distances__npz=None), "no distances"),
        "inner zip corrupt": (replaced(corepoints__zip=b"\x00" * 300), "corepoints.zip: not a zip archive"),
        "corrupt cloud.laz": (replaced(corepoints__zip=inner("corepoints.zip", cloud__laz=b"LASF" + bytes(120))),
                              "corepoints.zip: cloud.laz: "),
        "bad json": (replaced(timestamps__json=b'[{"days": 0,'), "timestamps.json: not valid JSON"),
        "timestamps not a list": (replaced(timestamps__json=b'{"days": 1}'), "timestamps.json: expected a list"),
        "timestamps too few": (replaced(timestamps__json=b'[{"days": 1}, {"days": 2}]'),
                               "timestamps.json: 2 time deltas for 6 epochs"),
        "timestamp of the wrong type": (replaced(timestamps__json=json.dumps(["2024-01-01"] * 6).encode()),
                                        "timestamps.json: entry 0 is not a time delta"),
        "timestamp NaN": (replaced(timestamps__json=b'[{"days": NaN}' + b', {"days": 1}' * 5 + b"]"),
                          "timestamps.json: entry 0 is not a time delta"),
        "bad metadata json": (replaced(reference_epoch__zip=inner("reference_epoch.zip", metadata__json=b"{x")),
                              "reference_epoch.zip: metadata.json: not valid JSON"),
        "distances of ints": (replaced(distances__npz=npz(d.astype(np.int64))),
                              "distances: expected a float array of shape (50, 6)"),
        "distances 1-D": (replaced(distances__npz=npz(d.ravel())), "distances: expected a 2-D array"),
        "distances 3-D": (replaced(distances__npz=npz(d[..., None])), "distances: expected a 2-D array"),
        "core count mismatch": (replaced(distances__npz=npz(d[:40])), "corepoints.zip: 50 core points but distances for 40"),
        "distances infinite": (replaced(distances__npz=npz(inf)), "distances: 1 infinite values"),
        "uncertainties without fields": (replaced(uncertainties__npz=npz(u[["lodetection", "spread1"]])),
                                         "uncertainties: expected py4dgeo's records"),
        "uncertainties of another shape": (replaced(uncertainties__npz=npz(u[:, :3])),
                                           "uncertainties: expected py4dgeo's records"),
        "huge declared shape": (replaced(distances__npz=None, distances__npy=huge_header_npy()),
                                "distances.npy: its header declares a float64 array of shape (1000000000, 1000000)"),
        "pickled objects": (replaced(distances__npz=None, distances__npy=npy(np.array([[{}]], dtype=object),
                                                                             allow_pickle=True)),
                            "distances.npy: holds Python objects"),
        "smoothed of another shape": (replaced(smoothed_distances__npz=npz(d[:, :4])),
                                      "smoothed_distances: expected a float array of shape (50, 6)"),
        "npz without its array": (replaced(distances__npz=zipped({"other.npy": npy(d)})),
                                  "distances.npz: holds no arr_0.npy"),
    }


@pytest.mark.slow
@pytest.mark.parametrize("case", list(malformed()))
def test_a_malformed_archive_is_one_clean_line_and_leaves_no_store(tmp_path, capsys, case):
    """Ten malformed archives gave tracebacks and left a half store that blocked the retry."""
    data, message = malformed()[case]
    archive = tmp_path / "a.zip"
    archive.write_bytes(data)
    out = tmp_path / "st.zarr"
    err = refused(capsys, ["series", "import", str(archive), "-o", str(out)], code=1)
    assert err.startswith(f"m3c2: error: {archive}") and message in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.zip"]  # no store, no temporary
    archive.write_bytes(GOOD.read_bytes())  # the retry works
    assert main(["series", "import", str(archive), "-o", str(out)]) == 0


def test_a_zip_bomb_is_refused_before_it_is_inflated(tmp_path, capsys, monkeypatch):
    """A member declaring more than the import may hold (half the available memory) is not read."""
    monkeypatch.setenv("M3C2_AVAILABLE_MEMORY", str(4 << 20))
    archive = tmp_path / "bomb.zip"
    archive.write_bytes(replaced(timestamps__json=b" " * (64 << 20)))  # 64 MiB of spaces, deflated to ~64 KiB
    err = refused(capsys, ["series", "import", str(archive), "-o", str(tmp_path / "st.zarr")], code=1)
    assert err == (f"m3c2: error: {archive}: timestamps.json: declares 64.0 MiB uncompressed, more than the 2.0 MiB "
                   f"an import may hold (a zip bomb?)\n")


def test_a_fifo_or_missing_archive_is_refused_without_blocking(tmp_path, capsys):
    fifo = tmp_path / "a.zip"
    os.mkfifo(fifo)
    assert refused(capsys, ["series", "import", str(fifo), "-o", str(tmp_path / "s")], code=1) == \
        f"m3c2: error: {fifo}: not a regular file\n"
    assert refused(capsys, ["series", "import", str(tmp_path / "none.zip"), "-o", str(tmp_path / "s")], code=1) == \
        f"m3c2: error: {tmp_path / 'none.zip'}: no such file\n"


def test_a_failure_while_writing_leaves_no_half_store(tmp_path, capsys, monkeypatch):
    from m3c2kit.base.errors import CloudWriteError
    from m3c2kit.series import store as st
    real = st.append_batch

    def full_disk(path, index, batch):
        raise CloudWriteError(f"{path}: No space left on device")

    monkeypatch.setattr(st, "append_batch", full_disk)
    out = tmp_path / "st.zarr"
    assert main(["series", "import", str(GOOD), "-o", str(out)]) == 1
    assert "No space left on device" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
    monkeypatch.setattr(st, "append_batch", real)
    assert main(["series", "import", str(GOOD), "-o", str(out)]) == 0


@pytest.mark.slow
def test_3000_epochs_are_committed_in_chunks(tmp_path, monkeypatch):
    """One commit per epoch: 1,431 of 3,000 epochs after 90 s."""
    xr = pytest.importorskip("xarray")
    from m3c2kit.series import store as st
    rng = np.random.default_rng(3)
    n_core, n_epochs = 50, 3000
    d = rng.normal(0, 0.01, (n_core, n_epochs))
    u = np.zeros((n_core, n_epochs), dtype=good_array("uncertainties").dtype)
    u["lodetection"], u["num_samples1"], u["num_samples2"] = 0.02, 10, 12
    stamps = json.dumps([{"days": 0, "seconds": 3600 * (k + 1), "microseconds": 0} for k in range(n_epochs)])
    archive = tmp_path / "big.zip"
    archive.write_bytes(replaced(distances__npz=npz(d), uncertainties__npz=npz(u), timestamps__json=stamps.encode()))
    commits = []
    real = st.append_batch
    monkeypatch.setattr(st, "append_batch", lambda path, index, batch: (commits.append(len(batch)),
                                                                        real(path, index, batch)))
    out = tmp_path / "st.zarr"
    assert main(["series", "import", str(archive), "-o", str(out)]) == 0
    assert commits == [n_epochs]  # 3,000 epochs of 50 core points fit in one commit of whole chunks
    ds = xr.open_zarr(out)
    assert ds.sizes["epoch"] == n_epochs
    assert np.array_equal(ds["distance"].values, d)
    assert str(ds["time"].values[-1]).startswith("2024-05-05T12:00")


def test_smoothed_distances_are_imported(tmp_path):
    xr = pytest.importorskip("xarray")
    smoothed = good_array("distances") * 0.5
    archive = tmp_path / "s.zip"
    archive.write_bytes(replaced(smoothed_distances__npz=npz(smoothed)))
    out = tmp_path / "st.zarr"
    assert main(["series", "import", str(archive), "-o", str(out)]) == 0
    assert np.array_equal(xr.open_zarr(out)["smoothed_distance"].values, smoothed, equal_nan=True)


# red team (issue 31, item 3): an output inside ANY series store, not only the one the command reads


def test_a_new_store_or_import_inside_another_store_is_refused(series, capsys, tmp_path):
    """`series REF EPOCH -o STORE/new` and `import -o STORE/new` wrote a store inside an archive
    they do not read, without its lock; also through a link to the store."""
    folder, store, paths, _ = series
    (tmp_path / "link").symlink_to(store)
    archive = tmp_path / "a.zip"
    archive.write_bytes(zipped(good_members()))
    before = tree(store)
    for argv in (["series", str(paths[0]), str(paths[1]), "-o", str(store / "nested.zarr"), *PARAMS],
                 ["series", "import", str(archive), "-o", str(tmp_path / "link" / "distance" / "imported")]):
        err = refused(capsys, argv)
        assert "is inside the series store" in err and str(store) in err, err
    assert tree(store) == before
    assert main(["series", "import", str(archive), "-o", str(tmp_path / "beside.zarr")]) == 0  # outside: fine
    err = refused(capsys, ["series", "report", str(tmp_path / "beside.zarr"), "-o", str(store / "r.html")])
    assert "is inside the series store" in err and str(store) in err, err  # a store the command does not read
    assert tree(store) == before
