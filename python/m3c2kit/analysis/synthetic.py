"""Synthetic test surfaces: self-affine (fractional Brownian) height fields by spectral synthesis,
and the noisy planes of section 3.4 (Fig. 4)."""
from __future__ import annotations

import numpy as np


def self_affine_surface(n: int = 256, spacing: float = 0.1, hurst: float = 0.5, rms: float = 1.0,
                        seed: int = 0, directions: int = 8, ratio: float = 1.5,
                        oversampling: float = 50.0) -> np.ndarray:
    """n x n points (x, y, z), one at random in each cell of a square grid of `spacing`, with z a self-affine surface of Hurst exponent `hurst`, by
    spectral synthesis (a randomised Weierstrass-Mandelbrot sum, Ausloos & Berman 1985):

        z(x, y) = sum_m sum_j ratio^(-m hurst) cos(2 pi f_m (x cos t_mj + y sin t_mj) + p_mj),
        f_m = ratio^m / L,

    L = n spacing, `directions` components per frequency with uniformly random directions t and
    phases p (numpy PCG64 from `seed`), frequencies from 1/L up to `oversampling` times the
    points' Nyquist frequency. Its power spectrum is ~ |k|^-(2 hurst + 2), so that of a fractional
    Brownian surface, and unlike an FFT on the point grid it keeps the wavelengths below the point
    spacing, so the roughness of eq. (3) follows <sigma(D)> ~ D^hurst down to a few point spacings
    (an FFT field is too smooth there, which steepens the apparent exponent for small hurst).
    Scaled to standard deviation `rms`."""
    rng = np.random.default_rng(seed)
    length = n * spacing
    f_max = oversampling / (2 * spacing)
    octaves = int(np.ceil(np.log(f_max * length) / np.log(ratio))) + 1
    y, x = np.meshgrid(np.arange(n) * spacing, np.arange(n) * spacing)
    # One point uniformly at random in each grid cell (stratified): on an exact grid, wavelengths
    # below the spacing would alias into coherent long waves instead of point-to-point roughness.
    x = x.ravel() + rng.random(n * n) * spacing
    y = y.ravel() + rng.random(n * n) * spacing
    z = np.zeros(n * n)
    for m in range(octaves):
        f = ratio ** m / length
        theta = rng.random(directions) * 2 * np.pi
        phase = rng.random(directions) * 2 * np.pi
        amp = ratio ** (-m * hurst)
        for t, p in zip(theta, phase):
            z += amp * np.cos(2 * np.pi * f * (x * np.cos(t) + y * np.sin(t)) + p)
    z *= rms / z.std()
    return np.ascontiguousarray(np.column_stack([x, y, z]))


def noisy_plane(nx: int, ny: int, dx: float, noise: float = 1.0, z: float = 0.0, x_shift: float = 0.0,
                seed: int = 0) -> np.ndarray:
    """A horizontal grid of nx x ny points with spacing dx (section 3.4), at height z plus
    Gaussian noise of standard deviation `noise` (numpy PCG64 from `seed`), shifted by x_shift
    along x. Rows are x-major."""
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    x = i.ravel() * dx + x_shift
    y = j.ravel() * dx
    return np.ascontiguousarray(np.column_stack([x, y, z + rng.normal(0.0, noise, nx * ny)]))
