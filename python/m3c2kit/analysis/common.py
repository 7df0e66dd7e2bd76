"""Helpers shared by the analysis commands: scale lists, log-log fits, tables, CSV, sampling."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .. import engine
from ..base.errors import UsageError
from ..io.atomic import atomic_output
from ..io.text_cells import spreadsheet_safe
from ..base.optional import require
from ..settings.parsers import normal_scales, positive


def scales(name: str, spec) -> np.ndarray:
    """Diameters from 'MIN:MAX:STEP' (MAX included), 'a,b,c', a number or a sequence."""
    return np.array(normal_scales(spec, name), dtype=float)


def value_range(name: str, spec) -> tuple[float, float] | None:
    """'MIN:MAX' -> (MIN, MAX), or None."""
    if spec is None:
        return None
    if isinstance(spec, str):
        parts = spec.split(":")
        if len(parts) != 2:
            raise UsageError(f"{name} must be MIN:MAX, got {spec!r}")
        lo, hi = (positive(name, p) for p in parts)
    else:
        lo, hi = (positive(name, p) for p in spec)
    if hi < lo:
        raise UsageError(f"{name}: MAX ({hi}) is below MIN ({lo})")
    return lo, hi


def loglog_fit(x, y, l0: float = 1.0) -> dict:
    """Least-squares line log(y) = log(a) + b log(x / l0) (natural logs) over the finite,
    positive pairs: b with its standard error (from the residuals, n - 2 degrees of freedom),
    a = y at x = l0 (its multiplicative standard error exp(se of log a) as `a_factor`), R^2 and n."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    n = int(ok.sum())
    out = {"slope": math.nan, "slope_se": math.nan, "a": math.nan, "a_factor": math.nan, "r2": math.nan, "n": n}
    if n < 2:
        return out
    u, v = np.log(x[ok] / l0), np.log(y[ok])
    ub, vb = u.mean(), v.mean()
    sxx = float(np.sum((u - ub) ** 2))
    if sxx == 0:
        return out
    b = float(np.sum((u - ub) * (v - vb)) / sxx)
    a = vb - b * ub
    out.update(slope=b, a=float(math.exp(a)))
    resid = v - (a + b * u)
    syy = float(np.sum((v - vb) ** 2))
    out["r2"] = 1.0 - float(np.sum(resid ** 2)) / syy if syy > 0 else 1.0
    if n > 2:
        s2 = float(np.sum(resid ** 2)) / (n - 2)
        out["slope_se"] = math.sqrt(s2 / sxx)
        out["a_factor"] = math.exp(math.sqrt(s2 * (1.0 / n + ub ** 2 / sxx)))
    return out


def write_csv(path, columns: dict[str, np.ndarray]) -> None:
    """A plain CSV table (header line, one row per entry), written atomically."""
    names = list(columns)
    arrays = [np.asarray(columns[k]) for k in names]
    rows = len(arrays[0]) if arrays else 0
    with atomic_output(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(",".join(names) + "\n")
            for i in range(rows):
                f.write(",".join(_cell(a[i]) for a in arrays) + "\n")


def _cell(v) -> str:
    if isinstance(v, (float, np.floating)):
        return "nan" if not np.isfinite(v) else repr(float(v))
    if isinstance(v, (bool, np.bool_)):
        return str(int(v))
    if isinstance(v, (str, np.str_)):
        return spreadsheet_safe(str(v))
    return str(v)


def format_table(columns: dict[str, np.ndarray], formats: dict[str, str] | None = None) -> list[str]:
    """Aligned text table, one line per row."""
    formats = formats or {}
    names = list(columns)
    cells = [[format(columns[k][i], formats.get(k, "g")) if not isinstance(columns[k][i], str) else columns[k][i]
              for k in names] for i in range(len(columns[names[0]]))]
    widths = [max(len(k), *(len(r[j]) for r in cells)) if cells else len(k) for j, k in enumerate(names)]
    lines = ["  ".join(k.rjust(w) for k, w in zip(names, widths))]
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in cells]
    return lines


