"""CANUPO classification (Brodu & Lague 2012): features against a brute-force eigen-decomposition,
a classifier trained on one synthetic scene applied to another, the classifier files (JSON and
qCANUPO .prm), labels from polygons, the command line and its errors."""
from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from canupo_scene import GROUND, VEGETATION, scene
from m3c2kit.classify import classify, features, keep_mask, read_classifier, train, write_classifier
from m3c2kit.classify.labels import labels_from_polygons, read_polygons
from m3c2kit.classify.model import BinaryClassifier, Classifier, _signed_distance
from m3c2kit.classify.train import best_split
from m3c2kit.cli.main import main
from m3c2kit.base.errors import UsageError
from m3c2kit.io import read_cloud, write_cloud_table

pytest.importorskip("sklearn")


def brute(cloud, core, diameter):
    d2 = ((cloud - core) ** 2).sum(axis=1)
    nb = cloud[d2 <= (diameter / 2) ** 2]
    c = np.cov(nb.T, bias=True)
    e = np.sort(np.clip(np.linalg.eigvalsh(c), 0, None))[::-1]
    return e / e.sum(), len(nb)


def test_features_equal_brute_force_eigenvalues_far_from_the_origin():
    rng = np.random.default_rng(3)
    cloud = np.vstack([rng.uniform(0, 3, (2000, 3)) * [1, 1, 0.05], rng.normal(1.5, 0.3, (800, 3))])
    cloud += [654321.0, 5432109.0, 120.0]
    core = cloud[::23]
    scales = [1.2, 0.5]
    f = features(cloud, scales, core)
    assert f.ok.all()
    checked = 0
    for i, c in enumerate(core):
        for k, s in enumerate(scales):
            p, n = brute(cloud, c, s)
            assert f.count[i, k] == n
            if n < 3:
                continue
            checked += 1
            np.testing.assert_allclose(f.proportions[i, k], p, atol=1e-9, rtol=0)
            a, b, cc = p[0] - p[1], 2 * (p[1] - p[2]), 3 * p[2]
            np.testing.assert_allclose(f.barycentric[i, k], [a, b, cc], atol=1e-9, rtol=0)
            np.testing.assert_allclose(f.triangle[i, k], [b + cc / 2, cc * np.sqrt(3) / 2], atol=1e-9, rtol=0)
    assert checked > 0.9 * len(core) * len(scales)
    # CANUPO's descriptor layout: x, y of each scale in the order given.
    np.testing.assert_array_equal(f.vector()[:, 2:4], f.triangle[:, 1])


@pytest.mark.slow
def test_trained_on_one_scene_classifies_another_at_97_percent_balanced_accuracy():
    a, la = scene(1, size=20)
    b, lb = scene(2, size=20, origin=(150000.0, 450000.0, 10.0))
    clf = train([(a, la.astype(str))], [0.4, 0.6, 0.8, 1.2, 1.6, 2.4, 3.2], max_per_class=20000)
    p = classify(clf, b)
    names = p.labels(clf)
    recall = [np.mean(names[lb == c] == str(c)) for c in (GROUND, VEGETATION)]
    assert np.mean(recall) >= 0.97, recall
    assert (p.index >= 0).all()
    assert np.all((p.confidence >= 0) & (p.confidence <= 1))
    # Misclassified points lie near the boundary: their confidence is lower on average.
    wrong = names != lb.astype(str)
    assert p.confidence[wrong].mean() < p.confidence[~wrong].mean()
    mask = keep_mask(clf, b, ["2"])
    np.testing.assert_array_equal(mask, names == "2")
    with pytest.raises(UsageError, match="not a class"):
        keep_mask(clf, b, ["tree"])


def test_best_split_maximises_balanced_accuracy():
    s = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    positive = np.array([False, False, True, False, True, True])
    ba, t = best_split(s, positive)
    # Thresholds: 1.5 -> (3/3 + 2/3) / 2 = 0.833; 3.5 -> (2/3 + 3/3) / 2 = 0.833: the first kept.
    assert ba == pytest.approx(5 / 6) and t == 1.5


