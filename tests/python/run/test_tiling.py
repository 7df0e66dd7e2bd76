"""Out-of-core tiling (python/m3c2kit/run/, docs/scaling.md): a tiled run equals the single
in-memory run bit for bit, in core-point order, and writes the same file bytes."""
from __future__ import annotations

import filecmp
from pathlib import Path

import laspy
import numpy as np
import pytest

from m3c2kit import _core, api
from m3c2kit.run import memory as tiling
from m3c2kit.settings import build_params
from m3c2kit.cli.main import main
from m3c2kit.base.errors import UsageError
from m3c2kit.io import read_cloud
from m3c2kit.io.streaming import PointSource
from m3c2kit.io.fields import FIELDS as OUTPUT_FIELDS
from m3c2kit.engine.result import COLUMNS
from m3c2kit.engine import neighbourhood_reach as halo
from m3c2kit.run.cores import streaming_subsample
from m3c2kit.run.memory import choose_tile_size, parse_memory
from m3c2kit.io.fields import TableStyle
from m3c2kit.run.tiled import TiledOptions, run_tiled
from m3c2kit.output.writing import write

REPO = Path(__file__).resolve().parents[3]
TORONTO = REPO / "data" / "toronto-ttp"
FIELDS = ("core", "distance", "lod", "significant", "n1", "n2", "sigma1", "sigma2", "i1", "i2", "normal",
          "normal_scale", "roughness", "status")

#: The M3C2 columns a LAS/LAZ output carries by default (m3c2kit.io.fields: `compact`).
LAS_COLUMNS = [c for c in COLUMNS[3:] if any(f.name == c and f.compact for f in OUTPUT_FIELDS)]


def assert_same(full, tiled) -> None:
    assert len(full) == len(tiled)
    for name in FIELDS:
        a, b = np.asarray(getattr(full, name)), np.asarray(getattr(tiled, name))
        assert a.dtype == b.dtype and a.shape == b.shape, name
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name


def tiled_equals_untiled(tmp_path, ref_path, cmp_path, *, core=None, core_normals=None, suffix=".csv",
                         tile_size, chunk_size=7_000, position="core", projected=False, **kw):
    ref, cmp_ = read_cloud(ref_path), read_cloud(cmp_path)
    full = api.compare(ref, cmp_, core, core_normals=core_normals, **kw)
    out_t, out_u = tmp_path / f"tiled{suffix}", tmp_path / f"untiled{suffix}"
    rep = run_tiled(ref_path, cmp_path, core, core_normals=core_normals, output=out_t, return_result=True,
                    style=TableStyle(position=position, projected=projected),
                    tiling=TiledOptions(tile_size=tile_size, chunk_size=chunk_size), **kw)
    assert_same(full, rep.result)
    # The reference's attributes of the core points too, matched by streaming (m3c2kit.run.attributes).
    write(out_u, full, like=ref, position=position, projected=projected)
    assert filecmp.cmp(out_t, out_u, shallow=False), "output files differ"
    assert not list(tmp_path.glob(".m3c2-tiles-*")), "work folder left behind"
    return full, rep


@pytest.fixture(scope="module")
def tilted_pair(tmp_path_factory):
    """A rough surface tilted 35 degrees about y plus a vertical wall: normals in every direction.
    Written as LAS (reference, file order shuffled) and .npy (compared)."""
    d = tmp_path_factory.mktemp("tilted")
    rng = np.random.default_rng(3)
    n = 9000
    u, v = rng.uniform(0, 30, n), rng.uniform(0, 30, n)
    w = 0.05 * np.sin(u) + rng.normal(0, 0.01, n)
    a = np.radians(35)
    ref = np.column_stack([u * np.cos(a) - w * np.sin(a), v, u * np.sin(a) + w * np.cos(a)])
    wall = np.column_stack([rng.normal(12, 0.01, 2000), rng.uniform(0, 30, 2000), rng.uniform(0, 18, 2000)])
    ref = np.round(np.concatenate([ref, wall])[rng.permutation(n + 2000)], 3)
    cmp_ = ref[rng.permutation(len(ref))] + np.array([0.1, 0.0, 0.2]) + rng.normal(0, 0.01, ref.shape)
    header = laspy.LasHeader(version="1.4", point_format=6)
    header.scales, header.offsets = np.array([0.001] * 3), np.floor(ref.min(axis=0))
    las = laspy.LasData(header)
    las.x, las.y, las.z = ref[:, 0], ref[:, 1], ref[:, 2]
    las.write(d / "ref.las")
    np.save(d / "cmp.npy", cmp_)
    return d / "ref.las", d / "cmp.npy"


