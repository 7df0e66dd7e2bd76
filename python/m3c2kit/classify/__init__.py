"""CANUPO: multi-scale dimensionality classification (Brodu & Lague 2012, ISPRS J. 68), the
vegetation removal the M3C2 paper runs before comparing (Lague et al. 2013, section 4.3).

    >>> from m3c2kit.classify import features, train, read_classifier, classify, keep_mask
    >>> f = features(cloud_xyz, [0.5, 1, 2])                 # triangle coordinates per scale
    >>> clf = train([(xyz_ground, "ground"), (xyz_veg, "vegetation")], scales=[0.5, 1, 2])
    >>> label, confidence = classify(clf, scene_xyz)
    >>> kept = scene_xyz[keep_mask(clf, scene_xyz, ["ground"])]

Training needs scikit-learn (``pip install m3c2kit[classify]``); applying a classifier does not.
docs/algorithm.md ("Multi-scale dimensionality") gives the equations, docs/classify.md the
command line and the classifier files.
"""
import sys
from types import ModuleType

#: Each public name's module, imported on first use (PEP 562): a compare imports
#: classify.vegetation for its --classifier option, which must not bring the classifier's modules
#: into every run (issue 45: 0.21 s of each compare's start).
_LAZY = {"classify": "apply", "filtered": "apply", "keep_mask": "apply", "Features": "features",
         "features": "features", "Classifier": "model", "read_classifier": "model", "write_classifier": "model",
         "train": "train"}

__all__ = ["Features", "features", "Classifier", "read_classifier", "write_classifier", "train", "classify",
           "keep_mask", "filtered"]


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module 'm3c2kit.classify' has no attribute {name!r}")
    from importlib import import_module
    value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


class _Package(ModuleType):
    """`features` and `train` are both submodules and the functions they define. Importing a
    submodule binds its name on the package to the module (the import system's setattr), which
    would hide the function once another module had imported it; the names stay the functions'
    (as when this file imported them eagerly)."""

    def __setattr__(self, name, value):
        if name in _LAZY and isinstance(value, ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
