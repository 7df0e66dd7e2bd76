"""M3C2-PM and M3C2-EP (issue 16) against brute-force numpy oracles written from the papers'
formulas (trigonometric Jacobian, explicit sums), plus bits across threads and bad inputs."""
from __future__ import annotations

import numpy as np
import pytest

from m3c2kit import _core
from m3c2kit.run import uncertainty_inputs as ui
from m3c2kit.base.errors import UsageError

Z95 = 1.959963984540054
CHI2_3_95 = 7.814727903251178


def surface(rng, n, z0=0.0):
    xy = rng.uniform(0, 6, (n, 2))
    return np.column_stack([xy, z0 + 0.02 * np.sin(xy[:, 0]) + rng.normal(0, 0.003, n)])


def params(kind):
    p = _core.Params()
    p.normal_source = _core.NormalSource.vertical
    p.projection_diameter = 1.0
    p.max_depth = 0.5
    p.min_points = 1
    p.uncertainty = getattr(_core.Uncertainty, kind)
    return p


def cylinder(cloud, core, n, r, L):
    v = cloud - core
    t = v @ n
    w = v - np.outer(t, n)
    return np.flatnonzero((np.abs(t) <= L) & ((w * w).sum(1) <= r * r))


CORES = np.array([[1.5, 1.5, 0.0], [3.0, 3.2, 0.0], [4.4, 2.0, 0.0]])
N = np.array([0.0, 0.0, 1.0])


# ---------------------------------------------------------------- M3C2-PM
@pytest.mark.parametrize("rule", ["nearest", "all"])
def test_pm_matches_oracle(rule):
    rng = np.random.default_rng(3)
    ref, cmp_ = surface(rng, 3000), surface(rng, 3000, 0.01)
    s1, s2 = rng.uniform(0.001, 0.02, (3000, 3)), rng.uniform(0.001, 0.02, (3000, 3))
    p = params("pm")
    p.precision_rule = getattr(_core.PrecisionRule, rule)
    p.precision_scale1, p.precision_scale2, p.registration_error = 2.0, 0.5, 0.003
    out = ui.compute(ref, cmp_, CORES, p, precision1=s1, precision2=s2)
    for k, core in enumerate(CORES):
        sig = []
        for cloud, s, scale in ((ref, s1, 2.0), (cmp_, s2, 0.5)):
            idx = cylinder(cloud, core, N, 0.5, 0.5)
            proj2 = ((s[idx] * N) ** 2).sum(1)
            if rule == "nearest":  # CloudCompare's: the point nearest the points' centre of gravity
                g = cloud[idx].mean(0)
                sig.append(scale * np.sqrt(proj2[np.argmin(((cloud[idx] - g) ** 2).sum(1))]))
            else:
                sig.append(scale * np.sqrt(proj2.mean()))
        assert out["spread1"][k] == pytest.approx(sig[0], rel=1e-12)
        assert out["spread2"][k] == pytest.approx(sig[1], rel=1e-12)
        assert out["lod"][k] == pytest.approx(Z95 * (np.hypot(*sig) + 0.003), rel=1e-12)
        assert out["status"][k] == 0


def test_pm_missing_precision_is_a_usage_error():
    rng = np.random.default_rng(1)
    ref = surface(rng, 500)
    with pytest.raises(UsageError, match="3 precisions"):
        ui.compute(ref, ref, CORES, params("pm"), precision1=np.ones((499, 3)), precision2=np.ones((500, 3)))
    with pytest.raises(UsageError, match="no precision field sz"):
        ui.precision_array({"sx": [1], "sy": [1]}, "sx,sy,sz", what="reference.las")


