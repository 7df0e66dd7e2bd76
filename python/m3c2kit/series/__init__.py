"""M3C2 time series (docs/series.md): one reference, many epochs, a Zarr store of core points x
epochs, and its analysis (temporal median, change points, 4D objects-by-change).

Needs the optional extra ``m3c2kit[series]`` (xarray and zarr); every entry point says so when it
is missing (m3c2kit.series.store.require_extra)."""
