"""Shadow techniques: one module per technique, one shared interface, one registry.

Every technique is a :class:`Technique` with

* ``name`` and ``bits_per_texel`` (the storage cost HPG17 Figure 1 compares);
* ``depth_bias``: subtracted from the fragment depth before the lookup (HPG17 §5:
  "With non-linear quantization we use a constant depth bias of 10⁻³ depth
  units"; the other techniques use the same value so that differences in the
  report come from the techniques, not from the bias);
* ``prepare(depth_samples, params)``: the filtered texture built from the
  multisampled shadow map, a chain of named :class:`Step` s;
* ``shadow(texture, uv, depth, noise=None)``: the shadow intensity (the fraction of
  light blocked, 0 = lit, 1 = fully shadowed) of fragments at texel coordinates
  ``uv`` and depth ``depth``.

:mod:`moments_ref.pipeline` runs the same steps as cached stages (two techniques
whose chains start with the same step names share those results) and
:mod:`moments_ref.report` iterates over :func:`names` without special cases.

Conventions
-----------
``depth_samples`` is an ``(H, W, S)`` float array of sample depths in [-1, 1]
(:func:`moments_ref.raster.rasterize_depth`), or a :class:`LayeredSamples` (the
output of the translucency pass, :func:`moments_ref.techniques.translucent.translucency_pass`):
per sample a depth distribution of K layers with weights summing to 1. An opaque
map is the special case K = 1, weight 1.

``uv`` is ``(..., 2)`` in texels, u = x (column) and v = y (row), texel centres at
``i + 0.5`` (the convention of :mod:`moments_ref.bluenoise` and of the window
coordinates of :func:`moments_ref.raster.project_points`). ``depth`` is the
fragment's NDC depth in the light's view, broadcast against ``uv[..., 0]``.

Registering a technique
-----------------------
A further module builds a :class:`Technique` and calls :func:`register`; the
pipeline and the report pick it up by name. A technique that needs a light of a
particular kind says so in ``light_kinds``; one that needs several views sets
``multiview`` (its stage names must contain ``vwss`` for multi-view work, as
``stages.json`` promises).

Registered here, in this order: ``pcf``, ``vsm``, ``esm``, ``evsm64``,
``evsm128``, ``msm64``, ``msm128``, ``nlq64``, ``nlq32``, ``nlq64_dither``,
``nlq32_dither``, ``translucent_msm`` and ``msm_soft`` (moment soft shadow
mapping, :mod:`.msm_soft`, ``light_kinds=("area",)``). ``msm_soft`` is imported
here so that the registry does not depend on which modules a program happened
to import. Its texture step needs the area light, and its error is measured
against multi-view rasterization rather than the hard-shadow PCF, so
:mod:`moments_ref.pipeline` runs it with the other area-light outputs (PCSS,
VWSS, MVR: :data:`moments_ref.pipeline.AREA_OUTPUTS`), not through the
generic texture/lookup loop. The scattering techniques of :mod:`.scattering`
work in epipolar coordinates, not in shadow-map texels: they are not
registered (the report takes their rows from
:func:`moments_ref.techniques.scattering.report_rows`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from .._arrays import InputError, real_input

__all__ = [
    "Step",
    "Technique",
    "LayeredSamples",
    "register",
    "get",
    "names",
    "TECHNIQUES",
    "sample_count",
    "is_layered",
    "check_uv_depth",
    "bilinear_filtered",
]


@dataclass(frozen=True)
class LayeredSamples:
    """Per-sample depth distributions of a shadow map with translucent occluders.

    Attributes
    ----------
    depth : (H, W, S, K) float32 array
        Layer depths in [-1, 1], nearest first; unused layers hold 1 (far).
    weight : (H, W, S, K) float64 array
        Non-negative layer weights summing to 1 over K: the share of the light
        that layer k absorbs, ``α_k ∏_{l<k} (1 − α_l)``; the last used layer is the
        opaque surface (or the far plane) with the remaining transmittance.

    Notes
    -----
    Slides, "Translucent occluders": rendering to a moment shadow map with alpha
    blending, far to near, leaves exactly ``Σ_k weight_k b(depth_k)`` in each
    sample; ``Σ_{depth_k < zf} weight_k`` is one minus the product of the
    transmittances in front of ``zf``.
    """

    depth: np.ndarray
    weight: np.ndarray

    @property
    def shape(self):
        """``(H, W, S)``."""
        return self.depth.shape[:3]


def is_layered(samples) -> bool:
    """True for :class:`LayeredSamples` (translucency pass output)."""
    return isinstance(samples, LayeredSamples)


def sample_count(samples) -> int:
    """MSAA samples per texel of an (H, W, S) map or of :class:`LayeredSamples`."""
    return int(samples.shape[2])


@dataclass(frozen=True)
class Step:
    """One named stage of building a technique's texture.

    ``fn(x, params) -> y``. Equal names mean equal results for the same shadow
    map: the pipeline computes a name once and shares it between techniques.
    """

    name: str
    fn: Callable[[Any, dict], Any]


@dataclass(frozen=True)
class Technique:
    """A shadow technique behind the shared interface (module docstring).

    Attributes
    ----------
    name : str
    bits_per_texel : int
        Storage per shadow-map texel of the filtered texture.
    depth_bias : float
        Subtracted from the fragment depth in :meth:`shadow`.
    make_steps : callable ``(samples: int, layered: bool) -> tuple[Step, ...]``
        The steps from the shadow map to the texture for a map with ``samples``
        MSAA samples, opaque or layered. An empty chain means the texture is the
        shadow map itself (PCF).
    lookup : callable ``(texture, uv, zf, noise) -> intensity``
        Shadow intensity at the already biased depth ``zf``.
    description, reference : str
        One line each: what it is, where it comes from.
    needs_noise : bool
        Its lookup reads per-pixel blue noise (HPG17 §4.2).
    translucency : bool
        It renders translucent occluders with alpha blending (it then receives
        :class:`LayeredSamples` when the scene has translucent geometry);
        techniques without it see only the opaque occluders.
    requires_translucency : bool
        The report runs it only on scenes with translucent occluders.
    four_moments : bool
        It reconstructs from four moments (HPG17 §5: such techniques leak with
        three occluders in a filter region).
    light_kinds : tuple of str
        Light kinds it supports ("directional", "area"; an area light is used
        as a spot light from its centre).
    multiview : bool
        It renders several views of an area light.
    """

    name: str
    bits_per_texel: int
    depth_bias: float
    make_steps: Callable[[int, bool], tuple]
    lookup: Callable
    description: str = ""
    reference: str = ""
    needs_noise: bool = False
    translucency: bool = False
    requires_translucency: bool = False
    four_moments: bool = False
    light_kinds: tuple = ("directional", "area")
    multiview: bool = False
    defaults: dict = field(default_factory=dict)

    def steps(self, samples: int, layered: bool = False) -> tuple:
        """The :class:`Step` chain for a map with ``samples`` samples (layered or not)."""
        return tuple(self.make_steps(int(samples), bool(layered)))

    def prepare(self, depth_samples, params=None):
        """Build the filtered texture from the shadow map.

        Parameters
        ----------
        depth_samples : (H, W, S) float array or LayeredSamples
            The shadow map (module docstring). Layered input is accepted only by
            techniques with ``translucency``.
        params : dict, optional
            Overrides of :attr:`defaults` (scene parameters).

        Returns
        -------
        texture : array in the technique's storage format
        """
        layered = is_layered(depth_samples)
        if layered and not self.translucency:
            raise InputError(f"depth_samples: technique {self.name!r} does not render translucent occluders; "
                             "pass the opaque (H, W, S) depth map")
        if not layered:
            from ..filtering import check_depth_samples

            depth_samples = check_depth_samples(depth_samples)
        p = {**self.defaults, **(params or {})}
        x = depth_samples
        for step in self.steps(sample_count(depth_samples), layered):
            x = step.fn(x, p)
        return x

    def shadow(self, texture, uv, depth, noise=None):
        """Shadow intensity in [0, 1] of fragments (1 = fully shadowed).

        Parameters
        ----------
        texture : array
            Output of :meth:`prepare`.
        uv : (..., 2) float array
            Texel coordinates (module docstring).
        depth : (...) float array
            Fragment depth in the light's NDC; the technique's ``depth_bias`` is
            subtracted here.
        noise : (..., 2) float array in [0, 1], optional
            Per-fragment blue noise (:func:`moments_ref.bluenoise.frame_noise`);
            required when ``needs_noise``.

        Returns
        -------
        intensity : (...) float array
        """
        uv, zf = check_uv_depth(uv, depth)
        if self.needs_noise and noise is None:
            raise InputError(f"noise: technique {self.name!r} needs per-fragment blue noise (..., 2), got None")
        zf = zf - zf.dtype.type(self.depth_bias)
        return self.lookup(texture, uv, zf, noise)


def check_uv_depth(uv, depth):
    """Validate ``uv`` (..., 2) and ``depth`` broadcastable to ``uv[..., 0]``; float64 both."""
    uv = real_input(uv, "uv", trailing=2, dtype=np.float64)
    zf = real_input(depth, "depth", dtype=np.float64)
    try:
        shape = np.broadcast_shapes(uv.shape[:-1], zf.shape)
    except ValueError:
        raise InputError(f"depth: expected a shape broadcastable to uv.shape[:-1] {uv.shape[:-1]}, "
                         f"got {zf.shape}") from None
    return np.broadcast_to(uv, shape + (2,)), np.broadcast_to(zf, shape)


def bilinear_filtered(texture, uv, dtype=np.float32):
    """Hardware bilinear filtering of a float texture (clamp to edge).

    Parameters
    ----------
    texture : (H, W, C) float array
        Texel values after the format's decode (what the texture unit filters).
    uv : (..., 2) float array
        Texel coordinates, centres at ``i + 0.5``.
    dtype : float32 or float64
        Arithmetic of the interpolation (float32 emulates the texture unit).

    Returns
    -------
    values : (..., C) array of ``dtype``
    """
    from ..bluenoise import bilinear_footprint

    rows, cols, w = bilinear_footprint(np.asarray(uv, dtype=dtype), texture.shape)
    t = np.asarray(texture)[rows, cols].astype(dtype, copy=False)  # (..., 4, C)
    return np.einsum("...k,...kc->...c", w.astype(dtype), t)


#: The registry: name -> Technique, in registration order.
TECHNIQUES: dict[str, Technique] = {}


def register(technique: Technique) -> Technique:
    """Add a technique to the registry (its name must be new); return it."""
    if not isinstance(technique, Technique):
        raise InputError(f"technique: expected a Technique, got {type(technique).__name__}")
    if technique.name in TECHNIQUES and TECHNIQUES[technique.name] is not technique:
        raise InputError(f"technique: the name {technique.name!r} is already registered")
    TECHNIQUES[technique.name] = technique
    return technique


def names() -> list[str]:
    """Registered technique names, in registration order."""
    return list(TECHNIQUES)


def get(name) -> Technique:
    """The registered technique ``name``; unknown names list the known ones."""
    if isinstance(name, Technique):
        return name
    try:
        return TECHNIQUES[name]
    except (KeyError, TypeError):
        raise InputError(f"technique: unknown technique {name!r}; known techniques: {', '.join(TECHNIQUES)}") from None


# Register the shipped techniques (order = the report's row order).
from . import pcf, vsm, esm, evsm, msm, nlq, translucent  # noqa: E402,F401
from . import msm_soft  # noqa: E402,F401  (area light: run by pipeline's area-light path)
