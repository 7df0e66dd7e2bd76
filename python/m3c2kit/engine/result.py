"""The result of an M3C2 run as numpy arrays, and its table of output columns."""
from __future__ import annotations

from dataclasses import field, make_dataclass

import numpy as np

from . import OPTIONAL_RESULT_FIELDS, RESULT_FIELDS, STATUS_NAMES

#: Output columns in every format, in this order (a contract: see docs/cli.md).
COLUMNS = ("x", "y", "z", "distance", "lod", "significant", "p_value", "n1", "n2", "sigma1", "sigma2",
           "nx", "ny", "nz", "normal_scale", "roughness", "status")
#: The columns of the core point and its normal, the same for every compared cloud (a series
#: stores them once), and those of each comparison (a series stores them per epoch). A series
#: store does not hold p_value: its format (2) predates the column (docs/algorithm.md, "p-values").
CORE_COLUMNS = ("x", "y", "z", "nx", "ny", "nz", "normal_scale", "roughness")
COMPARISON_COLUMNS = tuple(c for c in COLUMNS if c not in CORE_COLUMNS and c != "p_value")
#: Written after the status when the run made them (uncertainty pm / ep; docs/algorithm.md §6.5).
UNCERTAINTY_COLUMNS = ("spread1", "spread2")
#: Written last with --fdr (m3c2kit.run.fdr: one global ranking of every core point's p_value).
FDR_COLUMNS = ("q_value", "significant_fdr")

#: Reason codes of the `status` column: STATUS_NAMES (the engine's, by code), and its groups, each
#: owned here: a core point computed in full; without a normal (too few neighbours within D/2, or a
#: degenerate fit); with a normal but an empty cylinder in the reference (1) or the compared (2)
#: cloud; with a normal and both cylinders searched, whatever they held.
STATUS_OK = STATUS_NAMES.index("ok")
NO_NORMAL = ("too_few_normal_points", "degenerate_normal")
EMPTY_CYLINDER = {1: "empty_cylinder_reference", 2: "empty_cylinder_compared"}
SEARCHED = ("ok", *EMPTY_CYLINDER.values(), "too_few_points_for_lod")


def status_in(status, names) -> np.ndarray:
    """Whether each code of `status` is one of the statuses `names` (STATUS_NAMES): one comparison
    per name (np.isin took 0.9 ms a call on 90k core points, and a run's warnings make several)."""
    status = np.asarray(status)
    out = np.zeros(status.shape, dtype=bool)
    for name in names:
        out |= status == STATUS_NAMES.index(name)
    return out


class _ResultMethods:
    """Per-core-point M3C2 output. Index i of every array is core point i.

    distance = i2 - i1 along the oriented normal (NaN where not computed); lod is the level of
    detection at the requested confidence (NaN where n1 or n2 < min_points); significant is
    True iff n1, n2 >= min_points and |distance| > lod; p_value is the two-sided p-value of the
    test the LOD expresses, p_value < 1 - confidence exactly where significant (NaN where lod is);
    with --fdr, the attributes q_value (the adjusted p-value) and significant_fdr (q <= Q) that
    m3c2kit.run.fdr sets on the whole run's Result (they are not the engine's: no fields);
    status says why anything is NaN.
    Its arrays are the engine's Result fields (m3c2kit.engine.RESULT_FIELDS), plus ``core`` (the
    core points) and ``params`` (what the run was asked).
    """

    @classmethod
    def from_engine(cls, core: np.ndarray, raw: dict, params: dict):
        raw = dict(raw)
        raw["significant"] = raw["significant"].astype(bool)
        return cls(core=core, params=params, **raw)

    def __len__(self) -> int:
        return len(self.distance)

    @property
    def xi(self) -> np.ndarray:
        """xi = D / sigma(D), the normal-accuracy indicator of eq. (4) (section 5.1)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.normal_scale / self.roughness

    def projected(self, which: int) -> np.ndarray:
        """Positions core + i_k * normal on cloud k (1 = reference, 2 = compared)."""
        offset = self.i1 if which == 1 else self.i2
        return self.core + offset[:, None] * self.normal

    def columns(self, projected: bool = False, position: str = "core",
                fallback: str = "nan") -> dict[str, np.ndarray]:
        """The output table: name -> column. NaN wherever a value was not computed, including
        `significant` where there is no LOD and n1/n2 where no cylinder was searched.

        position "reference" / "compared" places each row at core + i_k * normal on that cloud;
        where there is none (no normal, or an empty cylinder: the `status` column says which) the
        row's x, y, z are NaN (fallback "nan", the default), or its core point (fallback "core",
        also chosen by position "reference-or-core" / "compared-or-core": --position's values)."""
        cloud, _, or_what = position.partition("-or-")
        fallback = or_what or fallback
        if fallback not in ("nan", "core"):
            raise ValueError(f"fallback must be 'nan' or 'core', got {fallback!r}")
        xyz = self.core
        if cloud != "core":
            proj = self.projected(1 if cloud == "reference" else 2)
            missing = np.isnan(proj).any(axis=1, keepdims=True)
            xyz = np.where(missing, self.core if fallback == "core" else np.nan, proj)
        searched = ~status_in(self.status, NO_NORMAL)
        significant = np.where(np.isnan(self.lod), np.nan, self.significant.astype(float))
        table = {
            "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2],
            "distance": self.distance, "lod": self.lod, "significant": significant, "p_value": self.p_value,
            "n1": np.where(searched, self.n1, np.nan), "n2": np.where(searched, self.n2, np.nan),
            "sigma1": self.sigma1, "sigma2": self.sigma2,
            "nx": self.normal[:, 0], "ny": self.normal[:, 1], "nz": self.normal[:, 2],
            "normal_scale": self.normal_scale, "roughness": self.roughness,
            "status": self.status.astype(np.uint8),
        }
        for name in UNCERTAINTY_COLUMNS + FDR_COLUMNS:
            if getattr(self, name, None) is not None:
                table[name] = getattr(self, name)
        if projected:
            p1, p2 = self.projected(1), self.projected(2)
            table.update(x1=p1[:, 0], y1=p1[:, 1], z1=p1[:, 2], x2=p2[:, 0], y2=p2[:, 1], z2=p2[:, 2])
        return table

    def status_counts(self) -> dict[str, int]:
        codes, counts = np.unique(self.status, return_counts=True)
        return {STATUS_NAMES[c]: int(n) for c, n in zip(codes, counts)}


#: The Result class: ``core``, one array per engine Result field, ``params``.
Result = make_dataclass("Result", [("core", np.ndarray)] + [(name, np.ndarray) for name in RESULT_FIELDS]
                        + [("params", dict, field(default_factory=dict))]
                        + [(name, object, field(default=None)) for name in OPTIONAL_RESULT_FIELDS],
                        bases=(_ResultMethods,),
                        namespace={"__module__": __name__})
Result.__doc__ = _ResultMethods.__doc__
