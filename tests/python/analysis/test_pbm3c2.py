"""m3c2kit.pbm3c2 (PB-M3C2, Zahs et al. 2022) against a known truth: seeded facets moved along their
normals by known amounts, with the facet ids given as segments and with our region growing; the
random forest on labelled pairs; a reference facet without a compared one; per_point(); the same
bits for any thread count; and the caller's mistakes (UsageError). validation/pbm3c2_truth.py
runs the large scenes and the LOD's coverage."""
from __future__ import annotations

import math

import numpy as np
import pytest

import m3c2kit
from m3c2kit.analysis.pbm3c2 import CORRESPONDENCES, PBM3C2Options, STATUS
from m3c2kit.base.errors import UsageError

#: 2 x 3 facets 1.5 m square, 3 m apart, tilted up to 25 deg from the vertical (normals oriented
#: up: the distances have the moves' signs), 3 mm noise, 400 points per m^2 in both epochs.
MOVES = np.array([0.0, 0.02, -0.05, 0.0, 0.08, -0.01])
SIZE, SPACING, DENSITY, NOISE = 1.5, 3.0, 400, 0.003
IDS = 100 + 10 * np.arange(len(MOVES))  # given ids, not 0..5: they must come back as given
#: The geometric pairing rules (not the forest): every test of the pairs runs each.
RULES = [c for c in CORRESPONDENCES if c != "forest"]


def _status(words: str) -> int:
    """The STATUS code whose text holds `words` (the codes are the API's, not copied here)."""
    (code,) = [k for k, text in STATUS.items() if words in text]
    return code


def _frame(n):
    a = np.cross([1.0, 0.0, 0.0], n)
    a /= np.linalg.norm(a)
    return a, np.cross(n, a)