@pytest.mark.slow
def test_toronto_multiscale_small_tiles(tmp_path):
    # S = 60 with a halo of ~6.3: every tile reads core points of its neighbours.
    full, rep = tiled_equals_untiled(tmp_path, TORONTO / "TTP_15.laz", TORONTO / "TTP_23.laz", tile_size=60,
                                     core_spacing=3, normal_scale="2:8:2", projection_scale=4, max_depth=6)
    assert rep.tiles > 50 and rep.halo > 6
    assert (full.status == 0).sum() > 1000


@pytest.mark.slow
def test_toronto_every_point_is_core_laz_output(tmp_path):
    tiled_equals_untiled(tmp_path, TORONTO / "TTP_15.laz", TORONTO / "TTP_23.laz", tile_size=120, suffix=".laz",
                         normal_scale=3, projection_scale=2, max_depth=4, median=True, chunk_size=30_000)


@pytest.mark.slow
def test_autzen_las_output_projected(tmp_path, shared_data):
    pair = shared_data / "pairs" / "autzen-bmx"
    tiled_equals_untiled(tmp_path, pair / "autzen-bmx-2010.las", pair / "autzen-bmx-2023.las", tile_size=8,
                         suffix=".las", normal_scale=3, projection_scale=2, max_depth=5, registration_error=0.05,
                         projected=True, position="compared-or-core", chunk_size=100)  # LAS: no NaN xyz


@pytest.mark.slow
@pytest.mark.parametrize("kw", [
    dict(orient="+z"), dict(orient="-x"), dict(orient="5,15,40"), dict(normal_source="compared"),
    dict(normal_source="mean"), dict(normal_source="vertical"), dict(normal_source="horizontal", orient="+x"),
    dict(depth_search="progressive", compat="cloudcompare"), dict(first_pass_depth=0.5, t_statistic=True),
    dict(positive_search_only=True, median=True),
])
def test_tilted_normals_all_orientations(tmp_path, tilted_pair, kw):
    ref, cmp_ = tilted_pair
    params = dict(normal_scale="1,2.5", projection_scale=1.0, max_depth=2.0, core_spacing=0.7)
    params.update(kw)
    if params.get("normal_source") == "vertical":
        params.pop("normal_scale")
    full, rep = tiled_equals_untiled(tmp_path, ref, cmp_, tile_size=7.0, **params)
    assert rep.tiles > 12 and rep.halo > 1.5
    assert np.isfinite(full.distance).mean() > 0.5


@pytest.mark.slow
def test_core_file_with_core_normals_and_txt_inputs(tmp_path, tilted_pair):
    ref, cmp_ = tilted_pair
    rng = np.random.default_rng(5)
    core = np.column_stack([rng.uniform(0, 25, 400), rng.uniform(0, 30, 400), rng.uniform(0, 18, 400)])
    normals = rng.normal(size=(400, 3))
    cmp_txt = tmp_path / "cmp.txt"
    np.savetxt(cmp_txt, np.load(cmp_), fmt="%.17g")
    tiled_equals_untiled(tmp_path, ref, cmp_txt, core=core, core_normals=normals, normal_source="core",
                         tile_size=5.0, projection_scale=1.0, max_depth=3.0)


def test_copc_box_queries_keep_file_order(shared_data):
    path = shared_data / "readers" / "pdal" / "copc" / "lone-star.copc.laz"
    src = PointSource(path)
    assert src.kind == "copc"
    whole = read_cloud(path).xyz
    lo, hi = whole.min(axis=0), whole.max(axis=0)
    box_lo = lo + (hi - lo) * np.array([0.3, 0.55, 0.0])
    box_hi = lo + (hi - lo) * np.array([0.45, 0.7, 1.0])
    got = src.query_box(box_lo, box_hi)
    inside = np.all((whole >= box_lo) & (whole <= box_hi), axis=1)
    assert 0 < len(got) < len(whole) // 10
    assert np.array_equal(got, whole[inside])


