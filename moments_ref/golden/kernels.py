"""Kernel golden cases: whole shadow maps in, the texture a compute shader writes out.

``moments-ref conformance --kernel`` runs a compute shader on these cases
(:mod:`moments_ref.conformance.kernel`); ``verify`` and ``oracle.check`` read them
like every other case. A row is one texel of the output, so the one comparator
(:mod:`moments_ref.golden.compare`) judges a kernel texel by texel.

* ``kernel-filter-nlq64``, ``-nlq32``, ``-msm64``, ``-moments``: the HPG17 §4.1
  filter kernel on a multisampled shadow map of several 32×24 blocks whose sides
  are not multiples of the block (partial blocks at the right and bottom), with
  occluder edges on block boundaries, thin occluders, foliage, two layers per
  texel and a flat region where Φ is ill-conditioned. Inputs: ``depth`` (H·W, 4),
  the four samples of each texel in row-major order (``kwargs`` give H and W),
  and ``zf`` (H·W, 4), four fragment depths per texel at which the texel is
  shaded. The kernel resolves b(z), blurs with the 9² Gaussian (σ = 2.4,
  clamp-to-edge) and writes the texel; the harness decodes it and shades it:
  ``intensity`` (H·W, 4) = unpack64/unpack32 + Algorithm 3 (NLQ, after
  ``BIAS_FLOAT32`` and Φ in the kernel), or ``decode_unorm16`` +
  ``BIAS_UNORM16`` + Algorithm 1 (the 64-bit MSM of the optimized basis). The
  decode runs in float64, so the intensity measures the kernel's codes alone.
  ``-moments`` compares the filtered moments (H·W, 4) themselves (RGBA32F).
* ``kernel-vwss-points``: VWSS Listing 2, points reprojected into 8 light views
  and z-buffered by an atomic maximum on integer keys of the reversed depth
  ``r = (1 − z_ndc)/2`` (:func:`moments_ref.techniques.vwss.warp.depth_key`, the
  paper's ``asuint`` with the sign transform: no depth is clipped, as in the
  listing, so points behind the far plane have r < 0 and must lose). Inputs
  ``points`` (N, 4) (w = 1) and ``views`` (8, 4, 4); the output ``depth`` (8·H·W,)
  is each texel's largest r, :data:`EMPTY_DEPTH` where no point landed.

Expected values: the global float64 path (:func:`moments_ref.gpu.filtering.blur`
of :func:`~moments_ref.gpu.filtering.resolve_moments`, then the chain in float64)
and ``np.maximum.at`` on the keys of float64 projections. Tolerances: the
spread of legitimate kernels (:mod:`moments_ref.golden.spread`), including the
float32 filters of :mod:`moments_ref.gpu.filter32` (sums regrouped, powers,
weights from a GPU ``exp``), Ψ4's two logarithms a few ulps off, Φ on moments a
few ulps apart, and float32 projections in other operation orders. The codes of
the quantized formats are stored too (``texels`` and ``texels_acceptable``, the
codes of the legitimate kernels): the harness reports them, and the intensity
decides, since Φ's conditioning lets correct kernels store other codes.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..gpu import filter32, fused32
from ..gpu.filtering import blur, resolve_moments
from ..moments import BIAS_FLOAT32, BIAS_UNORM16, bias_moments
from . import cells
from ._rows import Rows

__all__ = ["KERNEL_CASES", "FILTER_FORMATS", "MAPS", "EMPTY_DEPTH", "VWSS_MAP", "case_specs", "filter_codes",
           "vwss_reference", "decode_intensity", "kernel_kwargs", "view_matrices", "cell_variant"]

#: Output formats of the filter kernel: name -> (texel dtype, components per texel).
FILTER_FORMATS = {"nlq64": ("uint16", 4), "nlq32": ("uint32", 1), "msm64": ("uint16", 4), "moments": ("float32", 4)}
#: Map size (H, W) of each filter case: several 32×24 blocks, sides not multiples of the block.
MAPS = {"nlq64": (53, 75), "nlq32": (41, 70), "msm64": (30, 40), "moments": (49, 66)}
#: Samples per texel of the filter cases (4× MSAA).
SAMPLES = 4
#: Fragment depths per texel at which the decoded texel is shaded.
ZF_PER_TEXEL = 4
#: Light views, map (H, W) and points of ``kernel-vwss-points``.
VWSS_MAP = (8, 40, 56)
#: (count, height range, half-size) of the point groups: receiver floor, occluders, points behind the far plane.
VWSS_GROUPS = ((1300, (0.0, 0.0), 1.6), (900, (0.9, 1.3), 0.6), (300, (1.95, 2.05), 0.3), (700, (-0.6, -0.2), 1.7))
VWSS_POINTS = sum(g[0] for g in VWSS_GROUPS)
#: The decoded depth of a texel no point was written to (below every reversed depth the case has).
EMPTY_DEPTH = -4.0
#: Case names, in the order they are listed.
KERNEL_CASES = tuple(f"kernel-filter-{f}" for f in FILTER_FORMATS) + ("kernel-vwss-points",)


def _snap(z):
    """Depths on the grid k·2⁻²³ − 1: exact in float32, and so is the window depth (z + 1)/2."""
    return np.clip(np.round((np.asarray(z, np.float64) + 1) * 2.0**23) * 2.0**-23 - 1, -1, 1)


def _regions(h, w):
    """Boolean masks (H, W) of the map's regions and their comments, in painting order."""
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    u, v = (u + 0.5) / w, (v + 0.5) / h
    x, y = np.mgrid[0:h, 0:w][1], np.mgrid[0:h, 0:w][0]
    return {
        "box": ((u >= 0.25) & (u < 0.6) & (v >= 0.2) & (v < 0.65), "box occluder over the receiver"),
        "step": (u + 0.5 * v > 1.0, "second occluder behind a slanted edge crossing blocks"),
        "lines": (((x == 31) | (x == 32)) & (v > 0.05) & (v < 0.9) | ((y == 23) | (y == 24)) & (u > 0.1),
                  "thin occluders on the block boundaries x = 32 and y = 24"),
        "foliage": ((u >= 0.7) & (v < 0.3), "independent uniform sample depths (foliage) at the map's edge"),
        "layers": ((u < 0.2) & (v > 0.6), "two layers at -0.9 and 0.95 mixed per sample"),
        "flat": ((u >= 0.3) & (u < 0.5) & (v >= 0.75), "nearly constant depth 0.3 (Φ ill-conditioned)"),
    }


