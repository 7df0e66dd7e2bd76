"""The executor of compare runs (docs/architecture.md, docs/scaling.md): one plan
(:mod:`.plan`: the options resolved and checked once), executed in memory (:mod:`.in_memory`) or in
tiles on this machine or on Dask (:mod:`.tiled`), every task making the same engine call
(:mod:`.tasks`). The tiled pieces: :mod:`.tiled_plan` (what a tiled run is asked, its plan made
once), :mod:`.memory` (planning), :mod:`.partition` (tiles and halos), :mod:`.spill` (every spill
write), :mod:`.vegetation` (--classifier in tiles), :mod:`.grid_cores` (--grid by streaming),
:mod:`.dask` (the cluster, THE task executor), :mod:`.merge` (core order, the output),
:mod:`.attributes` (the core points' attributes by streaming), :mod:`.cylinder_points` (the
empty-cylinder diagnosis on streamed clouds), :mod:`.outcome` (the report)."""
from __future__ import annotations

from .in_memory import compare
from .plan import Plan, make_plan
from .tiled import run_tiled

__all__ = ["Plan", "make_plan", "compare", "run_tiled"]
