"""View-warped soft shadows (VWSS, Marrs, Watson, Healey 2018) and its baselines.

* :mod:`.lights`: Poisson-disk light samples and their perspective views.
* :mod:`.points`: the enlarged source view (VWSS Eqs. (1)–(3)) and point generation (§3.1).
* :mod:`.warp`: reproject, snap and z-buffer points into many maps (§3.2, Listing 2).
* :mod:`.mvr`: multi-view rasterization, the baseline and the reference.
* :mod:`.shading`: 5-tap multi-view PCF and PCSS (§4); the G-buffer is
  :func:`moments_ref.scene.gbuffer.depth_gbuffer`.
* :mod:`.paper`: the paper's figures (Tables 1 and 2) and the claims measured against them.

The functions ``warp`` and ``mvr`` are not re-exported here, so that
``moments_ref.techniques.vwss.warp`` and ``moments_ref.techniques.vwss.mvr`` stay the modules:
import them as ``from moments_ref.techniques.vwss.warp import warp``.

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from .lights import LIGHT_NEAR_PARAM, LightSamples, depth_range, light_near, light_views, poisson_disk
from .mvr import mvr_passes
from .points import PointCloud, SourceView, center_view, enlarged_view, generate_points, naive_points, source_view
from .shading import multiview_visibility, pcf_sum, pcss
from ..._shim import renamed
from .warp import project_to_texels, warp_passes, zbuffer_max

__all__ = [
    "LIGHT_NEAR_PARAM", "LightSamples", "depth_range", "light_near", "light_views", "poisson_disk",
    "mvr_passes",
    "PointCloud", "SourceView", "center_view", "enlarged_view", "generate_points", "naive_points", "source_view",
    "multiview_visibility", "pcf_sum", "pcss",
    "project_to_texels", "warp_passes", "zbuffer_max",
]

#: Old names (a DeprecationWarning): linear_depth, GBuffer and gbuffer moved to moments_ref.scene.
__getattr__ = renamed("techniques.vwss")
