"""Scenes for shadow maps: meshes, lights, cameras and scene files.

* :mod:`.mesh`: :class:`Mesh`, procedural generators (box, cylinder, plane,
  railing, banner, umbrella, torus_knot), 4×4 transforms, :func:`read_obj`.
* :mod:`.lights`: :class:`DirectionalLight` (orthographic map fitted to the
  scene), :class:`AreaLight` (rectangle, perspective maps from points on it).
* :mod:`.camera`: :class:`Camera` of the shaded view.
* :mod:`.files`: :func:`load_scene`, :func:`list_scenes`, :class:`Scene`.

Shipped scenes (``scenes/*.toml``): ``railing`` (HPG17 Figure 1), ``facade``
(Figure 8), ``three-occluders`` (Figure 9), ``knot`` (a torus knot of about 200k
triangles under a rectangular area light, for VWSS) and ``translucent``.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from .camera import Camera
from .files import ROLES, Scene, SceneObject, list_scenes, load_scene
from .lights import AreaLight, DirectionalLight
from .mesh import (
    GENERATORS,
    Mesh,
    banner,
    box,
    cylinder,
    merge,
    plane,
    railing,
    read_obj,
    rotate,
    scale,
    torus_knot,
    translate,
    umbrella,
)

__all__ = [
    "Camera", "Scene", "SceneObject", "ROLES", "list_scenes", "load_scene",
    "AreaLight", "DirectionalLight",
    "GENERATORS", "Mesh", "merge", "translate", "rotate", "scale", "read_obj",
    "box", "cylinder", "plane", "railing", "banner", "umbrella", "torus_knot",
]
