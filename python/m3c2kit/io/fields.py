"""The output fields of a compare run: their names (m3c2kit's, CloudCompare's or PDAL's), their
stored types, and the core points' own attributes carried beside them.

One table, :data:`FIELDS`, holds every output column once with its three names and its type;
docs/python.md's field table is generated from it (:func:`markdown_table`, checked by
tests/python/io/test_io_fields.py).

Stored types (``float64=False``, the default): values a survey measures (distance, LOD, spreads,
normal scale, roughness, normal components) as float32 in text and PLY files, whose relative
precision is 2**-24 = 6e-8: below 1 km that is under 0.06 mm, far below any lidar or
photogrammetric precision; counts as float32 (exact below 2**24 points per cylinder; NaN where
no cylinder was searched, never a 0 that reads as "an empty cylinder": ``status`` 1 or 2 says
why); ``status`` as uint8; ``significant`` as float32 (0 or 1, NaN where there is no LOD:
unknown is not "no change"); ``p_value`` and ``q_value`` as float64 (float32 could round a p-value
just below 1 - confidence onto it, breaking p < 1 - confidence <=> significant). Projected positions (x1 ... z2) stay float64: they are
coordinates, and float32 would lose centimetres at UTM magnitudes. ``float64=True``
(--float64) stores every float column as float64.

LAS/LAZ files (``las=True``) store them as scaled integers with a ``no_data`` value for NaN
(m3c2kit.io.quantised): lengths in int32 at 1e-4 of the CRS unit (0.1 mm: at most 0.05 mm
off), normal components in int16 at 1e-4, counts in uint32, ``significant`` in uint8; a column
that does not fit (a length beyond 214 km) stays float32. That keeps a LAZ output within twice
the size of the same points' input (tests/python/output/test_output_size.py). LAS files also carry
only the columns marked ``compact`` (CloudCompare's default set: distance, uncertainty,
significance, the counts; and ``status``) unless ``all_fields`` (--all-fields); text and PLY
files carry every column.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from .quantised import Quantised, as_float32, quantised

__all__ = ["Field", "FIELDS", "FIELD_NAME_SETS", "FieldNames", "TableStyle", "output_name", "typed_columns",
           "core_attributes", "carried_columns", "markdown_table", "FLOAT32_RELATIVE_PRECISION"]

FieldNames = Literal["m3c2", "cloudcompare", "pdal"]
FIELD_NAME_SETS = ("m3c2", "cloudcompare", "pdal")

#: float32's unit roundoff, 2**-24: the relative error of a value stored as float32.
FLOAT32_RELATIVE_PRECISION = 2.0**-24


@dataclass(frozen=True)
class Field:
    """One output column: m3c2kit's name, CloudCompare's (qM3C2 scalar field), PDAL's
    (filters.m3c2 dimension; None where the tool has no such output: m3c2kit's name is used),
    its stored type and what it is."""

    name: str
    cloudcompare: str | None
    pdal: str | None
    dtype: str  # "measure" (float32, float64 on request), "coordinate" and "probability" (float64), "uint8"
    meaning: str
    las: str | None = None  # LAS storage (m3c2kit.io.quantised.KINDS); None: as `dtype` says
    compact: bool = True  # in a LAS file without --all-fields


FIELDS: tuple[Field, ...] = (
    Field("distance", "M3C2 distance", "m3c2_distance", "measure", "M3C2 distance i2 - i1 along the normal (eq. 1)", las="length"),
    Field("lod", "distance uncertainty", "m3c2_uncertainty", "measure", "level of detection at --confidence (eq. 1)", las="length"),
    Field("significant", "significant change", "m3c2_significant", "measure", "1 when |distance| > lod, 0 when not, NaN without LOD", las="flag"),
    Field("p_value", None, None, "probability", "two-sided p-value of the LOD's test: < 1 - confidence exactly where significant (algorithm.md)", compact=False),
    Field("n1", "Npoints_cloud1", "m3c2_count1", "measure", "reference points in the cylinder", las="count"),
    Field("n2", "Npoints_cloud2", "m3c2_count2", "measure", "compared points in the cylinder", las="count"),
    Field("sigma1", "STD_cloud1", "m3c2_std_dev1", "measure", "spread of the reference points along the normal", las="length", compact=False),
    Field("sigma2", "STD_cloud2", "m3c2_std_dev2", "measure", "spread of the compared points along the normal", las="length", compact=False),
    Field("nx", "NormalX", None, "measure", "normal, x component", las="unit", compact=False),
    Field("ny", "NormalY", None, "measure", "normal, y component", las="unit", compact=False),
    Field("nz", "NormalZ", None, "measure", "normal, z component", las="unit", compact=False),
    Field("normal_scale", "normal scale", None, "measure", "the diameter D the normal was fitted at", las="length", compact=False),
    Field("roughness", None, None, "measure", "sigma(D), the spread of the normal neighbourhood about its plane", las="length", compact=False),
    Field("status", None, None, "uint8", "reason code: 0 ok, 1-5 why a value is NaN (README)"),
    Field("spread1", None, None, "measure", "sqrt(n^T S_1 n), the reference mean's propagated spread along the normal (pm / ep, algorithm.md 6.5)", las="length", compact=False),
    Field("spread2", None, None, "measure", "sqrt(n^T S_2 n), the compared mean's propagated spread along the normal (pm / ep)", las="length", compact=False),
    Field("q_value", None, None, "probability", "--fdr: the BH / BY adjusted p-value (algorithm.md)", compact=False),
    Field("significant_fdr", None, None, "uint8", "--fdr: 1 when q_value <= Q, else 0"),
    Field("x1", None, None, "coordinate", "projection on the reference, x (--projected)"),
    Field("y1", None, None, "coordinate", "projection on the reference, y"),
    Field("z1", None, None, "coordinate", "projection on the reference, z"),
    Field("x2", None, None, "coordinate", "projection on the compared cloud, x"),
    Field("y2", None, None, "coordinate", "projection on the compared cloud, y"),
    Field("z2", None, None, "coordinate", "projection on the compared cloud, z"),
)
_BY_NAME = {f.name: f for f in FIELDS}


def _check_names(field_names: str) -> str:
    if field_names not in FIELD_NAME_SETS:
        from ..base.errors import UsageError
        raise UsageError(f"--field-names must be one of {', '.join(FIELD_NAME_SETS)}, got {field_names!r}")
    return field_names


def output_name(name: str, field_names: str = "m3c2", *, spaces: bool = True) -> str:
    """The name column `name` gets under `field_names`; with ``spaces=False`` (text and PLY
    files, whose column names cannot hold spaces) spaces become ``_``, as in CloudCompare's own
    ASCII export."""
    f = _BY_NAME.get(name)
    out = name
    if f is not None and field_names != "m3c2":
        out = getattr(f, _check_names(field_names)) or name
    return out if spaces else out.replace(" ", "_")


def _stored(name: str, values: np.ndarray, float64: bool, las: bool, where: str) -> np.ndarray | Quantised:
    field = _BY_NAME.get(name)
    kind = field.dtype if field is not None else None
    values = np.asarray(values)
    if kind == "uint8":
        return values.astype(np.uint8)
    if kind == "measure":
        if las and not float64 and field.las is not None:
            return quantised(values, field.las, f"{where}column {name!r}")
        return values.astype(np.float64) if float64 else as_float32(values, f"{where}column {name!r}")
    return values.astype(np.float64) if values.dtype.kind == "f" else values


def typed_columns(table: dict[str, np.ndarray], *, field_names: str = "m3c2", float64: bool = False,
                  spaces: bool = True, las: bool = False,
                  all_fields: bool = False, path=None) -> dict[str, np.ndarray | Quantised]:
    """The result table (Result.columns() without x, y, z) renamed and cast for storage; for a
    LAS file (`las`) quantised, and only the ``compact`` columns unless `all_fields`. `path`, the
    file they go to, is named by the error of a value its storage cannot hold."""
    where = f"{path}: " if path is not None else ""
    _check_names(field_names)
    if las and not all_fields:
        table = {k: v for k, v in table.items() if k not in _BY_NAME or _BY_NAME[k].compact}
    return {output_name(k, field_names, spaces=spaces): _stored(k, v, float64, las, where)
            for k, v in table.items()}


@dataclass(frozen=True)
class TableStyle:
    """How a compare run's point table is written, in every mode (the one place of these
    defaults: m3c2kit.write, the command line's outputs and the tiled merge take them from here):
    the projected positions x1..z2 too (`projected`), rows at the core points or at their
    projections (`position`), the columns' names (`field_names`), float64 or the compact stored
    types (`float64`), every column in LAS/LAZ or CloudCompare's set (`all_fields`), and the
    reference's own attributes of the core points carried beside them (`attributes`)."""

    projected: bool = False
    position: str = "core"
    field_names: str = "m3c2"
    float64: bool = False
    all_fields: bool = False
    attributes: bool = True

    #: The compare settings (parameter table names) that are this style's, not the engine's.
    SETTINGS = ("position", "field_names", "float64", "all_fields")

    @classmethod
    def taken_from(cls, settings: dict, **given) -> "TableStyle":
        """The style the settings `settings` ask for, removing them from it (the run does not take
        them); unset ones (absent or None) keep this class's defaults. `given`: other fields."""
        asked = {name: settings.pop(name, None) for name in cls.SETTINGS}
        return cls(**{k: v for k, v in asked.items() if v is not None}, **given)

    def rows(self, result) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """(xyz, the other columns) of `result` (an m3c2kit.Result, or a chunk of one) as placed
        and chosen by this style."""
        table = result.columns(projected=self.projected, position=self.position)
        xyz = np.column_stack([table.pop("x"), table.pop("y"), table.pop("z")])
        return xyz, table

    def stored(self, table: dict[str, np.ndarray], quantises: bool, path) -> dict[str, np.ndarray | Quantised]:
        """The columns renamed and typed for the file `path`, whose format `quantises` (LAS/LAZ:
        m3c2kit.io.registry.Format.quantises; its names may hold spaces) or not."""
        return typed_columns(table, field_names=self.field_names, float64=self.float64, spaces=quantises,
                             las=quantises, all_fields=self.all_fields, path=path)


def carried_columns(values: dict[str, np.ndarray], taken) -> dict[str, np.ndarray]:
    """The core points' own attributes named beside the M3C2 columns `taken`: a name already
    taken (an M3C2 column) is prefixed ``core_``."""
    return {(name if name not in taken else f"core_{name}"): np.asarray(v) for name, v in values.items()}


def core_attributes(source, index: np.ndarray | None, taken: set[str]) -> dict[str, np.ndarray]:
    """The attributes (intensity, classification, GPS time, RGB, ...) of the points of `source`
    (a Cloud) that the core points are, in core-point order, with their own types.

    `index`: for each core point, the row of `source` it is (m3c2kit.engine.match_rows: the core
    points are the reference itself, a subsample of it, or the --core file's points), or None when
    some core point is not among them; then, or when `source` has no fields, nothing is carried. A
    name already in `taken` (an M3C2 column) is prefixed ``core_``."""
    fields = getattr(source, "fields", None) or {}
    if not fields or index is None:
        return {}
    return carried_columns({name: np.asarray(values)[index] for name, values in fields.items()}, taken)


def markdown_table() -> str:
    """docs/python.md's table of output names and stored types, from :data:`FIELDS`."""
    from .quantised import KINDS
    types = {"measure": "float32 (float64 with --float64)", "coordinate": "float64", "probability": "float64",
             "uint8": "uint8"}

    def in_las(f: Field) -> str:
        if f.las is None:
            text = types[f.dtype].replace(" (float64 with --float64)", "")
        else:
            dtype, scale = KINDS[f.las]
            text = f"{dtype.name} at {scale:g}" if scale is not None else dtype.name
            text += ", NaN as no_data (float64 with --float64)"
        return text + ("" if f.compact else "; only with --all-fields")

    lines = ["| m3c2kit | CloudCompare (`--field-names cloudcompare`) | PDAL (`--field-names pdal`) | stored as "
             "(text, PLY) | stored in LAS/LAZ | meaning |",
             "|---|---|---|---|---|---|"]
    for f in FIELDS:
        cc = f"`{f.cloudcompare}`" if f.cloudcompare else f"(`{f.name}`)"
        pdal = f"`{f.pdal}`" if f.pdal else f"(`{f.name}`)"
        lines.append(f"| `{f.name}` | {cc} | {pdal} | {types[f.dtype]} | {in_las(f)} | {f.meaning} |")
    return "\n".join(lines)