def test_signed_distance_to_a_polyline_with_half_line_ends():
    roof = np.array([[-1.0, -1.0], [0.0, 0.0], [1.0, -1.0]])  # a "^", extended to half-lines
    below = np.array([0.0, -5.0])
    q = np.array([[0.0, -0.5], [0.0, 1.0], [3.0, -3.0], [-3.0, -2.0], [10.0, -10.5]])
    d = _signed_distance(q, roof, below)
    r = np.sqrt(0.5)
    # Analytic: (0, -0.5) lies 0.5 / sqrt(2) below both arms; (0, 1) is 1 above the apex; (3, -3) is on
    # the right arm's extension; (-3, -2) is 1 / sqrt(2) above the left arm's line y = x;
    # (10, -10.5) 0.5 / sqrt(2) below the right one's y = -x.
    expected = [0.5 * r, -1.0, 0.0, -r, 0.5 * r]
    np.testing.assert_allclose(np.abs(d), np.abs(expected), atol=1e-12)
    assert d[0] > 0 and d[1] < 0 and d[3] < 0 and d[4] > 0


def small_classifier():
    a, la = scene(5, size=12)
    return train([(a[la == GROUND], "2"), (a[la == VEGETATION], "3")], [0.5, 1.0, 2.0], max_per_class=5000), a


def test_json_and_prm_files_round_trip(tmp_path):
    clf, pts = small_classifier()
    p0 = classify(clf, pts)
    write_classifier(tmp_path / "c.json", clf)
    back = read_classifier(tmp_path / "c.json")
    np.testing.assert_array_equal(classify(back, pts).index, p0.index)
    np.testing.assert_array_equal(classify(back, pts).confidence, p0.confidence)
    write_classifier(tmp_path / "c.prm", clf)
    prm = read_classifier(tmp_path / "c.prm")
    assert prm.source_format == "prm" and prm.labels == ["2", "3"]
    np.testing.assert_array_equal(prm.scales, np.float32(clf.scales))
    b, q = clf.binaries[0], prm.binaries[0]
    np.testing.assert_array_equal(q.w1, np.float32(b.w1))
    np.testing.assert_array_equal(q.path, np.float32(b.path))
    pp = classify(prm, pts)
    assert np.mean(pp.index == p0.index) > 0.999  # float32 weights move only points on the boundary
    with pytest.raises(Exception, match="integer classes"):
        named = Classifier(clf.scales, [BinaryClassifier("ground", "veg", b.w1, b.w2, b.path, b.ref_pos,
                                                         b.ref_neg)], ["ground", "veg"])
        write_classifier(tmp_path / "n.prm", named)


def test_prm_written_by_hand_in_qcanupo_layout_is_read(tmp_path):
    # A file as qCANUPO writes it with the "new" header (9999, descriptor 1, 2 values per scale),
    # two scales, one classifier whose boundary is the polyline (0,-1) (0,0) (1,1).
    w1 = [1.0, 0.0, 0.0, 0.0, 0.0]  # X = x of the first scale
    w2 = [0.0, 0.0, 1.0, 0.0, 0.5]  # Y = x of the second scale + 0.5
    data = struct.pack("<IIII", 9999, 1, 2, 2) + struct.pack("<2f", 2.0, 1.0) + struct.pack("<I", 1)
    data += struct.pack("<ii", 7, 9) + struct.pack("<5f", *w1) + struct.pack("<5f", *w2)
    data += struct.pack("<I", 3) + struct.pack("<6f", 0, -1, 0, 0, 1, 1)
    data += struct.pack("<4f", 1, -1, -1, 1) + struct.pack("<2f", 1.0, 1.0)
    (tmp_path / "h.prm").write_bytes(data)
    clf = read_classifier(tmp_path / "h.prm")
    assert clf.labels == ["7", "9"] and list(clf.scales) == [2.0, 1.0]
    b = clf.binaries[0]
    vec = np.array([[0.5, 0.0, -2.5, 0.0],    # plane (0.5, -2): 0.5 right of the vertical half-line
                    [-0.25, 0.0, -3.5, 0.0],  # (-0.25, -3): 0.25 left of it
                    [0.2, 0.0, 0.5, 0.0]])    # (0.2, 1): 0.8 / sqrt(2) above the y = x half-line
    plane = b.project(vec)
    np.testing.assert_allclose(plane, [[0.5, -2.0], [-0.25, -3.0], [0.2, 1.0]])
    d = b.signed_distance(plane)  # positive on refPointPos's side (1, -1): class 9
    np.testing.assert_allclose(d, [0.5, -0.25, -0.8 / np.sqrt(2)], atol=1e-7)
    (tmp_path / "t.prm").write_bytes(data[:-3])
    with pytest.raises(Exception, match="truncated"):
        read_classifier(tmp_path / "t.prm")
    (tmp_path / "x.prm").write_bytes(struct.pack("<IIII", 9999, 2, 3, 1) + data[16:])
    with pytest.raises(Exception, match="only the dimensionality descriptor"):
        read_classifier(tmp_path / "x.prm")