# ---------------------------------------------------------------- M3C2-EP
def polar_cov(p, origin, s_range, ppm, s_scan, s_yaw):
    """The paper's polar-to-Cartesian propagation with trigonometry (independent of the engine's)."""
    d = p - origin
    r = np.linalg.norm(d)
    yaw = np.arctan2(d[1], d[0])
    scan = np.arccos(d[2] / r)  # zenith angle
    J = np.array([[np.sin(scan) * np.cos(yaw), -r * np.sin(scan) * np.sin(yaw), r * np.cos(scan) * np.cos(yaw)],
                  [np.sin(scan) * np.sin(yaw), r * np.sin(scan) * np.cos(yaw), r * np.cos(scan) * np.sin(yaw)],
                  [np.cos(scan), 0.0, -r * np.sin(scan)]])
    D = np.diag([s_range**2 + (ppm * 1e-6 * r) ** 2, s_yaw**2, s_scan**2])
    return J @ D @ J.T


def ep_oracle(ref, cmp_raw, ids1, ids2, table, tfm, cxx, red, core, n, covariance, weights):
    R, t = tfm[:, :3], tfm[:, 3]
    cmp_t = (cmp_raw - red) @ R.T + t + red
    rows = {int(row[0]): row for row in table}
    out = []
    for k, (cloud, raw, ids) in enumerate(((ref, ref, ids1), (cmp_t, cmp_raw, ids2))):
        idx = cylinder(cloud, core, n, 0.5, 0.5)
        covs, ws = [], []
        for j in idx:
            row = rows[int(ids[j])]
            c = polar_cov(raw[j], row[1:4], row[4], row[5], row[6], row[7])
            if k == 1:
                c = R @ c @ R.T
            covs.append(c)
            ws.append(np.linalg.inv(c) if weights == "matrix" else np.eye(3) / (n @ c @ n))
        W = np.sum(ws, 0)
        Q = np.linalg.inv(W)
        m = Q @ np.sum([w @ (cloud[j] - core) for w, j in zip(ws, idx)], 0)
        if covariance == "mean_of_points":
            S = np.mean(covs, 0)
        elif weights == "matrix":
            S = Q
        else:  # scalar weights: sum w^2 S_i / (sum w)^2
            S = np.sum([w[0, 0] ** 2 * c for w, c in zip(ws, covs)], 0) / W[0, 0] ** 2
        if k == 1:
            Js = []
            for j in idx:
                d = raw[j] - red
                J = np.zeros((3, 12))
                for a in range(3):
                    J[a, 3 * a:3 * a + 3] = d
                    J[a, 9 + a] = 1.0
                Js.append(J)
            if covariance == "independent":
                G = Q @ np.sum([w @ J for w, J in zip(ws, Js)], 0)
                S = S + G @ cxx @ G.T
            else:
                S = S + np.mean([J @ cxx @ J.T for J in Js], 0)
        out.append((m, S))
    (m1, S1), (m2, S2) = out
    return n @ (m2 - m1), np.sqrt(n @ S1 @ n), np.sqrt(n @ S2 @ n), S1 + S2


def ep_case(seed=5):
    rng = np.random.default_rng(seed)
    ref, cmp_ = surface(rng, 2500), surface(rng, 2500, 0.005)
    table = np.array([[1, -20.0, 3.0, 8.0, 0.004, 30.0, 0.0004, 0.0002],
                      [2, 25.0, 1.0, 5.0, 0.003, 0.0, 0.0002, 0.0005]])
    ids1, ids2 = rng.integers(1, 3, 2500).astype(np.uint32), rng.integers(1, 3, 2500).astype(np.uint32)
    a = 0.002
    tfm = np.array([[np.cos(a), -np.sin(a), 0.0, 0.03], [np.sin(a), np.cos(a), 0.0, -0.02], [0.0, 0.0, 1.0, 0.01]])
    L = rng.normal(size=(12, 12)) * np.r_[np.full(9, 1e-5), np.full(3, 3e-3)]
    cxx = L @ L.T
    red = np.array([2.0, 1.0, 0.5])
    return ref, cmp_, ids1, ids2, table, tfm, cxx, red


