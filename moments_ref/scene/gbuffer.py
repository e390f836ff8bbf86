"""Receiver points seen by the camera: the G-buffer pass and its projection into the shadow map.

One :class:`GBuffer` holds them, built two ways: :func:`camera_gbuffer` rasterizes
the scene from the camera and keeps the nearest fragment per pixel (positions
interpolated, face normals: the report's receivers); :func:`depth_gbuffer` renders a
depth buffer and unprojects each pixel centre (VWSS §4's deferred G-buffer pass,
``moments-ref vwss``). :func:`light_projection` gives each receiver point its texel
coordinates, its unbiased depth in the light's shadow map, its signed depth
gradient per texel along the receiver (``gradient``) and the gradient's length
(``slope``); :func:`z_ndc_lookup` is the depth a lookup compares, with or
without the receiver-slope bias (:data:`SLOPE_BIAS_TEXELS`). :func:`check_shaded`
refuses, before a run, a camera that would shade no receiver pixel.

Depth bias (HPG17 §5). The filterable techniques use the constant bias alone
("With non-linear quantization we use a constant depth bias of 10⁻³ depth units
for all results"); PCF uses "a higher depth bias", which costs it its contact
shadows: here the constant plus the receiver-slope term. The 9×9 PCF reference
uses neither the slope term nor a single depth: it compares each tap with the
receiver plane's depth at that tap (receiver-plane depth, Isidoro 2006, from
``gradient``), so a plane lit at an angle does not shadow itself and contact
shadows stay (:mod:`moments_ref.techniques.references`).

References
----------
.. [1] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [2] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [3] Isidoro 2006: John R. Isidoro. 2006. *Shadow Mapping: GPU-based Tips and Techniques*. Game
       Developers Conference 2006 (receiver plane depth bias: the receiver's depth at each filter
       tap from its depth gradient in shadow-map space)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._arrays import InputError, real_input
from .._shim import alias, renamed, renamed_keywords
from .raster import project_points, rasterize_depth, rasterize_fragments, unproject_points

__all__ = ["GBuffer", "camera_gbuffer", "depth_gbuffer", "light_projection", "z_ndc_lookup", "check_shaded",
           "SLOPE_BIAS_TEXELS", "BACKGROUND", "RECEIVER", "OCCLUDER", "OUTSIDE_LIGHT"]

#: kind image codes of :class:`GBuffer`.
BACKGROUND, RECEIVER, OCCLUDER, OUTSIDE_LIGHT = 0, 1, 2, 3


@dataclass
class GBuffer:
    """Receiver points seen by the camera.

    Attributes
    ----------
    resolution : (width, height)
    kind : (height, width) int8 image
        0 background, 1 receiver (shaded, counted in the metrics), 2 occluder,
        3 receiver outside the light's shadow map (left unshadowed, not counted).
    pixel : (N,) int64
        Flat index ``row * width + col`` of each pixel with ``kind == 1``, in row-major order.
    position : (N, 3) float64 world positions
    lambert : (N,) float64 ``|n · l|`` (two-sided surfaces; None from :func:`depth_gbuffer`)
    normal : (N, 3) float64 unit face normals (None from :func:`depth_gbuffer`)
    uv : (N, 2) float64 texel coordinates in the shadow map (filled by ``light_projection``)
    z_ndc_light : (N,) float64 NDC depth in the light's view (unbiased; see :func:`z_ndc_lookup`)
    slope : (N,) float64 depth change per shadow-map texel along the receiver surface, ``|gradient|``
    gradient : (N, 2) float64 signed depth change per texel along the receiver,
        ``(∂z/∂u, ∂z/∂v)`` (u = column, v = row): the receiver plane in the map
    """

    resolution: tuple
    kind: np.ndarray
    pixel: np.ndarray
    position: np.ndarray
    lambert: np.ndarray = None
    normal: np.ndarray = None
    uv: np.ndarray = None
    z_ndc_light: np.ndarray = None
    slope: np.ndarray = None
    gradient: np.ndarray = None

    #: Old name of ``z_ndc_light`` (DeprecationWarning).
    depth = alias("z_ndc_light")

    @property
    def receiver_mask(self) -> np.ndarray:
        """(height, width) bool: the shaded receiver pixels (``kind == RECEIVER``)."""
        return self.kind == RECEIVER

    @property
    def occluder_mask(self) -> np.ndarray:
        """(height, width) bool: an occluder in front (``kind == OCCLUDER``; shown, not shaded)."""
        return self.kind == OCCLUDER


def camera_gbuffer(scene, resolution):
    """Nearest fragment per camera pixel among receivers and opaque occluder-only objects."""
    width, height = resolution
    rec = scene.receiver
    # Occluders that are not also receivers hide receivers; translucent ones do not
    # (the receiver is seen through them).
    role = np.array([scene.objects[i].role == "occluder" for i in scene.occluder_object], dtype=bool).reshape(-1)
    keep = role & ~scene.occluder_translucent
    occ_tri = scene.occluder.triangles[keep]
    v = np.concatenate([rec.vertices, scene.occluder.vertices])
    tri = np.concatenate([rec.triangles, occ_tri + rec.vertices.shape[0]])
    frags, _ = rasterize_fragments(v, tri, scene.camera.resized(resolution).clip_from_world(), (height, width),
                                   samples=1, dtype=np.float64)
    kind = np.zeros(height * width, dtype=np.int8)
    if len(frags):
        order = np.lexsort((frags.depth, frags.texel))
        texel = frags.texel[order]
        first = np.ones(texel.shape[0], bool)
        first[1:] = texel[1:] != texel[:-1]
        sel = order[first]
    else:
        sel = np.zeros(0, np.intp)
    texel, tri_id = frags.texel[sel], frags.triangle[sel]
    is_rec = tri_id < rec.triangles.shape[0]
    kind[texel] = np.where(is_rec, RECEIVER, OCCLUDER)
    pixel = texel[is_rec]
    pos = frags.position[sel][is_rec].astype(np.float64)
    # Face normals of the receiver triangles (two-sided Lambert).
    t = rec.triangles[tri_id[is_rec]]
    p0, p1, p2 = (rec.vertices[t[:, k]] for k in range(3))
    n = np.cross(p1 - p0, p2 - p0)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    if getattr(scene.light, "kind", "directional") == "directional":
        to_light = np.broadcast_to(-scene.light.direction, pos.shape)
    else:
        d = scene.light.center - pos
        to_light = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-30)
    lambert = np.abs(np.einsum("ij,ij->i", n, to_light))
    return GBuffer(resolution=(width, height), kind=kind.reshape(height, width), pixel=pixel,
                   position=pos, lambert=lambert, normal=n)


def depth_gbuffer(receiver_vertices, receiver_triangles, clip_from_world, size, occluder_vertices=None,
                  occluder_triangles=None) -> GBuffer:
    """Receiver world positions per camera pixel from a depth buffer (VWSS §4's G-buffer pass).

    Receivers and occluders are rasterized separately in float64; a pixel is a
    receiver where the receiver's depth is below 1 and not behind the occluder's,
    an occluder where only the occluder is in front. Its world position is the pixel
    centre at that depth, unprojected with the inverse of ``clip_from_world``
    (:func:`moments_ref.scene.raster.unproject_points`).

    Parameters
    ----------
    receiver_vertices, receiver_triangles : mesh of the receivers
    clip_from_world : (4, 4) camera matrix
    size : (H, W) or int
    occluder_vertices, occluder_triangles : optional mesh of the occluders, which
        hide the receiver where they are in front.

    Returns
    -------
    GBuffer without ``lambert`` and ``normal`` (every receiver pixel, none left out).
    """
    m = real_input(clip_from_world, "clip_from_world", dtype=np.float64)
    drec = rasterize_depth(receiver_vertices, receiver_triangles, m, size, dtype=np.float64)[0][..., 0]
    h, w = drec.shape
    if occluder_vertices is not None:
        docc = rasterize_depth(occluder_vertices, occluder_triangles, m, size, dtype=np.float64)[0][..., 0]
    else:
        docc = np.ones_like(drec)
    rec = (drec < 1) & (drec <= docc)
    occ = (docc < 1) & ~rec
    z = np.where(rec, drec, docc)
    row, col = np.mgrid[0:h, 0:w]
    pos = unproject_points(np.stack([col + 0.5, row + 0.5], axis=-1), z, m, (h, w))
    kind = np.where(rec, RECEIVER, np.where(occ, OCCLUDER, BACKGROUND)).astype(np.int8)
    return GBuffer(resolution=(w, h), kind=kind, pixel=np.flatnonzero(rec), position=pos[rec])


#: Receiver-slope bias in shadow-map texels (see :func:`light_projection`): the
#: farthest a tap of the 9×9 footprint reaches along any direction (4√2 texels on
#: the diagonal) plus half a texel diagonal for the fragment's position in its texel.
SLOPE_BIAS_TEXELS = 4.5 * 2**0.5


def _plane_gradient(position, normal, clip_from_world, size):
    """(∂depth/∂u, ∂depth/∂v) along the receiver plane at each point, light-space depth per texel.

    Two tangents of the surface are projected into the shadow map; the depth
    gradient with respect to texel coordinates solves the 2×2 system of their
    texel offsets. A projective map takes the plane to a plane in (u, v, depth),
    so the gradient is the same at every point of a planar receiver. Grazing
    surfaces (singular system) give non-finite entries.
    """
    a = np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(normal, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(normal, t1)
    scale = 1e-3 * max(1.0, float(np.abs(position).max()))
    xy0, z0 = project_points(position, clip_from_world, size)
    xy1, z1 = project_points(position + scale * t1, clip_from_world, size)
    xy2, z2 = project_points(position + scale * t2, clip_from_world, size)
    j = np.stack([xy1 - xy0, xy2 - xy0], axis=1)  # (N, 2 tangents, 2 texel axes)
    dz = np.stack([z1 - z0, z2 - z0], axis=1)
    det = j[:, 0, 0] * j[:, 1, 1] - j[:, 0, 1] * j[:, 1, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        gx = (dz[:, 0] * j[:, 1, 1] - dz[:, 1] * j[:, 0, 1]) / det
        gy = (dz[:, 1] * j[:, 0, 0] - dz[:, 0] * j[:, 1, 0]) / det
    return np.stack([gx, gy], axis=-1)


def _depth_gradient(plane):
    """The :func:`_plane_gradient` ``plane`` with grazing surfaces set to zero (no receiver plane: a single depth)."""
    return np.where(np.isfinite(plane).all(axis=-1, keepdims=True), plane, 0.0)


def _depth_slope(plane):
    """|∂depth/∂(texel)| along the receiver plane at each point (light-space depth per texel).

    The length of the :func:`_plane_gradient` ``plane``; grazing surfaces
    (singular system) get the largest finite slope.
    """
    with np.errstate(invalid="ignore", over="ignore"):
        slope = np.hypot(*plane.T)
    finite = np.isfinite(slope)
    return np.where(finite, slope, slope[finite].max() if finite.any() else 0.0)


def _inside_map(g, clip_from_world, size):
    """Texel coordinates and depth of ``g``'s receiver points, and which of them fall inside the shadow map."""
    h, w = size
    xy, depth = project_points(g.position, clip_from_world, (h, w))
    inside = (np.isfinite(depth) & (depth >= -1) & (depth <= 1)
              & (xy[:, 0] >= 0) & (xy[:, 0] <= w) & (xy[:, 1] >= 0) & (xy[:, 1] <= h))
    return xy, depth, inside


def _refuse_unshaded(g, inside, camera, what):
    """:class:`InputError` saying why no receiver pixel of ``g`` is shaded, unless one is."""
    if inside.any():
        return
    w, h = g.resolution
    seen = np.bincount(g.kind.reshape(-1), minlength=4)
    reason = (f"the {g.pixel.size} receiver pixels it sees lie outside the light's shadow map" if g.pixel.size else
              f"it sees only occluders ({seen[OCCLUDER]} pixels): the receivers are out of view, edge-on, of zero "
              "area or hidden (is the eye inside an occluder?)" if seen[OCCLUDER] else
              "it sees no geometry: the receivers are out of view, edge-on or of zero area, or the field of view "
              "is too narrow or too wide")
    view = "" if camera is None else f" (eye {camera.eye.tolist()}, target {camera.target.tolist()}, fov {camera.fov})"
    raise InputError(f"camera: shades no pixel of {what} at {w}×{h}{view}: {reason}; nothing to measure")


def check_shaded(scene, resolution, clip_from_world, size, what=None):
    """Refuse (:class:`InputError`, with the reason) a scene whose camera shades no receiver pixel.

    Exact, not conservative: the camera's G-buffer at ``resolution``
    (:func:`camera_gbuffer`) and its projection into the ``size`` shadow map of
    ``clip_from_world`` (:func:`light_projection`) are computed as the pipeline computes
    them, and at least one receiver pixel must be seen (not hidden by an occluder)
    and inside the shadow map. Costs one G-buffer pass, whose result it returns (a
    run of the same scene and resolution can take it instead of rendering it again:
    :class:`moments_ref.pipeline.Settings`'s ``camera_gbuffer``).
    """
    g = camera_gbuffer(scene, resolution)
    _refuse_unshaded(g, _inside_map(g, clip_from_world, size)[2], scene.camera,
                     what or f"the receivers of scene {getattr(scene, 'name', '?')!r}")
    return g


@renamed_keywords(view_proj="clip_from_world")
def light_projection(g, clip_from_world, size):
    """Texel coordinates, unbiased depth, depth gradient and slope of the receiver points in the shadow map.

    ``z_ndc_light`` is the NDC depth itself; ``gradient`` the signed depth change per
    texel along the receiver (:func:`_depth_gradient`), the receiver plane of the
    reference; ``slope`` its length (:func:`_depth_slope`), from which
    :func:`z_ndc_lookup` forms the receiver-slope bias of PCF.
    """
    xy, depth, inside = _inside_map(g, clip_from_world, size)
    _refuse_unshaded(g, inside, None, "the receivers")  # (checked before the run by check_shaded)
    kind = g.kind.reshape(-1).copy()
    kind[g.pixel[~inside]] = OUTSIDE_LIGHT
    pos, nrm = g.position[inside], g.normal[inside]
    plane = _plane_gradient(pos, nrm, clip_from_world, tuple(size))  # once: the gradient and its length
    gradient, slope = _depth_gradient(plane), _depth_slope(plane)
    return GBuffer(resolution=g.resolution, kind=kind.reshape(g.kind.shape), pixel=g.pixel[inside],
                   position=pos, lambert=g.lambert[inside], normal=nrm,
                   uv=xy[inside], z_ndc_light=depth[inside], slope=slope, gradient=gradient)


def z_ndc_lookup(g, slope_bias):
    """The light-NDC depth a shadow lookup compares, before the technique's constant bias.

    ``g.z_ndc_light − SLOPE_BIAS_TEXELS · g.slope`` when ``slope_bias`` (PCF: HPG17
    §5's "higher depth bias"), else ``g.z_ndc_light`` (the filterable
    techniques: HPG17 §5's constant 10⁻³ alone). The slope term is
    ``SLOPE_BIAS_TEXELS`` (4.5√2) texels times the depth change per texel: without
    it a plane lit at an angle has half of a 9×9 filter footprint in front of its
    own fragment and the unbiased 9×9 PCF is 0.5 there (surface acne). The
    reference does without it: it compares each tap with the receiver plane
    (``g.gradient``, :func:`moments_ref.techniques.pcf.pcf_filtered`).
    """
    return g.z_ndc_light - SLOPE_BIAS_TEXELS * g.slope if slope_bias else g.z_ndc_light


#: Old name (DeprecationWarning): receiver_depth -> z_ndc_lookup.
__getattr__ = renamed("scene.gbuffer")
