"""m3c2 series --error-model (issue 34): each epoch's LOD equals m3c2 compare's with the same model,
bit for bit; the store records the model's CONTENT, so `series add` computes the same LOD after the
file has moved, and refuses another model."""
import csv
import json

import numpy as np
import pytest

from m3c2kit.analysis.error_model import Component, ErrorModel, save
from m3c2kit.cli.main import main
from test_series import PARAMS, same, small  # noqa: F401 - the fixture, shared

xr = pytest.importorskip("xarray")


@pytest.mark.slow
def test_series_error_model_equals_compare_and_survives_a_moved_file(small, tmp_path, capsys):  # noqa: F811
    folder, paths = small
    model = ErrorModel(1e-5, (Component("spherical", 2e-5, 3.0),), 1.0, mean_u2=5e-6)  # excess 2.5e-5
    save(tmp_path / "model.json", model)
    store = tmp_path / "st.zarr"
    assert main(["series", str(paths[0]), *map(str, paths[1:3]), "-o", str(store), *PARAMS, "--quiet",
                 "--error-model", str(tmp_path / "model.json")]) == 0
    recorded = json.loads(xr.open_zarr(store).attrs["parameters"])["error_model"]
    assert recorded == model.to_json()  # the content, not the path
    (tmp_path / "model.json").rename(tmp_path / "moved.json")
    assert main(["series", "add", str(store), str(paths[3]), "--quiet"]) == 0
    ds = xr.open_zarr(store)
    for k, epoch in enumerate(paths[1:4]):
        out = tmp_path / f"c{k}.csv"
        assert main(["compare", str(paths[0]), str(epoch), "-o", str(out), *PARAMS, "--quiet", "--float64",
                     "--error-model", str(tmp_path / "moved.json")]) == 0
        rows = list(csv.DictReader(open(out)))
        for name in ("lod", "significant", "distance"):
            expected = np.array([float(r[name]) if r[name] not in ("", "nan") else np.nan for r in rows])
            assert same(ds[name].values[:, k].astype(np.float64), expected), (k, name)
    # the LOD is the model's: eq. (1)'s with the excess inside the square root
    assert np.nanmin(ds["lod"].values) > 1.95 * np.sqrt(2.5e-5)
    # the same model from another file is accepted; another model is refused, naming both
    assert main(["series", "add", str(store), str(paths[4]), "--quiet", "--error-model",
                 str(tmp_path / "moved.json")]) == 0
    save(tmp_path / "other.json", ErrorModel(1e-5, model.components, 1.0, mean_u2=1e-6))
    capsys.readouterr()
    assert main(["series", "add", str(store), str(paths[5]), "--error-model", str(tmp_path / "other.json")]) == 2
    assert "error_model" in capsys.readouterr().err