@pytest.mark.parametrize("weights", ["normal", "matrix"])
@pytest.mark.parametrize("covariance", ["independent", "mean_of_points"])
@pytest.mark.parametrize("lod", ["projected", "published"])
def test_ep_matches_oracle(weights, covariance, lod):
    ref, cmp_, ids1, ids2, table, tfm, cxx, red = ep_case()
    p = params("ep")
    p.ep_covariance = getattr(_core.EpCovariance, covariance)
    p.ep_lod = getattr(_core.EpLod, lod)
    p.ep_weights = getattr(_core.EpWeights, weights)
    ep = ui.EpInputs(table, table, ids1, ids2, tfm, cxx, red)
    out = ui.compute(ref, cmp_, CORES, p, ep=ep, covariances=True)
    for k, core in enumerate(CORES):
        d, s1, s2, S = ep_oracle(ref, cmp_, ids1, ids2, table, tfm, cxx, red, core, N, covariance, weights)
        assert out["distance"][k] == pytest.approx(d, abs=1e-12)
        assert out["spread1"][k] == pytest.approx(s1, rel=1e-9)
        assert out["spread2"][k] == pytest.approx(s2, rel=1e-9)
        want = Z95 * np.sqrt(N @ S @ N) if lod == "projected" else np.sqrt(CHI2_3_95 / (N @ np.linalg.solve(S, N)))
        assert out["lod"][k] == pytest.approx(want, rel=1e-9)
        assert out["covariance1"][k] + out["covariance2"][k] == pytest.approx(S, rel=1e-9, abs=1e-18)
        assert out["significant"][k] == (abs(out["distance"][k]) > out["lod"][k])


def test_ep_transform_applied_gives_the_same_result():
    ref, cmp_, ids1, ids2, table, tfm, cxx, red = ep_case(7)
    p = params("ep")
    raw = ui.compute(ref, cmp_, CORES, p, ep=ui.EpInputs(table, table, ids1, ids2, tfm, cxx, red))
    moved = (cmp_ - red) @ tfm[:, :3].T + tfm[:, 3] + red
    done = ui.compute(ref, moved, CORES, p, ep=ui.EpInputs(table, table, ids1, ids2, tfm, cxx, red,
                                                             transform_applied=True))
    for key in ("distance", "lod", "spread1", "spread2"):
        np.testing.assert_allclose(done[key], raw[key], rtol=1e-9, atol=1e-12)


def test_ep_same_bits_for_any_thread_count():
    rng = np.random.default_rng(11)
    ref, cmp_, ids1, ids2, table, tfm, cxx, red = ep_case(11)
    core = np.column_stack([rng.uniform(0.5, 5.5, (600, 2)), np.zeros(600)])
    p = params("ep")
    ep = ui.EpInputs(table, table, ids1, ids2, tfm, cxx, red)
    one = ui.compute(ref, cmp_, core, p, ep=ep, threads=1)
    two = ui.compute(ref, cmp_, core, p, ep=ep, threads=2)
    for key in one:
        assert np.array_equal(one[key], two[key], equal_nan=one[key].dtype.kind == "f"), key


def test_ep_bad_inputs_are_named():
    ref, cmp_, ids1, ids2, table, tfm, cxx, red = ep_case()
    p = params("ep")
    bad = ids2.copy()
    bad[17] = 9
    with pytest.raises(UsageError, match="compared cloud: point 17 has scan position id 9"):
        ui.compute(ref, cmp_, CORES, p, ep=ui.EpInputs(table, table, ids1, bad, tfm, cxx, red))
    with pytest.raises(UsageError, match="not symmetric"):
        c = cxx.copy()
        c[0, 1] += 1
        ui.compute(ref, cmp_, CORES, p, ep=ui.EpInputs(table, table, ids1, ids2, tfm, c, red))
    p.registration_error = 0.01
    with pytest.raises(UsageError, match="registration_error must be 0"):
        ui.compute(ref, cmp_, CORES, p, ep=ui.EpInputs(table, table, ids1, ids2, tfm, cxx, red))


