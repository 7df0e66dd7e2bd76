"""The provider's algorithms (issue 33's names are a contract)."""
from .c2c import C2CAlgorithm
from .classify_apply import ClassifyApplyAlgorithm
from .compare import CompareAlgorithm
from .pbm3c2 import PBM3C2Algorithm
from .pdal_compare import PdalCompareAlgorithm
from .register import RegisterAlgorithm
from .series_objects import SeriesObjectsAlgorithm
from .suggest import SuggestAlgorithm

ALGORITHMS = (CompareAlgorithm, PdalCompareAlgorithm, SuggestAlgorithm, C2CAlgorithm, ClassifyApplyAlgorithm,
              SeriesObjectsAlgorithm, PBM3C2Algorithm, RegisterAlgorithm)