def filter_map(rng, h, w, samples=SAMPLES):
    """A multisampled depth map for the filter cases: (H, W, S) float64 on the float32 grid, and each texel's region."""
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    u, v = (u + 0.5) / w, (v + 0.5) / h
    base = -0.1 + 0.3 * u + 0.2 * v
    z = base[..., None] + rng.uniform(-2e-3, 2e-3, (h, w, samples))
    region = np.full((h, w), "receiver", dtype="U8")
    for name, (mask, _) in _regions(h, w).items():
        region[mask] = name
        m = mask[..., None]
        if name == "box":
            z = np.where(m, -0.6 + 0.1 * u[..., None] + rng.uniform(-2e-3, 2e-3, z.shape), z)
        elif name == "step":
            z = np.where(m, z - 0.35, z)
        elif name == "lines":
            z = np.where(m, -0.7 + rng.uniform(-1e-3, 1e-3, z.shape), z)
        elif name == "foliage":
            z = np.where(m, rng.uniform(-0.8, 0.5, z.shape), z)
        elif name == "layers":
            z = np.where(m, np.where(rng.uniform(0, 1, z.shape) < 0.5, -0.9, 0.95), z)
        else:
            z = np.where(m, 0.3 + rng.uniform(-1e-5, 1e-5, z.shape), z)
    return _snap(z), region


def _filter_rows(h, w):
    def rows(rng, dtype):
        z, region = filter_map(rng, h, w)
        comments = {k: c for k, (_, c) in _regions(h, w).items()}
        comments["receiver"] = "tilted receiver, 4 jittered samples per texel"
        y, x = np.mgrid[0:h, 0:w]
        border = (x < 4) | (y < 4) | (x >= w - 4) | (y >= h - 4)
        stiff = np.isin(region, ("flat", "layers"))
        category = np.where(border, "edge", np.where(stiff, "stiff", "random")).ravel()
        comment = [comments[r] + (" (within 4 texels of the map's border: clamp-to-edge taps)" if b else "")
                   for r, b in zip(region.ravel(), border.ravel())]
        mean = z.mean(axis=-1).reshape(-1, 1)
        offsets = np.array([-0.1, 0.002, 0.05])[None]
        zf = np.concatenate([mean + offsets, rng.uniform(-1, 1, (h * w, 1))], axis=1)
        depth = z.reshape(h * w, -1)
        return Rows({"depth": depth, "zf": np.clip(zf, -1, 1)}, list(category), comment)

    return rows