def test_polygons_label_points_in_xy_with_holes(tmp_path):
    gj = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"label": "veg"},
         "geometry": {"type": "Polygon", "coordinates": [[[0, 0], [4, 0], [4, 4], [0, 4], [0, 0]],
                                                         [[1, 1], [2, 1], [2, 2], [1, 2], [1, 1]]]}},
        {"type": "Feature", "properties": {"label": 2},
         "geometry": {"type": "MultiPolygon", "coordinates": [[[[10, 0], [12, 0], [11, 3]]]]}}]}
    (tmp_path / "p.geojson").write_text(json.dumps(gj))
    polys = read_polygons(tmp_path / "p.geojson", "label")
    xyz = np.array([[0.5, 0.5, 9], [1.5, 1.5, 0], [3.9, 3.9, 0], [5, 5, 0], [11, 1, 0], [10.2, 2, 0]], float)
    assert labels_from_polygons(xyz, polys, "s").tolist() == ["veg", "", "veg", "", "2", ""]
    with pytest.raises(UsageError, match="no 'class' property"):
        read_polygons(tmp_path / "p.geojson", "class")


def test_command_line_train_and_apply(tmp_path, capsys):
    a, la = scene(7, size=12)
    b, lb = scene(8, size=12)
    write_cloud_table(tmp_path / "ground.laz", a[la == GROUND], {})
    write_cloud_table(tmp_path / "veg.ply", a[la == VEGETATION], {})
    write_cloud_table(tmp_path / "scene.laz", b, {"classification": np.ones(len(b), np.uint8)})
    clf = tmp_path / "c.json"
    assert main(["classify", "train", f"{tmp_path / 'ground.laz'}=ground", f"{tmp_path / 'veg.ply'}=vegetation",
                 "-o", str(clf), "--scales", "0.5:2:0.5", "--plot", str(tmp_path / "c.png")]) == 0
    err = capsys.readouterr().err
    assert "training balanced accuracy" in err and "2, 1.5, 1, 0.5" in err
    assert (tmp_path / "c.png").stat().st_size > 1000
    out = tmp_path / "out.laz"
    assert main(["classify", "apply", str(tmp_path / "scene.laz"), "--classifier", str(clf), "-o", str(out)]) == 2
    assert "--class-map" in capsys.readouterr().err and not out.exists()
    assert main(["classify", "apply", str(tmp_path / "scene.laz"), "--classifier", str(clf), "-o", str(out),
                 "--class-map", "ground=2,vegetation=5"]) == 0
    got = read_cloud(out)
    code = got.fields["classification"]
    assert set(np.unique(code)) <= {2, 5}
    ba = 0.5 * (np.mean(code[lb == GROUND] == 2) + np.mean(code[lb == VEGETATION] == 5))
    assert ba > 0.95
    assert np.all((got.fields["confidence"] >= 0) & (got.fields["confidence"] <= 1))