def test_input_files(tmp_path):
    (tmp_path / "sps.json").write_text('{"1": {"origin": [1, 2, 3], "sigma_range": 0.005, "sigma_scan": 0.0003, '
                                       '"sigma_yaw": 0.0004}, "2": {"origin": [4, 5, 6], "sigma_range": 0.004, '
                                       '"sigma_scan": 0.0001, "sigma_yaw": 0.0002, "sigma_range_ppm": 20}}')
    t = ui.load_scan_positions(tmp_path / "sps.json")
    np.testing.assert_array_equal(t[1], [2, 4, 5, 6, 0.004, 20, 0.0001, 0.0002])
    (tmp_path / "sps.csv").write_text("id,x,y,z,sigma_range,sigma_scan,sigma_yaw\n1,1,2,3,0.005,0.0003,0.0004\n")
    np.testing.assert_array_equal(ui.load_scan_positions(tmp_path / "sps.csv")[0], t[0])
    (tmp_path / "tfM.csv").write_text("1,0,0,0\n0,1,0,0\n")
    with pytest.raises(UsageError, match="expected a 3x4 matrix, got 2x4"):
        ui.load_matrix(tmp_path / "tfM.csv", (3, 4), "--transform")
    assert ui.parse_reduction_point("1,2,3").tolist() == [1, 2, 3]
    with pytest.raises(UsageError, match="--reduction-point"):
        ui.parse_reduction_point("1,2")


def test_e57_scan_index_and_poses(tmp_path):
    """E57: every point carries its scan's number (from 1) and a table without origins takes the
    scans' poses."""
    pye57 = pytest.importorskip("pye57")
    from m3c2kit.io import read_cloud
    path = tmp_path / "two.e57"
    with pye57.E57(str(path), mode="w") as out:
        for k, (n, t) in enumerate(((3, (1.0, 2.0, 3.0)), (2, (-4.0, 0.5, 1.0)))):
            xyz = np.arange(3 * n, dtype=np.float64).reshape(n, 3) + k
            out.write_scan_raw({"cartesianX": xyz[:, 0], "cartesianY": xyz[:, 1], "cartesianZ": xyz[:, 2]},
                               translation=np.array(t), rotation=np.array([1.0, 0, 0, 0]))
    cloud = read_cloud(path)
    assert cloud.fields["scan_index"].tolist() == [1, 1, 1, 2, 2]
    (tmp_path / "sps.json").write_text('{"1": {"sigma_range": 0.005, "sigma_scan": 0.0003, "sigma_yaw": 0.0004},'
                                       ' "2": {"sigma_range": 0.004, "sigma_scan": 0.0001, "sigma_yaw": 0.0002}}')
    t = ui.load_scan_positions(tmp_path / "sps.json", poses=cloud.scan_positions)
    np.testing.assert_array_equal(t[:, 1:4], [[1, 2, 3], [-4, 0.5, 1]])
    np.testing.assert_array_equal(ui.scan_position_ids(cloud.fields, "scan_index"), [1, 1, 1, 2, 2])


def test_ep_empirical_is_eq1_plus_the_propagated_alignment():
    """--ep-covariance empirical: eq. (1)'s sigma^2/n along n plus J(mean) Cxx J(mean)^T."""
    ref, cmp_, ids1, ids2, table, tfm, cxx, red = ep_case(13)
    p = params("ep")
    p.ep_covariance = _core.EpCovariance.empirical
    out = ui.compute(ref, cmp_, CORES, p, ep=ui.EpInputs(table, table, ids1, ids2, tfm, cxx, red))
    moved = (cmp_ - red) @ tfm[:, :3].T + tfm[:, 3] + red
    for k, core in enumerate(CORES):
        t1 = (ref[cylinder(ref, core, N, 0.5, 0.5)] - core) @ N
        idx2 = cylinder(moved, core, N, 0.5, 0.5)
        t2 = (moved[idx2] - core) @ N
        d = cmp_[idx2].mean(0) - red
        J = np.zeros((3, 12))
        for a in range(3):
            J[a, 3 * a:3 * a + 3] = d
            J[a, 9 + a] = 1.0
        var = t1.var(ddof=1) / len(t1) + t2.var(ddof=1) / len(t2) + N @ J @ cxx @ J.T @ N
        assert out["distance"][k] == pytest.approx(t2.mean() - t1.mean(), abs=1e-12)
        assert out["lod"][k] == pytest.approx(Z95 * np.sqrt(var), rel=1e-9)
