"""Engine-like samplers: the inputs a shadow map hands a port, drawn per chunk.

Each chunk's rows depend only on ``(seed, case, profile, chunk)``: the generator is
``numpy.random.default_rng(SeedSequence([seed, crc32(case), crc32(profile key), chunk]))``
and every chunk draws :data:`CHUNK` rows (the last one of a sweep is truncated), so any
split of the chunks over workers gives the same rows bit for bit.

A row is a **texel** (a depth distribution) and a **receiver**; its stratum is named
``"<texel>/<receiver>"`` (docs/sweep.md writes the distributions as formulas):

texels
    ``one``, ``two``, ``three``, ``four``: that many depths; each depth is uniform on
    [−1, 1] with probability 1/2, else near an end, ±(1 − 10^U(−4, 0)); weights are
    Dirichlet(1, …, 1), or with probability 1/4 one weight is faint, 10^U(−4, 0), before
    normalising. ``cluster``: two clusters of 1–3 depths, each cluster centred as above
    and spread by 10^U(−6, −1), Dirichlet weights.
receivers
    ``uniform`` zf ~ U(−1, 1); ``near`` zf = z_k ± 10^U(−7, −1) for a depth z_k of the texel
    (uniformly chosen); ``end`` zf = ±(1 − 10^U(−7, −1)).

Texel formats: the moments b(z) = Σ w_i (z_i, z_i², z_i³, z_i⁴) are computed in float64
and rounded once to float32 (a 128-bit float texel, HPG17 §2). Per case
(:data:`SAMPLERS`): Algorithm 1 (``shadow_intensity-*``) gets them biased by the harness
(Slides, "Bias the moments": BIAS_FLOAT32, b' = (1 − α) b + α b*, in float32 as a shader
does), or unbiased where the profile declares the bias (inside the port, or applied just
before the call exactly as for the golden rows, :mod:`.profiled`), in the profile's depth
range; the six-moment bound (``shadow_intensity6-*``, slides, "Prefiltered single
scattering") gets the six moments Σ w_i z_i^k (k = 1 … 6), biased by the harness with
BIAS6_FLOAT32 (α = 3e-4, the golden rows' preset) in float32; Algorithm 3 (``shade``) gets the representation r = Φ(b') of
the biased moments (HPG17 Eq. (5)), and with probability 1/2 the one the 64-bit or the
32-bit non-linear texel decodes to (pack64/unpack64, pack32/unpack32); the chains
(``e2e-*``) get the unbiased moments; the engine cases (``engine-*``) the distribution itself,
converted to the engine's frame and biased as :func:`moments_ref.golden.engine.derive_engine` does
(:mod:`.engine`); the texel decoders (``unpack64``, ``unpack32``) get the codes of those texels, the encoders (``pack64``, ``pack32``) the
representations Φ(b') (not decoded ones: re-encoding is the ``reencode`` cases'). Rows stay inside the case's contract where it has one
(:mod:`moments_ref.golden.contract`); rows that rounding pushes outside are drawn
anyway and judged as robustness rows, as in the goldens.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

import zlib

import numpy as np

from .. import moments, nonlinear, packing
from .._kernels import SWEEP_CHUNK
from ..golden.contract import XI4_RANGE
from . import engine, profiled

__all__ = ["CHUNK", "TEXELS", "RECEIVERS", "STRATA", "SAMPLERS", "chunk_rng", "draw_chunk", "draw_rows", "build_inputs", "draw_texels", "sweepable"]

#: Rows per chunk (fixed: the rows of chunk i do not depend on how a sweep is split; moments_ref._kernels).
CHUNK = SWEEP_CHUNK
TEXELS = ("one", "two", "three", "four", "cluster")
RECEIVERS = ("uniform", "near", "end")
#: Stratum names, ``"<texel>/<receiver>"``, in the order of the stratum index.
STRATA = tuple(f"{t}/{r}" for t in TEXELS for r in RECEIVERS)
_MAXD = 6  # depths per texel, padded with zero weights


def chunk_rng(seed, case, profile_key, chunk):
    """The generator of chunk ``chunk``: a function of ``(seed, case, profile, chunk)`` only."""
    words = [int(seed) & 0xFFFFFFFF, zlib.crc32(case.encode()), zlib.crc32(str(profile_key).encode()), int(chunk)]
    return np.random.default_rng(np.random.SeedSequence(words))


def _log_uniform(rng, lo, hi, n):
    return 10.0 ** rng.uniform(lo, hi, n)


def _depths(rng, n, k):
    """``(n, k)`` depths: uniform on [−1, 1], or (probability 1/2) ±(1 − 10^U(−4, 0))."""
    z = rng.uniform(-1, 1, (n, k))
    sign = np.where(rng.random((n, k)) < 0.5, -1.0, 1.0)
    near_end = sign * (1 - 10.0 ** rng.uniform(-4, 0, (n, k)))
    return np.where(rng.random((n, k)) < 0.5, z, near_end)


def draw_texels(rng, n):
    """Depth distributions: ``(depths (n, 6), weights (n, 6), texel stratum index (n,))``.

    Unused slots have weight 0 (and depth equal to the first depth).
    """
    kind = rng.integers(0, len(TEXELS), n)
    count = np.where(kind < 4, kind + 1, 0)
    z = _depths(rng, n, _MAXD)
    # Clusters: two centres, 1-3 depths each, spread 10^U(-6,-1) around them.
    centres = _depths(rng, n, 2)
    spread = _log_uniform(rng, -6, -1, n)[:, None] * rng.uniform(-1, 1, (n, _MAXD))
    per = rng.integers(1, 4, (n, 2))
    slot = np.arange(_MAXD)[None]
    in_first = slot < per[:, :1]
    in_second = (slot >= 3) & (slot < 3 + per[:, 1:])
    zc = np.clip(np.where(slot < 3, centres[:, :1], centres[:, 1:]) + spread, -1, 1)
    cluster = kind == 4
    used = np.where(cluster[:, None], in_first | in_second, slot < count[:, None])
    z = np.where(cluster[:, None], zc, z)
    w = rng.gamma(1.0, 1.0, (n, _MAXD))
    faint = rng.random(n) < 0.25
    w[:, 0] = np.where(faint, _log_uniform(rng, -4, 0, n) * w[:, 1:].mean(axis=1), w[:, 0])
    w = np.where(used, w, 0.0)
    w = np.where(used.any(axis=1, keepdims=True) & (w.sum(axis=1, keepdims=True) > 0), w, slot == 0)
    w = w / w.sum(axis=1, keepdims=True)
    z = np.where(used, z, z[:, :1])
    return z, w, kind


def _receivers(rng, z, w):
    """Receiver depths and their stratum index."""
    n = len(z)
    kind = rng.integers(0, len(RECEIVERS), n)
    uniform = rng.uniform(-1, 1, n)
    # A depth of the texel that carries weight.
    pick = np.argmax(rng.random(z.shape) * (w > 0), axis=1)
    offset = np.where(rng.random(n) < 0.5, -1.0, 1.0) * _log_uniform(rng, -7, -1, n)
    near = np.clip(z[np.arange(n), pick] + offset, -1, 1)
    end = np.where(rng.random(n) < 0.5, -1.0, 1.0) * (1 - _log_uniform(rng, -7, -1, n))
    zf = np.choose(kind, [uniform, near, end])
    return zf, kind


def _texel_moments(z, w, n=4):
    return moments.power_moments(np.asarray(z, np.float64), np.asarray(w, np.float64), n=n).astype(np.float32)


def _biased(b, preset):
    return moments.bias_moments(b, preset)  # float32 in, float32 arithmetic (a shader's bias)


def _inward32(lo, hi):
    """The float32 values nearest to ``[lo, hi]`` inside it (a float32 clip to the float64 bounds would round
    1.2e-7·(1 − 2⁻²²) down to 1.19999967e-7, outside the contract)."""
    lo32, hi32 = np.float32(lo), np.float32(hi)
    lo32 = lo32 if float(lo32) >= lo else np.nextafter(lo32, np.float32(np.inf))  # compared in float64
    hi32 = hi32 if float(hi32) <= hi else np.nextafter(hi32, np.float32(-np.inf))
    return lo32, hi32


#: Algorithm 3's ξ4 range (:data:`~moments_ref.golden.contract.XI4_RANGE`) as float32 bounds inside it.
_XI4_RANGE32 = _inward32(*XI4_RANGE)


def _representation(b, fmt):
    """Φ of the biased moments (``fmt`` 0), or what the 64-bit (1) or 32-bit (2) texel decodes to."""
    r = nonlinear.phi(_biased(b, moments.BIAS_FLOAT32))
    # Kept inside Algorithm 3's contract: float32 rounding can leave ξ4 a few ulps below 0.
    r[:, 2] = np.clip(r[:, 2], 0, 1)
    r[:, 3] = np.clip(r[:, 3], *_XI4_RANGE32)
    r64 = packing.unpack64(packing.pack64(r)).astype(np.float32)
    r32 = packing.unpack32(packing.pack32(r)).astype(np.float32)
    return np.choose(np.asarray(fmt)[:, None], [r, r64, r32]).astype(np.float32)


def _algorithm1(case, b, zf, fmt):
    if (case.kwargs.get("profile") or {}).get("bias") is not None:
        # The profile declares the bias: the port biases inside, or the harness just before the call (exactly,
        # in the engine's frame, :mod:`.profiled`); either way the row starts from the texel's moments.
        return {"b": b, "zf": zf}
    return {"b": _biased(b, moments.BIAS_FLOAT32), "zf": zf}


def _algorithm1_six(case, b, zf, fmt):
    """The six-moment bound (slides, "Prefiltered single scattering"): b(z) with six moments, biased by the harness
    with BIAS6_FLOAT32 in float32 (the case's golden rows' preset), or unbiased where the profile declares the bias."""
    if (case.kwargs.get("profile") or {}).get("bias") is not None:
        return {"b": b, "zf": zf}
    from ..msm6 import BIAS6_FLOAT32

    return {"b": _biased(b, BIAS6_FLOAT32), "zf": zf}


def _shade(case, b, zf, fmt):
    return {"r": _representation(b, fmt), "zf": zf}


def _chain(case, b, zf, fmt):
    return {"b": b, "zf": zf}


def _unpack64(case, b, zf, fmt):
    return {"q": packing.pack64(_representation(b, np.zeros_like(fmt)))}


def _unpack32(case, b, zf, fmt):
    return {"p": packing.pack32(_representation(b, np.zeros_like(fmt)))}


def _engine(case, rows):
    """An engine case takes the distribution itself (:func:`.engine.engine_inputs`: the engine's frame, its bias)."""
    return engine.engine_inputs(case, rows["z"], rows["w"], rows["zf"])


def _pack(case, b, zf, fmt):
    # Fresh Φ output: a decoded texel re-encoded is the reencode cases' business (codes on boundaries).
    return {"r": _representation(b, np.zeros_like(fmt))}


#: Case name prefix -> how a texel and a receiver become the case's inputs.
SAMPLERS = {
    "shadow_intensity-lower": _algorithm1, "shadow_intensity-upper": _algorithm1,
    "shadow_intensity6-lower": _algorithm1_six, "shadow_intensity6-upper": _algorithm1_six,
    "shade": _shade, "e2e-nlq64": _chain, "e2e-nlq32": _chain, "e2e-msm64": _chain,
    "unpack64": _unpack64, "unpack32": _unpack32, "pack64": _pack, "pack32": _pack,
    "engine-lower": _engine, "engine-upper": _engine, "engine-nlq64": _engine, "engine-nlq32": _engine,
}
_FROM_DISTRIBUTION = (_engine,)


def _sampler(name):
    for prefix, fn in SAMPLERS.items():
        if name.startswith(prefix + "-") and name.endswith("float32"):
            return fn
    return None


def sweepable(name):
    """Whether the sweep has a sampler for case ``name`` (float32 cases of :data:`SAMPLERS`)."""
    return _sampler(name) is not None


def build_inputs(case, rows, profile=None):
    """The case's inputs for row parameters ``rows`` (``z``, ``w`` (n, 6), ``zf`` (n,), ``fmt`` (n,)).

    Under a ``profile`` (:class:`~moments_ref.golden.profile.Profile`; ``case`` profiled by it) the
    rows are drawn in the papers' frame and converted as the golden rows are (:mod:`.profiled`: a
    [0, 1] depth range, a bias applied before the call); ``rows`` then also gets ``contract``, the
    rows inside the case's contract decided on the papers' inputs with the declared bias
    (:func:`moments_ref.golden.conventions.contract_mask`), None where the conversion changes nothing.
    """
    fn = _sampler(case.name)
    if fn in _FROM_DISTRIBUTION:
        return {k: np.ascontiguousarray(v) for k, v in fn(case, rows).items()}
    b = _texel_moments(rows["z"], rows["w"], 6 if case.width == 6 else 4)
    zf = np.asarray(rows["zf"], np.float64).astype(np.float32)
    inputs = fn(case, b, zf, np.asarray(rows["fmt"]))
    if profile is not None and (profiled.unit_depth(case) or profiled.harness_bias(case) is not None):
        from ..golden import CASES
        from ..golden.conventions import contract_mask

        rows["contract"] = contract_mask(CASES[case.name], inputs, profile)
        inputs = profiled.convert_inputs(case, inputs)
    return {k: np.ascontiguousarray(v) for k, v in inputs.items()}


def draw_rows(case, seed, chunk, rows=CHUNK, profile_key="default"):
    """Row parameters of the first ``rows`` rows of chunk ``chunk``.

    Returns a dict: ``z``, ``w`` (n, 6) the texel's depths and weights, ``zf`` (n,) the
    receiver, ``fmt`` (n,) the texel format index (0 float32 moments, 1 the 64-bit and
    2 the 32-bit non-linear texel), ``stratum`` (n,) the index into :data:`STRATA`.
    """
    rng = chunk_rng(seed, case.name, profile_key, chunk)
    z, w, texel = draw_texels(rng, CHUNK)
    zf, receiver = _receivers(rng, z, w)
    fmt = rng.integers(0, 3, CHUNK)
    if engine.is_engine(case):  # the engine cases take the distribution, not a texel format
        fmt = np.zeros_like(fmt)
    stratum = (texel * len(RECEIVERS) + receiver).astype(np.int8)
    return {"z": z[:rows], "w": w[:rows], "zf": zf[:rows], "fmt": fmt[:rows], "stratum": stratum[:rows]}


def draw_chunk(case, seed, chunk, rows=CHUNK, profile_key="default", profile=None):
    """The first ``rows`` rows of chunk ``chunk``: ``(inputs, row parameters)`` (:func:`draw_rows`,
    :func:`build_inputs`)."""
    params = draw_rows(case, seed, chunk, rows, profile_key)
    return build_inputs(case, params, profile), params