@pytest.mark.parametrize("failure", ["no folder", "drawing fails"])
def test_train_writes_no_classifier_when_its_plot_fails(failure, tmp_path, capsys, monkeypatch):
    """Issue 42: `classify train` wrote its classifier, then failed on --plot: both or neither."""
    a, la = scene(7, size=8)
    write_cloud_table(tmp_path / "ground.laz", a[la == GROUND], {})
    write_cloud_table(tmp_path / "veg.ply", a[la == VEGETATION], {})
    plot = tmp_path / "missing" / "c.png" if failure == "no folder" else tmp_path / "c.png"
    if failure == "drawing fails":
        import matplotlib.figure

        def broken(*args, **kwargs):
            raise OSError(28, "No space left on device")

        monkeypatch.setattr(matplotlib.figure.Figure, "savefig", broken)
    clf = tmp_path / "c.json"
    code = main(["classify", "train", f"{tmp_path / 'ground.laz'}=ground", f"{tmp_path / 'veg.ply'}=vegetation",
                 "-o", str(clf), "--scales", "0.5:2:0.5", "--plot", str(plot)])
    assert code == 1 and "Traceback" not in capsys.readouterr().err
    assert not clf.exists() and not plot.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ground.laz", "veg.ply"]  # no private folder left


def test_command_line_errors(tmp_path, capsys, monkeypatch):
    a, la = scene(9, size=8)
    write_cloud_table(tmp_path / "s.laz", a, {"classification": la})
    s = str(tmp_path / "s.laz")
    assert main(["classify", "train", s, "-o", str(tmp_path / "c.json")]) == 2
    assert "has no label" in capsys.readouterr().err
    assert main(["classify", "train", s, "--label-field", "species", "-o", str(tmp_path / "c.json")]) == 2
    assert "no field 'species'" in capsys.readouterr().err
    assert main(["classify", "train", f"{s}=only", "-o", str(tmp_path / "c.json"), "--scales", "1"]) == 2
    assert "at least two classes" in capsys.readouterr().err
    monkeypatch.setitem(__import__("sys").modules, "sklearn.discriminant_analysis", None)
    assert main(["classify", "train", s, "--label-field", "classification", "-o", str(tmp_path / "c.json"),
                 "--scales", "1,2"]) == 2
    assert "[classify]" in capsys.readouterr().err
    assert not (tmp_path / "c.json").exists()
    (tmp_path / "bad.json").write_text("{}")
    assert main(["classify", "apply", s, "--classifier", str(tmp_path / "bad.json"), "-o", str(tmp_path / "o.laz")]) == 1
    assert "not an m3c2kit classifier" in capsys.readouterr().err


@pytest.mark.slow
def test_compare_keeps_the_ground_of_both_clouds(tmp_path, capsys):
    # Epoch 2: the same ground raised by 0.10 m, and other shrubs and trees. Without the filter the
    # vegetation is measured as change (the paper's Fig. 1a); with it every distance is the 0.10 m.
    import m3c2kit
    a, la = scene(11, size=12)
    b, lb = scene(11, size=12)
    veg2, _ = scene(12, size=12)
    ground1 = a[la == GROUND]
    epoch2 = np.vstack([b[lb == GROUND] + [0, 0, 0.10], veg2[len(ground1):]])
    clf, _ = small_classifier()
    write_classifier(tmp_path / "c.json", clf)
    core = ground1[::40]
    kept = m3c2kit.compare(a, epoch2, core, normal_scale=1.0, projection_scale=0.5, max_depth=1.0,
                           classifier=str(tmp_path / "c.json"), keep="2")
    ok = np.isfinite(kept.distance)
    assert ok.mean() > 0.9
    assert np.abs(np.median(kept.distance[ok]) - 0.10) < 0.01
    with pytest.raises(UsageError, match="go together"):
        m3c2kit.compare(a, epoch2, core, normal_scale=1.0, projection_scale=0.5, max_depth=1.0, keep="2")
    write_cloud_table(tmp_path / "e1.laz", a, {})
    write_cloud_table(tmp_path / "e2.laz", epoch2, {})
    # The same run tiled (tests/python/run/test_run_modes.py checks every mode bit for bit).
    assert main(["compare", str(tmp_path / "e1.laz"), str(tmp_path / "e2.laz"), "-o", str(tmp_path / "d.laz"),
                 "--normal-scale", "1", "--projection-scale", "0.5", "--max-depth", "1", "--quiet",
                 "--classifier", str(tmp_path / "c.json"), "--keep", "3,2", "--tile-size", "5"]) == 0
