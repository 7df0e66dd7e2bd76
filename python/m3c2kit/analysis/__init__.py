"""The paper's analysis toolkit (Lague, Brodu & Leroux 2013; docs/analysis.md).

- roughness: <sigma(D)> per scale and the self-affine fit of eq. (3) (section 5.1, Fig. 6a, Table 1)
- calibrate: LOD95 calibration on differently subsampled copies of one cloud (5.2.1-5.2.2, Figs. 8-9)
- baselines: C2C and C2C_HF closest-point distances (section 3.4, Fig. 4)
- simplify: self-comparison, local averaging / outlier removal (section 6.3)
- suggest: parameter guidance for D, d and the maximum depth (sections 5.1-5.3)

D (normal scale) and d (projection scale) are DIAMETERS everywhere.
"""
from .baselines import c2c
from .calibrate import calibrate
from .roughness import fit_scaling, roughness_by_scale, roughness_table
from .simplify import simplify
from .suggest import suggest

__all__ = ["c2c", "calibrate", "fit_scaling", "roughness_by_scale", "roughness_table", "simplify", "suggest"]
