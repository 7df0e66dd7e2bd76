"""--classifier FILE --keep CLASS as the executor's vegetation filter (section 4.3: vegetation
removed by CANUPO before the comparison). m3c2kit.run takes it as an input (run.plan's
``vegetation``) and never imports this package: the filter says how far a point's class reaches
(the tiled run's halo) and classifies, in memory or one tile at a time on a worker."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..base.errors import UsageError

if TYPE_CHECKING:
    from .model import Classifier

# .apply and .model are imported where a filter is used: every compare imports this module for
# vegetation_filter(), and most use no classifier (issue 45).


@dataclass
class VegetationFilter:
    """The points of both clouds classified as one of `keep` by the classifier in `path`.
    Picklable: a Dask worker reads the classifier file again (`path`), not a pickled model."""

    path: object
    keep: list
    _classifier: Classifier | None = field(default=None, repr=False, compare=False)

    def __getstate__(self):
        return {"path": self.path, "keep": self.keep, "_classifier": None}

    @property
    def classifier(self) -> Classifier:
        if self._classifier is None:
            from .model import read_classifier
            self._classifier = read_classifier(self.path)
        return self._classifier

    @property
    def reach(self) -> float:
        """The farthest point whose position changes a point's class: half the largest scale,
        with a margin for the rounding of the box test."""
        r = 0.5 * float(np.max(self.classifier.scales))
        return r * (1 + 1e-9) + 1e-9

    def filtered(self, cloud, name: str, threads: int = 0):
        """In memory: `cloud` reduced to its kept points (UsageError naming `name` when none is left)."""
        from .apply import filtered
        return filtered(self.classifier, cloud, self.keep, name, threads=threads)

    def keep_mask(self, near: np.ndarray, own: np.ndarray, threads: int = 0) -> np.ndarray:
        """One tile: uint8 1 for each point of `own` kept, classified from its neighbours `near`."""
        from .apply import classify
        clf = self.classifier
        p = classify(clf, near, own, threads=threads)
        wanted = np.array([clf.labels.index(k) for k in self.keep])
        return np.isin(p.index, wanted).astype(np.uint8)


def vegetation_filter(classifier, keep) -> VegetationFilter | None:
    """The filter the parameters --classifier and --keep ask for (None without them); the
    classifier file is read and every class of --keep checked before any work."""
    if (classifier is None) != (keep is None):
        raise UsageError("--classifier and --keep go together: the classifier's classes to keep, e.g. "
                         "--classifier veg.json --keep ground")
    if classifier is None:
        return None
    names = [k.strip() for k in str(keep).split(",") if k.strip()] if isinstance(keep, str) else [str(k) for k in keep]
    filt = VegetationFilter(classifier, names)
    labels = filt.classifier.labels
    unknown = [k for k in names if k not in labels]
    if unknown:
        raise UsageError(f"--keep {','.join(unknown)}: not a class of the classifier (its classes: "
                         f"{', '.join(labels)})")
    return filt
