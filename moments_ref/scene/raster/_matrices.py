"""Sample patterns, view and projection matrices, projection of points (OpenGL conventions).

Part of :mod:`moments_ref.scene.raster` (see its docstring for the conventions).
"""

from __future__ import annotations

import numpy as np

from ..._arrays import InputError, real_input
from ..._shim import renamed_keywords
from ..depth import ndc_from_window, window_from_ndc

__all__ = ["SAMPLE_COUNTS", "SUBPIXEL_BITS", "MAX_SIZE", "sample_positions", "look_at", "orthographic", "frustum",
           "perspective", "project_points", "unproject_points"]

#: Supported MSAA sample counts.
SAMPLE_COUNTS = (1, 4, 8)
#: Sub-pixel precision of snapped vertex positions (Direct3D 11: 8 bits).
SUBPIXEL_BITS = 8
#: Largest supported map side (Direct3D 11's texture limit).
MAX_SIZE = 16384

_SUB = 1 << SUBPIXEL_BITS
_HALF = _SUB // 2
# D3D11_STANDARD_MULTISAMPLE_PATTERN, offsets from the pixel centre in 1/16 pixel (x right, y down).
_D3D11_PATTERN = {
    1: ((0, 0),),
    4: ((-2, -6), (6, -2), (-6, 2), (2, 6)),
    8: ((1, -3), (-1, 3), (5, 1), (-3, -5), (-5, 5), (-7, -1), (3, 7), (7, -7)),
}

# ---------------------------------------------------------------------------
# Sample patterns and matrices


def _check_samples(samples) -> int:
    try:
        s = int(samples)
        ok = s == samples and s in SAMPLE_COUNTS
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError(
            f"samples: expected one of the supported MSAA sample counts {SAMPLE_COUNTS}, got {samples!r}"
        )
    return s


def sample_positions(samples: int = 1) -> np.ndarray:
    """Sample offsets of the Direct3D 11 standard multisample pattern.

    Parameters
    ----------
    samples : int
        1, 4 or 8.

    Returns
    -------
    offsets : (samples, 2) float64 array
        Offsets ``(dx, dy)`` from the pixel centre in pixels, x to the right and
        y down (window coordinates), in sample order.

    Notes
    -----
    ``D3D11_STANDARD_MULTISAMPLE_PATTERN`` (Direct3D 11 documentation,
    ``D3D11_STANDARD_MULTISAMPLE_QUALITY_LEVELS``), in 1/16 pixel: 4×: (−2, −6),
    (6, −2), (−6, 2), (2, 6); 8×: (1, −3), (−1, 3), (5, 1), (−3, −5), (−5, 5),
    (−7, −1), (3, 7), (7, −7). All are multiples of 1/256 pixel, so the integer
    edge functions evaluate them exactly.

    Examples
    --------
    >>> sample_positions(4)[0]
    array([-0.125, -0.375])
    """
    s = _check_samples(samples)
    return np.asarray(_D3D11_PATTERN[s], dtype=np.float64) / 16.0


def _vec3(x, name):
    v = real_input(x, name, dtype=np.float64)
    if v.shape != (3,):
        raise InputError(f"{name}: expected 3 coordinates, got shape {v.shape}")
    return v


