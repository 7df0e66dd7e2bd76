"""The spatially correlated error model (``m3c2 variogram`` writes it, ``compare --error-model``
reads it): defined once in m3c2kit.settings.error_model, the layer of compare's parameters,
and named here for the analysis toolkit (variogram, random fields, aggregates)."""
from ..settings.error_model import (FORMAT, KINDS, LAG_DISTANCES, READS, VERSION, Component,  # noqa: F401
                                    ErrorModel, ErrorModelError, disc_distance_pdf, for_compare, load, model_bytes,
                                    save)

__all__ = ["FORMAT", "VERSION", "READS", "KINDS", "LAG_DISTANCES", "Component", "ErrorModel", "ErrorModelError",
           "disc_distance_pdf", "load", "save", "model_bytes", "for_compare"]