def _moments64(depth, h, w):
    return blur(resolve_moments(np.asarray(depth, np.float64).reshape(h, w, -1))).reshape(h * w, 4)


def filter_codes(fmt, moments, v2_cell=cells.DEFAULT_CELL):
    """The texels a kernel writes for float moments (n, 4): codes in the moments' dtype (not for "moments").

    ``v2_cell``: the √v2 grid of a 32-bit texel (:mod:`moments_ref.golden.cells`).
    """
    from ..affine import encode_unorm16
    from ..nonlinear import phi
    from ..packing import nlq_texels

    if fmt == "msm64":
        return encode_unorm16(moments)
    texels = nlq_texels(moments, fmt)
    if fmt == "nlq32" and v2_cell != cells.DEFAULT_CELL:
        texels = cells.recode(texels, phi(bias_moments(moments, BIAS_FLOAT32))[..., 2], v2_cell)
    return texels


def decode_intensity(fmt, texels, zf, v2_cell=cells.DEFAULT_CELL):
    """Shade decoded texels at the fragment depths ``zf`` (n, K) in float64: (n, K) intensities.

    NLQ: unpack64 / unpack32 and Algorithm 3 (HPG17); msm64: ``decode_unorm16``,
    ``BIAS_UNORM16`` and the lower bound of Algorithm 1. ``v2_cell``: the √v2 grid of a
    32-bit texel (:mod:`moments_ref.golden.cells`).
    """
    from ..affine import decode_unorm16
    from ..msm import shadow_intensity
    from ..nonlinear import shade
    from ..packing import unpack32, unpack64

    zf = np.asarray(zf, np.float64)
    if fmt == "msm64":
        b = bias_moments(decode_unorm16(np.asarray(texels, np.uint16)), BIAS_UNORM16)
        return shadow_intensity(np.broadcast_to(b[:, None, :], zf.shape + (4,)), zf)
    r = unpack64(np.asarray(texels, np.uint16)) if fmt == "nlq64" else unpack32(np.asarray(texels, np.uint32))
    if fmt == "nlq32" and v2_cell != cells.DEFAULT_CELL:
        r[..., 2] = cells.decode_v2(texels, v2_cell)
    return shade(np.broadcast_to(r[:, None, :], zf.shape + (4,)), zf)


def _filter_reference(fmt, h, w, cell=cells.DEFAULT_CELL):
    def reference(depth, zf):
        dt = np.asarray(depth).dtype
        if dt == np.float32:
            m = filter32.filter_float32(np.asarray(depth).reshape(h, w, -1)).reshape(h * w, 4)
        else:
            m = _moments64(depth, h, w)
        if fmt == "moments":
            return (m.astype(dt),)
        # The decode is float64 (it measures the codes alone); the result in the inputs' dtype (the policy).
        return (decode_intensity(fmt, filter_codes(fmt, m.astype(dt), cell), zf, cell).astype(dt),)

    return reference


def _xi_perturbed(r, sign):
    """ξ4 moved as Ψ4's two logarithms 3 ulps off move it (relative ``3 eps · a (1 + |ln a|)``, a = ln(ξ4 1e7))."""
    out = np.array(r, np.float64)
    a = np.log(np.maximum(out[:, 3], 1.2e-7) * 1e7)
    eps = float(np.finfo(np.float32).eps)
    out[:, 3] *= 1 + sign * 3 * eps * a * (1 + np.abs(np.log(a)))
    return out.astype(np.float32)