def look_at(eye, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """View matrix of a camera at ``eye`` looking at ``target`` (gluLookAt).

    Parameters
    ----------
    eye, target, up : (3,) float
        Camera position, the point it looks at, and the world direction that
        appears upwards.

    Returns
    -------
    view : (4, 4) float64 array
        World → view space: the camera sits at the origin looking along −z, with
        x to the right and y up.

    Raises
    ------
    InputError
        If ``eye == target`` or ``up`` is parallel to the viewing direction.
    """
    eye, target, up = _vec3(eye, "eye"), _vec3(target, "target"), _vec3(up, "up")
    f = target - eye
    nf = np.linalg.norm(f)
    if nf == 0:
        raise InputError(f"target: expected a point different from eye {eye.tolist()}, got the same point")
    f = f / nf
    s = np.cross(f, up)
    ns = np.linalg.norm(s)
    if ns <= 1e-12 * max(np.linalg.norm(up), 1e-300):
        raise InputError(f"up: expected a direction not parallel to target - eye {f.tolist()}, got {up.tolist()}")
    s = s / ns
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def _check_range(lo, hi, name_lo, name_hi):
    lo, hi = float(lo), float(hi)
    if not (np.isfinite(lo) and np.isfinite(hi) and hi != lo):
        raise InputError(f"{name_hi}: expected a finite value different from {name_lo}={lo}, got {hi}")
    return lo, hi


def orthographic(left, right, bottom, top, near, far) -> np.ndarray:
    """Orthographic projection (glOrtho): view box → NDC cube [−1, 1]³.

    Parameters
    ----------
    left, right, bottom, top : float
        View-space x and y extent of the box.
    near, far : float
        Distances of the near and far planes along −z (view space ``z = −near``
        maps to NDC depth −1, ``z = −far`` to +1).

    Returns
    -------
    proj : (4, 4) float64 array

    Notes
    -----
    Depth is linear in the distance: ``z_ndc = (2 d − far − near) / (far − near)``
    for a point at distance ``d`` in front of the light; directional lights use it.
    """
    l, r = _check_range(left, right, "left", "right")
    b, t = _check_range(bottom, top, "bottom", "top")
    n, f = _check_range(near, far, "near", "far")
    m = np.zeros((4, 4))
    m[0, 0], m[0, 3] = 2 / (r - l), -(r + l) / (r - l)
    m[1, 1], m[1, 3] = 2 / (t - b), -(t + b) / (t - b)
    m[2, 2], m[2, 3] = -2 / (f - n), -(f + n) / (f - n)
    m[3, 3] = 1.0
    return m


def frustum(left, right, bottom, top, near, far) -> np.ndarray:
    """Perspective projection of an (off-axis) frustum (glFrustum).

    Parameters
    ----------
    left, right, bottom, top : float
        Extent of the frustum's cross-section on the near plane (view space).
    near, far : float
        Positive distances of the near and far planes, ``0 < near < far``.

    Returns
    -------
    proj : (4, 4) float64 array

    Notes
    -----
    ``z_ndc = (far + near)/(far − near) − 2 far near / ((far − near) d)`` at
    distance ``d``: −1 on the near plane, +1 on the far plane, affine in 1/d.
    """
    l, r = _check_range(left, right, "left", "right")
    b, t = _check_range(bottom, top, "bottom", "top")
    n, f = float(near), float(far)
    if not (np.isfinite(n) and np.isfinite(f) and 0 < n < f):
        raise InputError(f"near, far: expected 0 < near < far, got near={near}, far={far}")
    m = np.zeros((4, 4))
    m[0, 0], m[0, 2] = 2 * n / (r - l), (r + l) / (r - l)
    m[1, 1], m[1, 2] = 2 * n / (t - b), (t + b) / (t - b)
    m[2, 2], m[2, 3] = -(f + n) / (f - n), -2 * f * n / (f - n)
    m[3, 2] = -1.0
    return m


def perspective(fovy, aspect, near, far) -> np.ndarray:
    """Symmetric perspective projection (gluPerspective).

    Parameters
    ----------
    fovy : float
        Vertical field of view in degrees, in (0, 180).
    aspect : float
        Width / height of the image.
    near, far : float
        ``0 < near < far``.

    Returns
    -------
    proj : (4, 4) float64 array
    """
    fovy, aspect = float(fovy), float(aspect)
    if not (0 < fovy < 180):
        raise InputError(f"fovy: expected a vertical field of view in (0, 180) degrees, got {fovy}")
    if not (np.isfinite(aspect) and aspect > 0):
        raise InputError(f"aspect: expected a positive finite width/height ratio, got {aspect}")
    t = float(near) * np.tan(np.radians(fovy) / 2)
    return frustum(-t * aspect, t * aspect, -t, t, near, far)


def _check_size(size) -> tuple[int, int]:
    try:
        hw = (size, size) if np.ndim(size) == 0 else tuple(size)
        h, w = (int(v) for v in hw)
        ok = len(hw) == 2 and all(int(v) == v for v in hw)
    except (TypeError, ValueError):
        ok = False
    if not ok or not (1 <= h <= MAX_SIZE and 1 <= w <= MAX_SIZE):
        raise InputError(
            f"size: expected a map size (H, W) or an int with 1 <= side <= {MAX_SIZE}, got {size!r}"
        )
    return h, w


def _check_matrix(clip_from_world) -> np.ndarray:
    m = real_input(clip_from_world, "clip_from_world", dtype=np.float64)
    if m.shape != (4, 4):
        raise InputError(f"clip_from_world: expected a (4, 4) matrix, got shape {m.shape}")
    return m


@renamed_keywords(view_proj="clip_from_world")
def project_points(points, clip_from_world, size):
    """Window coordinates and NDC depth of world points.

    Parameters
    ----------
    points : (..., 3) float array
        World positions.
    clip_from_world : (4, 4) float array
        ``projection @ view``.
    size : int or (H, W)
        Map size.

    Returns
    -------
    xy : (..., 2) float64 array
        Window coordinates in pixels, x right and y down; the point falls in
        texel ``(row, col) = (floor(y), floor(x))`` when that is inside the map.
    depth : (...) float64 array
        NDC depth ``z_clip / w_clip`` (in [−1, 1] inside the view volume).

    Notes
    -----
    Points behind a perspective camera (w ≤ 0) get NaN.
    """
    h, w = _check_size(size)
    m = _check_matrix(clip_from_world)
    p = real_input(points, "points", trailing=3, dtype=np.float64, finite=False)
    hom = _homogeneous(p, m)
    clip, cw = hom[..., :3], hom[..., 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        cw = np.where(cw > 0, cw, np.nan)
        ndc = clip / cw[..., None]
    return window_from_ndc(ndc, (h, w)), ndc[..., 2]


def unproject_points(xy_window, z_ndc, clip_from_world, size):
    """World positions of window positions and NDC depths: the inverse of :func:`project_points`.

    Parameters
    ----------
    xy_window : (..., 2) float array
        Window coordinates in pixels (x right, y down; pixel centres at ``+ 0.5``).
    z_ndc : (...) float array
        NDC depth.
    clip_from_world : (4, 4) float array
    size : (H, W)

    Returns
    -------
    (..., 3) float64 array: ``clip_from_world⁻¹ (x_ndc, y_ndc, z_ndc, 1)`` divided by its w.
    """
    h, w = size
    z = np.asarray(z_ndc, np.float64)
    ndc = np.concatenate([ndc_from_window(xy_window, (h, w)), z[..., None], np.ones_like(z)[..., None]], axis=-1)
    hom = ndc @ np.linalg.inv(clip_from_world).T
    return hom[..., :3] / hom[..., 3:]


def _clip_space(p, m):
    """Clip-space coordinates (4, ...) of world points given component-major, p (3, ...).

    ``x·m0 + y·m1 + z·m2 + m3`` per row, in this order (twelve multiply-adds over
    contiguous rows, in place; a BLAS matmul with a 3 × 4 operand is slower here).
    Called per chunk of triangles on their gathered vertices, so the arrays stay in
    cache and no array of the size of the whole mesh is allocated.
    """
    x, y, z = p
    c = np.empty((4,) + x.shape)
    t = np.empty_like(x)
    with np.errstate(invalid="ignore", over="ignore"):  # huge finite vertices overflow to inf
        for j in range(4):
            row = c[j]
            np.multiply(x, m[j, 0], out=row)
            row += np.multiply(y, m[j, 1], out=t)
            row += np.multiply(z, m[j, 2], out=t)
            row += m[j, 3]
    return c


def _homogeneous(p, m):
    """``m @ (p, 1)`` for points (..., 3) -> (..., 4), written out per row."""
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    return np.stack([x * m[j, 0] + y * m[j, 1] + z * m[j, 2] + m[j, 3] for j in range(4)], axis=-1)
