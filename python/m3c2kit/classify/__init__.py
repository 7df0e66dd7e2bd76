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
from .apply import classify, filtered, keep_mask
from .features import Features, features
from .model import Classifier, read_classifier, write_classifier
from .train import train

__all__ = ["Features", "features", "Classifier", "read_classifier", "write_classifier", "train", "classify",
           "keep_mask", "filtered"]
