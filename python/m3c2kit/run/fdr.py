"""False-discovery control over a run's p-values (--fdr Q, --fdr-method bh|by; docs/algorithm.md,
"False-discovery control"): one global step once every core point's p_value is known, the same
in memory, tiled and on Dask. The ranking is the engine's (m3c2::fdr_q_values: a stable sort on
(p, core index), O(m log m), float64), so a tiled run, which gathers the p-values of every core
point in core order, gets the in-memory run's bits."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import engine
from ..base.errors import UsageError

#: The methods' names, and what each is valid under (the summary says it).
METHODS = {"bh": "Benjamini-Hochberg, valid for independent or positively dependent p-values",
           "by": "Benjamini-Yekutieli, valid under any dependence"}

#: Bytes per core point the global step holds at once: the gathered p-values (8), the engine's
#: ranking (8 for the order, 8 for the q-values it returns) and significant_fdr (1), rounded up.
BYTES_PER_CORE = 32


@dataclass(frozen=True)
class Fdr:
    """The level Q and the method (bh, by) a run asked for."""

    level: float
    method: str

    @classmethod
    def of(cls, values: dict) -> "Fdr | None":
        """The run's --fdr and --fdr-method (resolved values), or None without --fdr."""
        level = values.get("fdr")
        return None if level is None else cls(float(level), values.get("fdr_method") or "bh")

    def text(self, discoveries: int) -> str:
        """The summary's and the report's sentence: BH and BY bound the expected share of false
        discoveries among the R made by Q, so at most Q R of them are expected false."""
        return (f"false-discovery control ({METHODS[self.method]}, --fdr {self.level:g}): {discoveries} core points "
                f"significant_fdr; at most {self.level:g} x {discoveries} = {self.level * discoveries:.1f} of them "
                f"expected to be false discoveries")

    def q_values(self, p: np.ndarray) -> np.ndarray:
        return engine.fdr_q_values(np.asarray(p, dtype=np.float64), self.method)

    def discoveries(self, q: np.ndarray) -> np.ndarray:
        """significant_fdr: q <= Q (0 where q is NaN: no p-value, no discovery)."""
        with np.errstate(invalid="ignore"):
            return (np.asarray(q) <= self.level).astype(np.uint8)

    def attach(self, result, q: np.ndarray) -> None:
        """Sets `result`'s (or a merge chunk's) q_value and significant_fdr columns."""
        result.q_value = q
        result.significant_fdr = self.discoveries(q)

    def apply(self, result) -> None:
        """The whole run's Result (in memory): its q-values from all of its p-values at once."""
        self.attach(result, self.q_values(result.p_value))


def check_memory(n_core: int, limit: int | None, base: int) -> None:
    """A run under --memory-limit holds the global step's BYTES_PER_CORE per core point beside its
    fixed costs (`base`): refused before the merge when that does not fit (docs/scaling.md)."""
    need = BYTES_PER_CORE * int(n_core)
    if limit is not None and base + need > limit:
        raise UsageError(f"--memory-limit {limit} B is too small for --fdr over {n_core} core points: its global "
                         f"ranking holds {need / 2**20:.0f} MiB beside the run's {base / 2**20:.0f} MiB "
                         f"(docs/scaling.md)")


def plain_text(tested: int, flagged: int, confidence: float) -> str | None:
    """The plain per-core-point test's multiplicity, stated plainly: over the `tested` core points
    with a p-value, each unchanged one is flagged with probability 1 - confidence, so about
    (1 - confidence) m0 of the `flagged` are false, m0 <= m (the unchanged ones) unknown."""
    if tested == 0:
        return None
    alpha = 1.0 - float(confidence)
    return (f"{flagged} of {tested} core points with a p-value significant at "
            f"{100 * float(confidence):g} %; about {alpha:g} x m0 <= {alpha * tested:.0f} of them expected false, "
            f"m0 (the unchanged core points) unknown (--fdr Q bounds the false share instead)")


def sentences(tested: int, flagged: int, confidence: float, fdr: "Fdr | None", discoveries: int) -> list[str]:
    """The summary's multiple-testing lines, the same in memory and tiled: the plain test's, then --fdr's."""
    plain = plain_text(tested, flagged, confidence)
    out = [plain] if plain else []
    if fdr is not None:
        out.append(fdr.text(discoveries))
    return out