@lru_cache(maxsize=8)
def _variant_texels(fmt, h, w, key, depth_bytes, cell=cells.DEFAULT_CELL):
    """Codes of the legitimate float32 kernels for one map (cached: the spread and the code table share them);
    ``cell``: the declared √v2 grid of a 32-bit texel, whose code a float32 kernel may also round in float32."""
    from ..nonlinear import phi
    from ..packing import pack32, pack64

    depth = np.frombuffer(depth_bytes, np.float32).reshape(h, w, -1)
    found = []
    for m in filter32.variant_moments(depth).values():
        found.append(filter_codes(fmt, m.reshape(h * w, 4), cell))
    m0 = filter32.filter_float32(depth).reshape(h * w, 4)
    nudge = np.where(np.arange(4) % 2 == 0, 1, -1).astype(np.float32)
    for s in (1, -1):  # Φ or the optimized basis on moments 2 ulps apart (fma, other formulas)
        found.append(filter_codes(fmt, (m0 + s * nudge * 2 * np.spacing(m0)).astype(np.float32), cell))
    if fmt in ("nlq64", "nlq32"):
        r = phi(bias_moments(m0, BIAS_FLOAT32))
        pack = pack64 if fmt == "nlq64" else pack32
        xi = [pack(_xi_perturbed(r, s)) for s in (1, -1)]
        if fmt == "nlq32" and cell != cells.DEFAULT_CELL:
            xi = [cells.recode(t, r[:, 2], cell) for t in xi]
            xi.append(cells.recode(pack(r), r[:, 2], cell, np.float32))  # √v2's code rounded in float32
        found += xi
        # The bias and Φ as a compiler contracts and reassociates them (either product of each sum fused).
        for s in fused32.CONTRACTIONS:
            rf = fused32.phi_fused(fused32.bias_fused(m0, BIAS_FLOAT32, s), s)
            t = pack(rf)
            found.append(cells.recode(t, rf[:, 2], cell) if fmt == "nlq32" and cell != cells.DEFAULT_CELL else t)
    return tuple(found)


def _texels_of(fmt, h, w, depth, cell=cells.DEFAULT_CELL):
    d = np.ascontiguousarray(np.asarray(depth, np.float32))
    return _variant_texels(fmt, h, w, (fmt, h, w), d.tobytes(), cell)


def _filter_spread(fmt, h, w, cell=cells.DEFAULT_CELL):
    def hook(inputs, dt):
        if np.dtype(dt) != np.float32:
            return []
        depth = inputs["depth"]
        if fmt == "moments":
            return [(m.reshape(h * w, 4),) for m in filter32.variant_moments(
                np.asarray(depth, np.float32).reshape(h, w, -1)).values()]
        return [(decode_intensity(fmt, t, inputs["zf"], cell),) for t in _texels_of(fmt, h, w, depth, cell)]

    return hook


def _filter_extra(fmt, h, w, cell=cells.DEFAULT_CELL):
    """``texels`` (the float32 reference kernel's codes) and ``texels_acceptable`` (n, K, ...) of the variants."""
    def extra(inputs):
        depth = np.asarray(inputs["depth"], np.float32)
        ref = filter_codes(fmt, _moments64(depth, h, w).astype(np.float32), cell)
        alts = [ref] + list(_texels_of(fmt, h, w, depth, cell))
        return {"texels": ref, "texels_acceptable": np.stack(alts, axis=1)}

    return extra


def cell_variant(h, w):
    """The 32-bit filter case for a profile's ``[format] v2_cell`` (:mod:`moments_ref.golden.cells`): the
    reference, spread and expected codes of the same kernel storing √v2 on the declared grid."""
    def variant(fmt=None, **_):
        cell = (fmt or {}).get("v2_cell", cells.DEFAULT_CELL)
        if cell == cells.DEFAULT_CELL:
            return {}
        return {"reference": _filter_reference("nlq32", h, w, cell), "spread_hook": _filter_spread("nlq32", h, w, cell),
                "extra": _filter_extra("nlq32", h, w, cell)}

    return variant


def kernel_kwargs(name):
    """The plain values a kernel case gives a port (``kwargs`` of the manifest)."""
    if name == "kernel-vwss-points":
        v, h, w = VWSS_MAP
        return {"views": v, "height": h, "width": w, "points": VWSS_POINTS, "empty_depth": EMPTY_DEPTH,
                "window": "x = (x_ndc + 1) W/2, y = (1 - y_ndc) H/2, texel (floor(y), floor(x))",
                "depth": "reversed r = (1 - z_ndc)/2, not clipped; key = depth_key(r)", "views_per_dispatch": 4}
    fmt = name.rsplit("-", 1)[1]
    h, w = MAPS[fmt]
    kw = {"height": h, "width": w, "samples": SAMPLES, "format": fmt, "block": [32, 24], "guard": 4,
          "threads": 256, "taps": 9, "sigma": 2.4, "depth_texture": "window depth d = (z + 1)/2"}
    if fmt in ("nlq64", "nlq32"):
        kw["bias"] = {"alpha": BIAS_FLOAT32.alpha, "target": list(BIAS_FLOAT32.target)}
    return kw


