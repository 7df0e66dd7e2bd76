"""m3c2kit:suggest, `m3c2 suggest`: D, d and the max depth for a pair, as outputs a model can
pass on to M3C2 compare (qgis/models/suggest_then_compare.model3)."""
import re

from qgis.core import QgsProcessingException, QgsProcessingOutputNumber, QgsProcessingOutputString

from ..base import cloud_parameter
from ..options import Opt
from .simple import OptionsAlgorithm

PROPOSAL = re.compile(r"^proposal \(rounded\): --normal-scale (\S+) --projection-scale (\S+) --max-depth (\S+)\s*$")


def proposal(stdout):
    """(D, d, max depth) of m3c2 suggest's 'proposal (rounded): ...' line."""
    for line in stdout.splitlines():
        match = PROPOSAL.match(line.strip())
        if match:
            return match[1], float(match[2]), float(match[3])
    raise QgsProcessingException("m3c2 suggest printed no proposal line (m3c2kit's version differs from this plugin's)")


class SuggestAlgorithm(OptionsAlgorithm):
    NAME = "suggest"
    DISPLAY = "Suggest M3C2 parameters"
    HELP = ("m3c2 suggest: proposes D (NORMAL_SCALE: the smallest scale with xi >= 25 at 95 % of sampled core points, "
            "else a multi-scale range), d (PROJECTION_SCALE: the smallest with median n >= 30 in both clouds) and "
            "MAX_DEPTH (3 x the 99th percentile of |distance| of a first pass), printing the numbers behind each "
            "in the log. Its outputs feed M3C2 compare in a model.")
    OPTIONS = (Opt("SAMPLE", "--sample", "integer", "Sampled core points", minimum=1),
               Opt("SEED", "--seed", "integer", "Seed of the random draws", minimum=0),
               Opt("DROP_NONFINITE", "--drop-nonfinite", "flag", "Drop points with NaN/Inf coordinates"))

    def initAlgorithm(self, config=None):  # noqa: N802 - QGIS's name
        self.addParameter(cloud_parameter("REFERENCE", "Reference cloud"))
        self.addParameter(cloud_parameter("COMPARED", "Compared cloud"))
        self.add_options()
        self.addOutput(QgsProcessingOutputString("NORMAL_SCALE", "D: normal scale (one value or a range)"))
        self.addOutput(QgsProcessingOutputNumber("PROJECTION_SCALE", "d: projection scale (diameter)"))
        self.addOutput(QgsProcessingOutputNumber("MAX_DEPTH", "max depth (half-length)"))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 - QGIS's name
        args = ["suggest", self.cloud_path(parameters, "REFERENCE", context),
                self.cloud_path(parameters, "COMPARED", context)] + self.option_arguments(parameters, context)
        scale, diameter, depth = proposal(self.m3c2(args, feedback))
        return {"NORMAL_SCALE": scale, "PROJECTION_SCALE": diameter, "MAX_DEPTH": depth}
