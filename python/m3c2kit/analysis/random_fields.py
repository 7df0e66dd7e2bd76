"""Gaussian random fields with an error model's covariance, for the simulations that check the
variogram fit and ``--error-model`` (validation/correlated_errors.py, tests).

Circulant embedding (Dietrich & Newsam 1997; Wood & Chan 1994): the covariance is laid on a
periodic grid larger than the points' bounding box by the component's reach (its range, twice
the practical range for the exponential, whose covariance is 5 % at its range), so that no two
points are closer through the wrap than directly; the FFT of that row is the spectrum, and the
FFT of white noise scaled by the square root of the spectrum is a stationary field with exactly
that covariance on the grid (a few slightly negative eigenvalues of the truncated exponential are
set to zero). The grid step is range/32 (range/64 for the exponential, whose variogram starts linearly), and
each point's bilinear interpolation is rescaled to the model's variance (interpolation between
nodes loses up to 8 % of it); the variogram is the model's at lags of a few steps and more
(tests/python/analysis/test_random_fields.py checks it from range/8). One independent field per
component; the nugget, when asked, is independent noise per point.
"""
from __future__ import annotations

import numpy as np

from ..base.errors import UsageError
from .error_model import Component, ErrorModel

__all__ = ["sample_field", "MAX_GRID_CELLS", "CELLS_PER_RANGE"]

#: grid steps per range (the spacing is range / CELLS_PER_RANGE)
CELLS_PER_RANGE = 32
#: the largest periodic grid (cells) one component may need; about 0.5 GiB of complex128 work
MAX_GRID_CELLS = 1 << 25


def _good_size(n: int) -> int:
    """The smallest 2^a 3^b 5^c >= n (fast FFT lengths)."""
    best = 1 << max(0, int(n - 1).bit_length())
    p2 = 1
    while p2 < best:
        p3 = p2
        while p3 < best:
            p5 = p3
            while p5 < best:
                if p5 >= n:
                    best = p5
                p5 *= 5
            p3 *= 3
        p2 *= 2
    return best


def _component_field(xy: np.ndarray, c: Component, rng: np.random.Generator) -> np.ndarray:
    # the exponential's linear start is smoothed by interpolation over a cell: twice as fine
    step = c.range / (CELLS_PER_RANGE * (2 if c.kind == "exponential" else 1))
    reach = c.range if c.kind == "spherical" else 2.0 * c.range
    lo = xy.min(axis=0)
    extent = xy.max(axis=0) - lo
    # cells covering the box, +1 for bilinear interpolation's upper neighbour
    cells = [float(np.ceil((e + reach) / step)) + 2 for e in extent]  # in floats: a tiny range overflowed int64
    if not cells[0] * cells[1] <= MAX_GRID_CELLS:
        raise UsageError(f"a correlated field of range {c.range:g} over a {extent[0]:g} x {extent[1]:g} box needs "
                         f"{cells[0]:.3g} x {cells[1]:.3g} grid cells, more than {MAX_GRID_CELLS}: use a smaller area "
                         "or a longer range")
    need = np.ceil(extent / step).astype(np.int64) + 2
    shape = tuple(_good_size(int(n)) for n in cells)
    # periodic distances: the minimal image along each axis
    ix = np.arange(shape[0]); ix = np.minimum(ix, shape[0] - ix) * step
    iy = np.arange(shape[1]); iy = np.minimum(iy, shape[1] - iy) * step
    row = c.covariance(np.hypot(ix[:, None], iy[None, :]))
    lam = np.fft.fft2(row).real
    np.maximum(lam, 0.0, out=lam)
    noise = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    grid = np.fft.fft2(np.sqrt(lam / (shape[0] * shape[1])) * noise).real  # Re: one field of covariance `row`
    del noise, lam
    assert need[0] <= shape[0] and need[1] <= shape[1]
    u = (xy - lo) / step
    i0 = np.floor(u).astype(np.int64)
    f = u - i0
    i, j = i0[:, 0], i0[:, 1]
    fx, fy = f[:, 0], f[:, 1]
    w = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy])
    value = w[0] * grid[i, j] + w[1] * grid[i + 1, j] + w[2] * grid[i, j + 1] + w[3] * grid[i + 1, j + 1]
    # Bilinear weights shrink the variance between nodes (to w'Cw of the cell's four corners, down
    # to 0.92 of the sill for the exponential at this step): divided back so that every point has
    # the model's variance, which keeps the variogram at lags beyond a cell on the model's.
    corners = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], dtype=np.float64) * step
    C = c.covariance(np.hypot(*(corners[:, None, :] - corners[None, :, :]).transpose(2, 0, 1)))
    shrink = np.einsum("in,ij,jn->n", w, C, w) / c.sill
    return value / np.sqrt(shrink)


def sample_field(xy: np.ndarray, model: ErrorModel, seed: int, *, include_nugget: bool = False) -> np.ndarray:
    """A zero-mean Gaussian field at the points `xy` ((n, 2) float64) with the covariance of
    `model`'s components (and iid N(0, nugget) added when `include_nugget`); the same values for
    the same seed."""
    xy = np.ascontiguousarray(xy, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise ValueError(f"xy must be (n, 2), got {xy.shape}")
    if not np.isfinite(xy).all():
        raise ValueError("xy has non-finite coordinates")
    out = np.zeros(len(xy))
    if len(xy) == 0:
        return out
    rng = np.random.default_rng(seed)
    for c in model.components:
        if c.sill > 0:
            out += _component_field(xy, c, rng)
    if include_nugget and model.nugget > 0:
        out += rng.normal(0.0, np.sqrt(model.nugget), len(xy))
    return out
