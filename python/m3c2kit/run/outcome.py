"""What a tiled run did (printed by the command line, returned by run_tiled)."""
from __future__ import annotations

from dataclasses import dataclass, field

from ..engine.result import Result
from .fdr import sentences
from .memory import MemoryPlan

@dataclass
class TiledReport:
    """What a tiled run did (also printed by the command line)."""

    core_points: int = 0
    tiles: int = 0
    tile_size: float = 0.0
    halo: float = 0.0
    reference_points: int = 0         # points of each input as read (before --classifier), where counted
    compared_points: int = 0
    tile_points_max: int = 0          # largest reference + compared points of one tile
    tile_points_total: int = 0        # sum over tiles (halo points counted once per tile)
    estimated_tile_bytes_max: int = 0
    memory_limit: int | None = None
    memory_plan: MemoryPlan | None = None
    dask: bool = False
    workers: int = 1
    seconds: dict = field(default_factory=dict)
    status_counts: dict = field(default_factory=dict)
    significant: int = 0
    significant_fdr: int = 0          # --fdr: the discoveries (q <= Q)
    fdr: object = None                # --fdr: the run's m3c2kit.run.fdr.Fdr
    with_p_value: int = 0             # core points tested (a finite p_value)
    confidence: float = 0.95          # the run's --confidence (the summary's multiple-testing line)
    with_distance: int = 0
    result: Result | None = None      # return_result: the merged Result
    attributes: dict | None = None    # with it, the core points' attributes (m3c2kit.run.attributes)
    grid: object = None               # --grid: the grid of core points (m3c2kit.run.raster.Grid)
    warnings: list = field(default_factory=list)  # m3c2kit.run.diagnostics' messages, also emitted
    evidence: object = None  # the columns the warnings were drawn from (m3c2kit.run.merge.Evidence)

    def lines(self, output) -> list[str]:
        where = f"Dask cluster ({self.workers} workers)" if self.dask else "one machine"
        out = [f"wrote {output}: {self.core_points} core points, {self.with_distance} with a distance, "
               f"{self.significant} significant changes",
               f"tiled on {where}: {self.tiles} tiles of {self.tile_size:.6g} with a halo of {self.halo:.6g}; "
               f"largest tile {self.tile_points_max} cloud points (estimated {self.estimated_tile_bytes_max / 2**20:.0f} MiB)",
               "status: " + ", ".join(f"{k} {v}" for k, v in self.status_counts.items())]
        out += ["multiple testing: " + text for text in
                sentences(self.with_p_value, self.significant, self.confidence, self.fdr, self.significant_fdr)]
        return out