@pytest.mark.slow
def test_copc_reference(tmp_path, shared_data):
    ref = shared_data / "readers" / "laspy" / "simple.copc.laz"
    xyz = read_cloud(ref).xyz
    rng = np.random.default_rng(2)
    cmp_ = tmp_path / "cmp.npy"
    np.save(cmp_, xyz[rng.permutation(len(xyz))] + rng.normal(0, 0.3, xyz.shape))
    full, rep = tiled_equals_untiled(tmp_path, ref, cmp_, tile_size=1200, normal_scale=600, projection_scale=400,
                                     max_depth=300, chunk_size=300)
    assert rep.tiles >= 4 and (full.status == 0).any()


def test_streaming_subsample_equals_global(tilted_pair):
    ref = PointSource(tilted_pair[0])
    xyz = read_cloud(tilted_pair[0]).xyz
    for spacing in (0.3, 1.7):
        kept = _core.subsample_min_spacing(xyz, spacing)
        assert np.array_equal(streaming_subsample(ref, spacing, chunk_size=1234), xyz[kept])


def test_refuses_what_it_cannot_reproduce(tmp_path):
    ref, cmp_ = TORONTO / "TTP_15.laz", TORONTO / "TTP_23.laz"
    kw = dict(normal_scale=3, projection_scale=2, max_depth=4, tiling=TiledOptions(tile_size=50), core_spacing=5)
    with pytest.raises(UsageError, match="normal-subsample"):
        run_tiled(ref, cmp_, normal_subsample=1.0, **kw)
    with pytest.raises(UsageError, match="bootstrap"):
        run_tiled(ref, cmp_, bootstrap=10, **kw)
    assert main(["compare", str(ref), str(cmp_), "-o", str(tmp_path / "o.csv"), "--normal-scale", "3",
                 "--projection-scale", "2", "--max-depth", "4", "--tile-size", "50",
                 "--normal-subsample", "1", "--quiet"]) == 2
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.slow
def test_cli_tiled_matches_untiled_bytes(tmp_path):
    ref, cmp_ = TORONTO / "TTP_15.laz", TORONTO / "TTP_23.laz"
    common = ["--normal-scale", "4,8", "--projection-scale", "4", "--max-depth", "6", "--core-spacing", "6",
              "--quiet"]
    assert main(["compare", str(ref), str(cmp_), "-o", str(tmp_path / "u.laz"), *common]) == 0
    assert main(["compare", str(ref), str(cmp_), "-o", str(tmp_path / "t.laz"), "--tile-size", "90", *common]) == 0
    # The limit counts this process's resident memory, which depends on the tests run before.
    limit = f"{(max(tiling.BASE_BYTES, tiling.rss_bytes() + tiling.HEADROOM_BYTES) + 60 * 2**20) // 2**20}MiB"
    assert main(["compare", str(ref), str(cmp_), "-o", str(tmp_path / "m.laz"), "--memory-limit", limit,
                 *common]) == 0
    # Every mode writes the same bytes, the reference's attributes of the core points (intensity,
    # ...) included (m3c2kit.run.attributes).
    u = read_cloud(tmp_path / "u.laz")
    assert "intensity" in u.fields and u.fields["intensity"].any()
    for other in ("t.laz", "m.laz"):
        assert filecmp.cmp(tmp_path / "u.laz", tmp_path / other, shallow=False), other


def test_memory_limit_and_halo():
    assert parse_memory("2GB") == 2_000_000_000 and parse_memory("512MiB") == 512 * 2**20
    with pytest.raises(UsageError):
        parse_memory("lots")
    p = build_params(normal_scale="1,6", projection_scale=2, max_depth=3)
    assert halo(p) == max(3.0, np.hypot(1.0, 3.0))
    s_small = choose_tile_size(500 * 2**20, 5.0, 20.0, 20.0, 1.0)
    s_big = choose_tile_size(4 * 2**30, 5.0, 20.0, 20.0, 1.0)
    assert 0 < s_small < s_big
    with pytest.raises(UsageError, match="too small"):
        choose_tile_size(260 * 2**20, 50.0, 1e4, 1e4, 1e4)