def sample_indices(n: int, count: int | None, seed: int = 0) -> np.ndarray:
    """`count` distinct indices of range(n) drawn with numpy's PCG64 from `seed`, sorted (all if
    count is None or >= n)."""
    if count is None or count >= n:
        return np.arange(n)
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(n, size=int(count), replace=False))


def median_spacing(points: np.ndarray, sample: int = 2000, seed: int = 0) -> float:
    """Median distance from a sample of points to their nearest OTHER point of the cloud
    (duplicates, at distance 0, are skipped): the typical point spacing."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    idx = sample_indices(len(points), min(sample, max(1, len(points) // 10)), seed)
    keep = np.ones(len(points), bool)
    keep[idx] = False
    others = points[keep]
    if len(others) == 0:
        return math.nan
    d = engine.c2c(others, np.ascontiguousarray(points[idx]))["distance"]
    d = d[d > 0]
    return float(np.median(d)) if d.size else math.nan


def figure_format(path, *, option: str = "--plot", extra: str = "report") -> str:
    """The format a figure is written to `path` in: its extension's, PNG without one. Checked
    before any work by every command that draws (a format matplotlib cannot write failed with a
    traceback after the command's other outputs were written); a missing matplotlib too."""
    backend_bases = require("matplotlib.backend_bases", extra=extra, purpose=f"drawing {option}")
    supported = backend_bases.FigureCanvasBase.get_supported_filetypes()
    fmt = Path(path).suffix.lstrip(".").lower() or "png"
    if fmt not in supported:
        raise UsageError(f"{option} {path}: cannot draw '.{fmt}' figures "
                         f"(supported: {' '.join('.' + f for f in sorted(supported))})")
    return fmt


def save_figure(fig, path) -> None:
    """Saves a matplotlib figure atomically (format from the extension)."""
    with atomic_output(Path(path)) as tmp:
        fig.savefig(tmp, dpi=120, format=figure_format(path))


def pyplot():
    """matplotlib.pyplot with the non-interactive Agg backend."""
    matplotlib = require("matplotlib", extra="report", purpose="plots")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def readable_log_axis(axis, lo: float, hi: float) -> None:
    """Log-axis ticks that do not overlap: labels at 1, 2, 5 x 10^k only (matplotlib labels
    every minor tick when the range spans less than a decade, and they collide), plain numbers,
    no minor labels."""
    from matplotlib import ticker

    decades = math.log10(hi / lo) if lo > 0 and hi > lo else 1.0
    subs = (1.0,) if decades > 4 else (1.0, 2.0, 5.0) if decades > 0.7 else (1.0, 1.5, 2.0, 3.0, 5.0, 7.0)
    axis.set_major_locator(ticker.LogLocator(base=10, subs=subs))
    axis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(ticker.NullFormatter())


def reference_line(x: np.ndarray, y_at: float, x_at: float, slope: float) -> np.ndarray:
    """y = y_at (x / x_at)^slope: a reference slope drawn through (x_at, y_at), a point of the
    data, so that it lies on the data whatever the fit's anchor l0 is."""
    return y_at * (np.asarray(x, dtype=float) / x_at) ** slope


def repeated_positions(xyz: np.ndarray) -> str | None:
    """A warning when core points share a position (merged scans, a cloud concatenated with
    itself): each counts as a point of its own, so the aggregates' intervals narrow (by sqrt 2 for
    doubled points) and the variogram gets a lag-0 bin of zero semivariance. None when all differ."""
    if len(xyz) < 2:
        return None
    distinct = len(np.unique(np.ascontiguousarray(xyz, dtype=np.float64), axis=0))
    repeated = len(xyz) - distinct
    if repeated == 0:
        return None
    return (f"{repeated} core points repeat the position of another ({len(xyz)} core points at {distinct} positions): "
            f"each counts as an independent point, which narrows the intervals and biases the variogram's nugget; "
            f"compare with the repeated reference points removed (m3c2 subsample --spacing)")