def _filter_specs():
    specs = []
    what = {"nlq64": "BIAS_FLOAT32 -> Φ (Algorithm 2) -> pack64 (RGBA16UI codes); decoded: unpack64 -> Algorithm 3",
            "nlq32": "BIAS_FLOAT32 -> Φ (Algorithm 2) -> pack32 (R32UI); decoded: unpack32 -> Algorithm 3",
            "msm64": "encode_unorm16 of the optimized basis (RGBA16UI codes); decoded: decode_unorm16 -> "
                     "BIAS_UNORM16 -> Algorithm 1 (lower bound)",
            "moments": "the filtered moments b1..b4 (RGBA32F)"}
    for fmt, (h, w) in MAPS.items():
        moments = fmt == "moments"
        specs.append(dict(
            name=f"kernel-filter-{fmt}", function=f"kernels.filter_{fmt}", dtype="float32", inputs=("depth", "zf"),
            outputs=("moments",) if moments else ("intensity",), rows=_filter_rows(h, w),
            reference=_filter_reference(fmt, h, w), truth=None, kwargs=kernel_kwargs(f"kernel-filter-{fmt}"),
            value_range=None if moments else (0, 1), spread_hook=_filter_spread(fmt, h, w),
            extra=None if moments else _filter_extra(fmt, h, w),
            **({"variant": cell_variant(h, w), "profile_keys": ("format",)} if fmt == "nlq32" else {}),
            description=f"HPG17 §4.1 filter kernel on a {h}×{w} map of 4× MSAA depths (several 32×24 blocks, "
                        f"partial blocks, edges): resolve b(z) -> 9² Gaussian (sigma 2.4, clamp-to-edge) -> "
                        + what[fmt]))
    return specs


def view_matrices():
    """The 8 view-projection matrices of ``kernel-vwss-points`` (a square area light above the scene), float64."""
    from ..scene.lights import AreaLight
    from ..techniques.vwss.lights import light_views

    light = AreaLight(center=[0.0, 3.0, 0.0], normal=[0.0, -1.0, 0.0], width=1.2, height=1.2, up=[0.0, 0.0, 1.0],
                      fov=70.0)
    return light_views(light, VWSS_MAP[0], near=1.0, far=3.2, seed=7).clip_from_world


def _vwss_points(rng, views):
    """Points whose projections keep 0.05 texel from every texel edge and 1e-3 from r = 0 in every view."""
    v, h, w = VWSS_MAP
    pts = []
    for count, (lo, hi), size in VWSS_GROUPS:
        found = np.zeros((0, 3))
        while len(found) < count:
            p = np.column_stack([rng.uniform(-size, size, 4 * count), rng.uniform(lo, hi, 4 * count),
                                 rng.uniform(-size, size, 4 * count)])
            found = np.concatenate([found, p[_clear(p, views, h, w)]])[:count]
        pts.append(found)
    p = np.concatenate(pts)
    return np.column_stack([p.astype(np.float32).astype(np.float64), np.ones(len(p))])


def _clear(p, views, h, w):
    clip = np.einsum("vij,nj->nvi", views, np.column_stack([p, np.ones(len(p))]))
    cw = clip[..., 3]
    x = (clip[..., 0] / cw + 1) * w / 2
    y = (1 - clip[..., 1] / cw) * h / 2
    r = 0.5 - 0.5 * clip[..., 2] / cw
    fx, fy = x - np.floor(x), y - np.floor(y)
    away = (np.minimum(fx, 1 - fx) > 0.05) & (np.minimum(fy, 1 - fy) > 0.05) & (np.abs(r) > 1e-3)
    return ((cw > 0.1) & away).all(axis=1)


def _vwss_rows(rng, dtype):
    views = view_matrices()
    points = _vwss_points(rng, views)
    depth = vwss_reference(points, views.astype(np.float32) if dtype == np.float32 else views)[0]
    hits = _vwss_hits(points, views)
    v, h, w = VWSS_MAP
    category = np.where(hits == 0, "edge", np.where(hits > 1, "stiff", "random"))
    far = (depth < 0) & (hits > 0)
    comment = np.where(hits == 0, "empty texel: no point lands here (keeps the clear key 0)",
                       np.where(far, "only points behind the far plane (r < 0): the sign transform orders them",
                                np.where(hits > 1, "several points: the atomic maximum keeps the nearest",
                                         "one point")))
    return Rows({"points": points, "views": views}, list(category), list(comment))