def _facets(seed=5, absent=()):
    """(ref, cmp, ref ids, cmp ids, normals); facets in `absent` have no compared points."""
    rng = np.random.default_rng(seed)
    clouds = {"ref": [], "cmp": [], "ref_ids": [], "cmp_ids": []}
    normals = []
    for k, move in enumerate(MOVES):
        tilt, azimuth = math.radians(rng.uniform(0, 25)), rng.uniform(0, 2 * math.pi)
        n = np.array([math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), math.cos(tilt)])
        a, b = _frame(n)
        centre = np.array([SPACING * (k % 3), SPACING * (k // 3), rng.uniform(-0.2, 0.2)])
        for name, shift in (("ref", 0.0), ("cmp", move)):
            if name == "cmp" and k in absent:
                continue
            count = int(DENSITY * SIZE * SIZE)
            u, v = rng.uniform(-SIZE / 2, SIZE / 2, (2, count))
            xyz = centre + (shift + rng.normal(0, NOISE, count))[:, None] * n + u[:, None] * a + v[:, None] * b
            clouds[name].append(xyz)
            clouds[f"{name}_ids"].append(np.full(count, IDS[k]))
        normals.append(n)
    return (np.vstack(clouds["ref"]), np.vstack(clouds["cmp"]), np.concatenate(clouds["ref_ids"]),
            np.concatenate(clouds["cmp_ids"]), np.array(normals))


@pytest.fixture(scope="module")
def scene():
    return _facets()


@pytest.fixture(scope="module")
def given(scene):
    ref, cmp_, ref_ids, cmp_ids, _ = scene
    return m3c2kit.pbm3c2(ref, cmp_, reference_segments=ref_ids, compared_segments=cmp_ids)


def _training():
    """Every true pair (1) and each facet with its neighbour in the row (0)."""
    true = [(i, i, 1) for i in IDS]
    false = [(IDS[k], IDS[k + 1], 0) for k in (0, 1, 3, 4)] + [(IDS[k + 1], IDS[k], 0) for k in (0, 1, 3, 4)]
    return np.array(true + false)


def test_the_default_rule_is_geometric(given):
    assert PBM3C2Options().correspondence in RULES and given.details["correspondence"] in RULES


@pytest.mark.parametrize("rule", RULES)
def test_every_geometric_rule_pairs_the_facets(scene, given, rule):
    ref, cmp_, ref_ids, cmp_ids, _ = scene
    r = m3c2kit.pbm3c2(ref, cmp_, reference_segments=ref_ids, compared_segments=cmp_ids, correspondence=rule)
    np.testing.assert_array_equal(r.pairs["compared_segment"], IDS)
    # The pairs decide nothing else: the same distances and LODs, bit for bit.
    np.testing.assert_array_equal(r.pairs["distance"], given.pairs["distance"])
    np.testing.assert_array_equal(r.pairs["lod"], given.pairs["lod"])


def test_given_segments_recover_the_moves(given):
    p = given.pairs
    np.testing.assert_array_equal(p["reference_segment"], IDS)
    np.testing.assert_array_equal(p["compared_segment"], IDS)
    assert (p["status"] == 0).all()
    # 900 points a facet at 3 mm: the centres' standard error is 0.1 mm, the LOD about 0.3 mm.
    np.testing.assert_allclose(p["distance"], MOVES, atol=1e-3)
    assert (np.abs(p["distance"] - MOVES) <= p["lod"]).sum() >= 5
    assert (p["lod"] < 1e-3).all() and (p["lod"] > 1e-4).all()
    np.testing.assert_array_equal(p["significant"].astype(bool), MOVES != 0)
    np.testing.assert_array_equal(p["n1"], np.full(6, int(DENSITY * SIZE * SIZE)))
    np.testing.assert_array_equal(p["n2"], p["n1"])
    np.testing.assert_allclose(p["roughness1"], NOISE, rtol=0.15)
    assert (p["nz"] > 0).all() and (p["normal_angle"] < 1.0).all()
    assert given.details["segmented_by"] == "given" and given.details["paired"] == 6


def test_the_columns_of_a_row_are_its_segments(scene, given):
    ref, cmp_, ref_ids, _, normals = scene
    p = given.pairs
    assert list(p) == ["x", "y", "z", "nx", "ny", "nz", "distance", "lod", "significant", "n1", "n2",
                       "reference_segment", "compared_segment", "roughness1", "roughness2", "normal_angle", "status",
                       "plane_misfit"]
    # True planes: the compared plane lies on its own points under the reference segment.
    assert (np.abs(p["plane_misfit"]) < 3 * p["roughness2"] / np.sqrt(p["n2"]) + p["lod"]).all()
    for k, i in enumerate(IDS):
        np.testing.assert_allclose([p["x"][k], p["y"][k], p["z"][k]], ref[ref_ids == i].mean(axis=0), atol=1e-12)
    n = np.column_stack([p["nx"], p["ny"], p["nz"]])
    assert (np.einsum("ij,ij->i", n, normals) > 0.9999).all()


@pytest.mark.parametrize("rule", RULES)
def test_grown_segments_pair_the_same_facets(scene, given, rule):
    ref, cmp_, ref_ids, cmp_ids, _ = scene
    grown = m3c2kit.pbm3c2(ref, cmp_, normal_scale=0.3, correspondence=rule)
    assert grown.details["segmented_by"] == "region growing"
    p = grown.pairs
    # Each grown segment's facet: the given id of most of its points.
    facet_of = {}
    for labels, ids, side in ((grown.reference_labels, ref_ids, "r"), (grown.compared_labels, cmp_ids, "c")):
        for s in np.unique(labels[labels >= 0]):
            on = ids[labels == s]
            assert np.mean(on == np.bincount(on).argmax()) > 0.99  # no segment spans two facets
            facet_of[side, int(s)] = int(np.bincount(on).argmax())
    assert len(p["reference_segment"]) == 6 and (p["status"] == 0).all()
    facets = [facet_of["r", int(s)] for s in p["reference_segment"]]
    assert sorted(facets) == sorted(IDS)
    assert [facet_of["c", int(s)] for s in p["compared_segment"]] == facets
    order = [facets.index(i) for i in IDS]
    np.testing.assert_allclose(p["distance"][order], MOVES, atol=1e-3)
    # The same planes less a few edge points: within the LOD of the given segments' distances.
    assert (np.abs(p["distance"][order] - given.pairs["distance"]) < given.pairs["lod"]).all()
    assert np.mean(grown.reference_labels >= 0) > 0.95


def test_forest_pairs_from_training(scene, given):
    pytest.importorskip("sklearn")
    ref, cmp_, ref_ids, cmp_ids, _ = scene
    r = m3c2kit.pbm3c2(ref, cmp_, reference_segments=ref_ids, compared_segments=cmp_ids, correspondence="forest",
                       training=_training(), search_radius=4.0)
    p = r.pairs
    np.testing.assert_array_equal(p["compared_segment"], IDS)
    assert (p["status"] == 0).all() and (p["probability"] >= 0.5).all()
    # The pairs decide nothing else: the distances are the geometric rule's, bit for bit.
    np.testing.assert_array_equal(p["distance"], given.pairs["distance"])
    np.testing.assert_array_equal(p["lod"], given.pairs["lod"])
    assert r.details["correspondence"] == "forest"


def test_forest_rejects_a_pair_of_different_surfaces():
    """A reference facet whose compared facet is absent: its only candidate within the search
    radius is a neighbour, which the forest scores below 1/2 (unpaired, NaN), where py4dgeo's
    argmax would measure it."""
    pytest.importorskip("sklearn")
    ref, cmp_, ref_ids, cmp_ids, _ = _facets(absent=(2,))
    training = np.array([row for row in _training() if row[1] != IDS[2]])
    r = m3c2kit.pbm3c2(ref, cmp_, reference_segments=ref_ids, compared_segments=cmp_ids, correspondence="forest",
                       training=training, search_radius=3.5)
    p = r.pairs
    assert p["status"][2] == _status("the classifier accepted no candidate")
    assert p["compared_segment"][2] == -1 and math.isnan(p["distance"][2])
    assert p["probability"][2] < 0.5
    assert (np.delete(p["status"], 2) == 0).all()


@pytest.mark.parametrize("rule", RULES)
def test_unpaired_reference_segment_has_nan_and_its_status(rule):
    ref, cmp_, ref_ids, cmp_ids, _ = _facets(absent=(4,))
    r = m3c2kit.pbm3c2(ref, cmp_, reference_segments=ref_ids, compared_segments=cmp_ids, correspondence=rule)
    p = r.pairs
    assert p["status"][4] == _status("no candidate within")
    assert p["compared_segment"][4] == -1 and p["n2"][4] == 0 and p["significant"][4] == 0
    for name in ("distance", "lod", "roughness2", "normal_angle"):
        assert math.isnan(p[name][4]), name
    assert (np.delete(p["status"], 4) == 0).all() and r.details["paired"] == 5
    np.testing.assert_allclose(np.delete(p["distance"], 4), np.delete(MOVES, 4), atol=1e-3)


@pytest.mark.parametrize("rule", RULES)
def test_a_step_grown_into_one_compared_segment_is_refused_and_a_half_seen_plane_is_not(rule):
    """The plane misfit (docs/pbm3c2.md): a compared segment that joins a facet moved 1 cm to a level
    0.5 m higher beside it is no plane over the reference facet (status 5, no distance); a compared
    facet seen over half the reference one is its true plane, measured."""
    rng = np.random.default_rng(11)

    def level(x0, z, count, width=2.0):
        return np.column_stack([rng.uniform(x0, x0 + width, count), rng.uniform(-1, 1, count),
                                z + rng.normal(0, NOISE, count)])

    ref = np.vstack([level(-2, 0.0, 2000), level(3, 0.0, 2000)])
    cmp_ = np.vstack([level(-2, 0.01, 2000), level(0, 0.5, 2000), level(4, 0.02, 1000, width=1.0)])
    ref_ids, cmp_ids = np.repeat([1, 2], 2000), np.repeat([1, 2], [4000, 1000])
    r = m3c2kit.pbm3c2(ref, cmp_, reference_segments=ref_ids, compared_segments=cmp_ids, correspondence=rule,
                       search_radius=2.0)
    p = r.pairs
    np.testing.assert_array_equal(p["compared_segment"], [1, 2])
    assert p["status"][0] == _status("off its own points") and r.details["paired"] == 1
    assert math.isnan(p["distance"][0]) and math.isnan(p["lod"][0]) and p["significant"][0] == 0
    assert abs(p["plane_misfit"][0]) > 0.04
    assert p["status"][1] == 0 and abs(p["distance"][1] - 0.02) < 1e-3
    assert abs(p["plane_misfit"][1]) < 1e-9  # every compared point is over the reference facet


@pytest.mark.parametrize("rule", RULES)
def test_mutual_keeps_only_the_nearer_of_two_reference_segments(rule):
    """Two reference facets, one compared facet on the first (moved 0.1 m along it): without mutual
    both are paired with it; with mutual the second is not (status 3)."""
    rng = np.random.default_rng(9)
    grid = rng.uniform(-0.5, 0.5, (400, 2))
    plane = np.column_stack([grid, rng.normal(0, 0.002, 400)])
    ref = np.vstack([plane, plane + [0.9, 0, 0]])
    cmp_ = plane + [0.1, 0, 0.01]
    ids = np.repeat([1, 2], 400)
    both = dict(reference_segments=ids, compared_segments=np.full(400, 7), search_radius=2.0, correspondence=rule)
    p = m3c2kit.pbm3c2(ref, cmp_, **both).pairs
    np.testing.assert_array_equal(p["compared_segment"], [7, 7])
    p = m3c2kit.pbm3c2(ref, cmp_, mutual=True, **both).pairs
    np.testing.assert_array_equal(p["compared_segment"], [7, -1])
    np.testing.assert_array_equal(p["status"], [0, _status("not mutual")])
    assert abs(p["distance"][0] - 0.01) < 1e-3 and math.isnan(p["distance"][1])


def test_per_point_columns(scene, given):
    ref, cmp_, ref_ids, cmp_ids, _ = scene
    ids = ref_ids.copy()
    ids[:10] = -1  # in no segment
    r = m3c2kit.pbm3c2(ref, cmp_, reference_segments=ids, compared_segments=cmp_ids)
    pp = r.per_point()
    assert list(pp) == ["segment", "distance", "lod", "significant", "status"]
    assert all(len(column) == len(ref) for column in pp.values())
    np.testing.assert_array_equal(pp["segment"], ids)
    assert np.isnan(pp["distance"][:10]).all() and np.isnan(pp["lod"][:10]).all()
    assert (pp["status"][:10] == _status("a negative segment id")).all()
    assert (pp["significant"][:10] == 0).all()
    row = {int(s): k for k, s in enumerate(r.pairs["reference_segment"])}
    rows = np.array([row[int(s)] for s in ids[10:]])
    for name in ("distance", "lod", "significant", "status"):
        np.testing.assert_array_equal(pp[name][10:], r.pairs[name][rows], err_msg=name)


def test_threads_give_the_same_bits(scene):
    ref, cmp_, *_ = scene
    one, four = (m3c2kit.pbm3c2(ref, cmp_, normal_scale=0.3, threads=t) for t in (1, 4))
    np.testing.assert_array_equal(one.reference_labels, four.reference_labels)
    np.testing.assert_array_equal(one.compared_labels, four.compared_labels)
    assert list(one.pairs) == list(four.pairs)
    for name in one.pairs:
        a, b = one.pairs[name], four.pairs[name]
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name


@pytest.mark.parametrize("call, message", [
    (dict(correspondence="forest"), "give training"),
    (dict(training=[[100, 100, 1], [100, 110, 0]]), "need correspondence='forest'"),
    (dict(reference_segments="ids"), "both clouds or of neither"),
    (dict(compared_segments="ids"), "both clouds or of neither"),
    (dict(reference_segments="half", compared_segments="ids"), "must be integers"),
    (dict(reference_segments="ids", compared_segments="ids", normal_scale=0.3), "normal_scale would change nothing"),
    (dict(reference_segments="ids", compared_segments="ids", correspondence="forest",
          training=[[100, 100, 1], [100, 999, 0]]), "the compared cloud has no segment 999"),
    (dict(reference_segments="ids", compared_segments="ids", correspondence="forest",
          training=[[5, 100, 1], [100, 110, 0]]), "the reference cloud has no segment 5"),
    (dict(correspondence="closest"), "correspondence must be one of"),
    (dict(search_radius=-1.0), "search_radius must be a positive number"),
    (dict(reference_segments="short", compared_segments="ids"), "one segment id per point"),
])
def test_usage_errors(scene, call, message):
    ref, cmp_, ref_ids, cmp_ids, _ = scene
    values = {"ids": ref_ids, "half": ref_ids + 0.5, "short": ref_ids[:-1]}
    kwargs = {k: values.get(v, v) if isinstance(v, str) and k.endswith("segments") else v for k, v in call.items()}
    if "compared_segments" in kwargs and kwargs["compared_segments"] is ref_ids:
        kwargs["compared_segments"] = cmp_ids
    with pytest.raises(UsageError, match=message):
        m3c2kit.pbm3c2(ref, cmp_, **kwargs)


def test_integral_float_ids_are_accepted(scene, given):
    ref, cmp_, ref_ids, cmp_ids, _ = scene
    r = m3c2kit.pbm3c2(ref, cmp_, reference_segments=ref_ids.astype(float), compared_segments=cmp_ids.astype(float))
    np.testing.assert_array_equal(r.pairs["distance"], given.pairs["distance"])


def test_a_training_file_names_its_lines(tmp_path):
    """py4dgeo's correspondences file: comments, a header after them, and a refused pair named by its
    file and line (helper's finding: 'training row 2' of a file with a header was its line 3)."""
    from m3c2kit.analysis.pbm3c2_forest import read_training
    path = tmp_path / "pairs.csv"
    path.write_text("# labelled by hand\nref,cmp,label\n0,0,1\n\n0;1;0\n")
    rows = read_training(path)
    assert rows.tolist() == [[0, 0, 1], [0, 1, 0]] and rows.where == [f"{path}, line 3", f"{path}, line 5"]
    path.write_text("0,0,1\nref,cmp,label\n")
    with pytest.raises(UsageError, match=r"pairs.csv, line 2: expected 'reference id, compared id, 1 or 0'"):
        read_training(path)