def _project(points, views):
    """(texel index, reversed depth r) of every (point, view) pair inside a map, in the inputs' dtype."""
    from ..techniques.vwss.warp import project_to_texels

    v, h, w = VWSS_MAP
    p = np.asarray(points)
    return project_to_texels(p[:, :3], np.asarray(views, p.dtype), (h, w), clip_depth=False)


def _vwss_hits(points, views):
    v, h, w = VWSS_MAP
    idx, _ = _project(np.asarray(points, np.float64), views)
    return np.bincount(idx, minlength=v * h * w)


def vwss_reference(points, views):
    """VWSS Listing 2 in NumPy: ``np.maximum.at`` on the keys of the reversed depths.

    Returns each texel's largest r (EMPTY_DEPTH where none), in the points' dtype.
    """
    from ..techniques.vwss.warp import EMPTY_KEY, depth_key, key_depth

    v, h, w = VWSS_MAP
    idx, r = _project(points, views)
    keys = np.full(v * h * w, EMPTY_KEY, np.uint32)
    np.maximum.at(keys, idx, depth_key(r))
    dt = np.asarray(points).dtype
    return (np.where(keys == EMPTY_KEY, EMPTY_DEPTH, key_depth(keys)).astype(dt),)


def _vwss_spread(inputs, dt):
    """Projections in other operation orders (float32, x/w first) and points 3 ulps apart."""
    if np.dtype(dt) != np.float32:
        return []
    p = np.asarray(inputs["points"], np.float64)
    m = np.asarray(inputs["views"], np.float64)
    eps = float(np.finfo(np.float32).eps)
    found = []
    for s in (3, -3):
        q = p.copy()
        q[:, :3] *= 1 + s * eps
        found.append(vwss_reference(q.astype(np.float32), m.astype(np.float32)))
    # GPU-style order: clip = M·p as four products summed left to right, then x/w.
    clip = np.zeros((p.shape[0], m.shape[0], 4), np.float32)
    pf, mf = p.astype(np.float32), m.astype(np.float32)
    for k in range(4):
        clip += pf[:, None, k:k + 1] * mf[None, :, :, k]
    found.append((_vwss_from_clip(clip),))
    return found


def _vwss_from_clip(clip):
    from ..techniques.vwss.warp import EMPTY_KEY, depth_key, key_depth

    v, h, w = VWSS_MAP
    f = np.float32
    cw = clip[..., 3]
    x = ((clip[..., 0] / cw + f(1)) * f(0.5)) * f(w)
    y = ((f(1) - clip[..., 1] / cw) * f(0.5)) * f(h)
    r = f(0.5) - f(0.5) * (clip[..., 2] / cw)
    ok = (cw > 0) & (x >= 0) & (x < w) & (y >= 0) & (y < h)
    view = np.broadcast_to(np.arange(v)[None], ok.shape)
    idx = (view[ok] * h + np.floor(y[ok]).astype(np.intp)) * w + np.floor(x[ok]).astype(np.intp)
    keys = np.full(v * h * w, EMPTY_KEY, np.uint32)
    np.maximum.at(keys, idx, depth_key(r[ok]))
    return np.where(keys == EMPTY_KEY, EMPTY_DEPTH, key_depth(keys)).astype(np.float32)


def _vwss_spec():
    v, h, w = VWSS_MAP
    return dict(
        name="kernel-vwss-points", function="kernels.vwss_points", dtype="float32", inputs=("points", "views"),
        outputs=("depth",), rows=_vwss_rows, reference=vwss_reference, truth=None,
        kwargs=kernel_kwargs("kernel-vwss-points"), perturb=False, row_inputs=False, spread_hook=_vwss_spread,
        description=f"VWSS Listing 2: {VWSS_POINTS} points reprojected into {v} light views of {h}×{w} texels, "
                    "z-buffered by an atomic maximum on depth_key(r), r = (1 - z_ndc)/2 not clipped; one row per "
                    f"texel, the largest r ({EMPTY_DEPTH:g} where no point landed)")


def case_specs():
    """Keyword dicts for :class:`moments_ref.golden.cases.Case`, one per kernel case."""
    return _filter_specs() + [_vwss_spec()]
