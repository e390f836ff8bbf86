"""The 32-bit decoder choice of docs/formats.md, measured: ``python -m moments_ref.tools.decoders``.

HPG17 §3.5 reads the 32-bit texel "rounded up to guarantee a lower bound to the
shadow intensity". This tool measures how well a decoder keeps that guarantee, the
way docs/formats.md reports it:

* :func:`against_bound`: shade of the decoded texel minus shade of the unquantized
  representation ``phi(bias_moments(b, BIAS_FLOAT32))`` (both HPG17 Algorithm 3 with
  its §3.4 clamps), over rows ``(b, zf)`` such as the ``e2e-nlq32`` golden rows;
* :func:`against_z`: the same decoded shade against the exact ``Z(z < zf)`` of random
  depth distributions (:func:`random_distributions`);
* :func:`excess_over_bound`: the largest over-shadowing against the bound and the
  share of rows above 0.05, over independent samples of each sampler of
  :data:`SAMPLERS` (``python -m moments_ref.tools.decoders --samples`` prints
  docs/formats.md's table): the largest excess is an extreme value of the sample,
  so it is stated with the sampler, the count and its spread over samples;
* :func:`scene_texels`: both, per receiver pixel of a shipped scene (the NLQ
  pipeline's filtered moments, bilinear lookup, the constant bias 1e-3 of §5).

Decoders (:data:`DECODERS`): the format (:func:`moments_ref.packing.unpack32` of
:func:`moments_ref.packing.pack32`, the HPG17 demo's cells and positions), the same
with depths read at the cell centre, and the schema-2 format this package stored
before (:func:`schema2_roundtrip`: ``round(127 √v2)``, ``round(63 Ψ4)``, depths at the
cell centre), kept here only to reproduce the comparison.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] HPG17 demo: The demo code accompanying HPG17 (Direct3D; C. Peters), whose 32-bit texel
       functions ``QuantizeMomentsNonLinear32Bit`` and ``UnpackMomentsNonLinear32Bit`` are public
       in engine code ported from it, e.g. the repository kingofthebongo2008/UCEngine,
       ``src/uc_dev/private/gx/dx12/shaders/shadows/moment_shadow_maps_32.hlsli`` and
       ``shadows.hlsli`` (cited for their behaviour; no code is copied). Its 64-bit format is a
       UNORM16 render-target write (``moment_shadow_maps_64.hlsli``).
"""

from __future__ import annotations

import numpy as np

from ..moments import BIAS_FLOAT32, bias_moments, power_moments
from ..nonlinear import phi, psi4, psi4_inverse, shade
from .. import packing

__all__ = ["DECODERS", "SAMPLERS", "schema2_roundtrip", "schema3_roundtrip", "against_bound", "against_z",
           "random_distributions", "random_representations", "excess_over_bound", "sample_table", "e2e_rows",
           "scene_texels", "main"]


def schema2_roundtrip(r):
    """Pack and decode ``r`` (n, 4) in the schema-2 32-bit format (float64): the comparison's baseline."""
    r = packing.saturate(r)
    t = np.clip(np.floor(511.5 * (r[:, :2] + 1)), 0, 1022)
    sv = np.rint(127 * np.sqrt(r[:, 2])) / 127
    c = np.rint(63 * psi4(r[:, 3]))
    return np.column_stack([(t + 0.5) / 511.5 - 1, sv * sv, psi4_inverse(np.minimum((c + 0.5) / 63, 1))])


def schema3_roundtrip(r, **positions):
    """``unpack32(pack32(r), **positions)`` in float64 (the format; keywords of :func:`packing.unpack32`)."""
    return packing.unpack32(packing.pack32(r), **positions)


def _demo_clamp(r, offset=5e-6):
    """The HPG17 demo's clamps (``ClampingOffset = 5e-6`` on v2 and y2 − y1) applied before Algorithm 3's own."""
    r = np.array(r, copy=True)
    r[:, 2] = np.clip(r[:, 2], offset, 1 - offset)
    r[:, 1] = np.maximum(r[:, 1], r[:, 0] + offset)
    return r


#: The decoders compared (name -> r (n, 4) -> decoded r).
DECODERS = {
    "schema 3 (HPG17 demo)": schema3_roundtrip,
    "schema 3 with the demo's clamp offset 5e-6": lambda r: _demo_clamp(schema3_roundtrip(r)),
    "schema 3, depths at the cell centre": lambda r: schema3_roundtrip(r, depth_decode="centre"),
    "schema 2": schema2_roundtrip,
}


def _stats(err):
    over, leak = np.maximum(err, 0), np.maximum(-err, 0)
    return {"over_max": float(err.max()), "over_mean": float(over.mean()), "abs_mean": float(np.abs(err).mean()),
            "leak_max": float(leak.max()), "leak_mean": float(leak.mean()), "rows": int(err.size)}


def _representation(b):
    return packing.saturate(phi(bias_moments(np.asarray(b, np.float64), BIAS_FLOAT32)))


def against_bound(b, zf, decoder):
    """Statistics of ``shade(decoder(r), zf) − shade(r, zf)``, r the unquantized representation of ``b``."""
    r = _representation(b)
    zf = np.asarray(zf, np.float64)
    return _stats(shade(decoder(r), zf) - shade(r, zf))


def random_distributions(n=3000, seed=0):
    """``(b, zf, Z)`` rows of n seeded distributions (1–6 depths: uniform, one surface, two clusters).

    Fragments on a grid of 41 depths and at, 1e-5, 1e-3 and 3e-3 behind and 1e-3 in front
    of each depth; ``Z`` the exact ``Z(z < zf)``.
    """
    rng = np.random.default_rng(seed)
    bs, zs, Zs = [], [], []
    for _ in range(n):
        k, kind = rng.integers(1, 7), rng.integers(0, 3)
        if kind == 0:
            z = rng.uniform(-1, 1, k)
        elif kind == 1:
            z = np.clip(rng.uniform(-1, 1) + rng.uniform(-1, 1, k) * 10 ** rng.uniform(-4, -1), -1, 1)
        else:
            z = np.clip(rng.uniform(-1, 1, 2)[rng.integers(0, 2, k)] + rng.normal(0, 1e-4, k), -1, 1)
        w = rng.dirichlet(np.ones(k))
        zf = np.clip(np.concatenate([np.linspace(-1, 1, 41), z, z + 1e-3, z + 3e-3, z - 1e-3, z + 1e-5]), -1, 1)
        bs.append(np.repeat(power_moments(z, w)[None], len(zf), 0))
        zs.append(zf)
        Zs.append((w[None, :] * (z[None, :] < zf[:, None])).sum(1))
    return np.concatenate(bs), np.concatenate(zs), np.concatenate(Zs)


def against_z(b, zf, Z, decoder):
    """Over-shadowing against the exact Z: max and share of rows above 0.01 of ``shade(decoder(r), zf) − Z``."""
    e = shade(decoder(_representation(b)), np.asarray(zf, np.float64)) - Z
    return {"over_max": float(e.max()), "share_over_0.01": float(np.mean(e > 0.01))}


def random_representations(n=100_000, seed=0, receivers="support"):
    """``(r, zf)``: n seeded representations (y1, y2, v2, ξ4), four fragment depths each (4 n rows).

    y1 < y2 uniform in [-1, 1] (sorted pairs), v2 uniform in [0, 1], ξ4 log-uniform in
    [1e-8, 1e-1], saturated as a texel is (:func:`moments_ref.packing.saturate`).
    ``receivers``: ``"uniform"`` draws the four fragments uniformly in [-1, 1];
    ``"support"`` puts two 1e-3 behind y1 and y2 (a receiver just behind an
    occluder, where a decoder's depth error matters most) and two uniform.
    """
    rng = np.random.default_rng(seed)
    y = np.sort(rng.uniform(-1, 1, (n, 2)), axis=1)
    r = packing.saturate(np.column_stack([y, rng.uniform(0, 1, n), 10 ** rng.uniform(-8, -1, n)]))
    zf = rng.uniform(-1, 1, (n, 4))
    if receivers == "support":
        zf[:, :2] = np.minimum(r[:, :2] + 1e-3, 1.0)
    elif receivers != "uniform":
        raise ValueError(f"receivers: expected 'uniform' or 'support', got {receivers!r}")
    return np.repeat(r, 4, axis=0), zf.reshape(-1)


def _distribution_rows(seed):
    b, zf, _ = random_distributions(3000, seed)
    return _representation(b), zf


#: The samplers whose excess over the bound docs/formats.md reports (:func:`excess_over_bound`).
SAMPLERS = {
    "3000 random depth distributions (1 to 6 depths: uniform, one surface, two clusters), fragments on a "
    "41-depth grid and 1e-5 to 3e-3 around each depth": lambda seed: _distribution_rows(seed),
    "1e5 random representations (y1 < y2 uniform, v2 uniform, ξ4 log-uniform 1e-8 to 0.1) x 4 fragments: two "
    "1e-3 behind y1 and y2, two uniform": lambda seed: random_representations(100_000, seed, "support"),
    "1e5 random representations (as above) x 4 uniform fragments": lambda seed: random_representations(
        100_000, seed, "uniform"),
}


def _wilson(k, n, z=1.96):
    """The 95 % Wilson score interval of a share k / n."""
    p = k / n
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return ((p + z * z / (2 * n) - half) / (1 + z * z / n), (p + z * z / (2 * n) + half) / (1 + z * z / n))


def excess_over_bound(sampler, decoder=DECODERS["schema 3 (HPG17 demo)"], seeds=range(8), threshold=0.05):
    """The decoder's over-shadowing against the unquantized bound, on independent samples of one sampler.

    ``sampler(seed) -> (r, zf)``: representations ``(n, 4)`` and fragment depths
    (:data:`SAMPLERS`). The largest excess of one sample is an extreme
    value that grows with the sample and depends on where the fragments are drawn,
    so it is given over ``len(seeds)`` independent samples (median, min and max),
    beside the share of rows above ``threshold`` with its 95 % Wilson interval
    (pooled over the samples).
    """
    maxima, k, n = [], 0, 0
    for seed in seeds:
        r, zf = sampler(seed)
        e = shade(decoder(r), zf) - shade(r, zf)
        maxima.append(float(e.max()))
        k += int(np.count_nonzero(e > threshold))
        n += e.size
    lo, hi = _wilson(k, n)
    return {"rows_per_sample": round(n / len(maxima)), "samples": len(maxima), "max_median": float(np.median(maxima)),
            "max_min": float(min(maxima)), "max_max": float(max(maxima)), "threshold": threshold, "seed_maxima": maxima,
            "share_over": k / n, "share_over_95": (float(lo), float(hi))}


def e2e_rows(dtype="float64"):
    """``(b, zf)`` of the golden case ``e2e-nlq32-<dtype>``."""
    from ..golden.cases import CASES, case_rows

    inputs, _, _ = case_rows(CASES[f"e2e-nlq32-{dtype}"])
    return inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64)


def scene_texels(name, decoder, full=False):
    """Per receiver pixel of a shipped scene: decoded minus unquantized bilinear shade (float32, bias 1e-3)."""
    from .. import pipeline
    from ..gpu.bluenoise import lookup_bilinear
    from ..scene import load_scene
    from ..scene.gbuffer import z_ndc_lookup

    sc = load_scene(name)
    size, samples, res = (None, None, None) if full else pipeline.reduced_settings(sc)
    out = pipeline.run(sc, ["nlq32"], pipeline.Settings(reference=False, full=full, shadow_map_size=size, msaa=samples,
                                                        resolution=res))
    b = out.values["onchip_resolve_blur" if out.msaa > 1 else "onchip_blur"]
    r = packing.saturate(phi(bias_moments(b, BIAS_FLOAT32)).reshape(-1, 4)).astype(np.float32)
    d = decoder(r.astype(np.float64)).astype(np.float32)
    uv = out.gbuffer.uv.astype(np.float32)
    zf = (z_ndc_lookup(out.gbuffer, False) - 1e-3).astype(np.float32)
    look = [lookup_bilinear(t.reshape(b.shape), uv, shade, zf).astype(np.float64) for t in (r, d)]
    e = look[1] - look[0]
    return {**_stats(e), "share_over_0.05": float(np.mean(e > 0.05)), "share_leak_0.05": float(np.mean(e < -0.05))}


def main(scenes=("railing", "facade", "three-occluders")):
    """Print docs/formats.md's tables (e2e rows, random distributions, the scenes' texels)."""
    b, zf = e2e_rows()
    print("| rows | decoder | over max | mean |error| | leak max | leak mean |\n|---|---|---|---|---|---|")
    for name, dec in DECODERS.items():
        s = against_bound(b, zf, dec)
        print(f"| e2e-nlq32-float64 | {name} | {s['over_max']:.3f} | {s['abs_mean']:.4f} | {s['leak_max']:.3f} | "
              f"{s['leak_mean']:.4f} |")
    b, zf, Z = random_distributions()
    for name, dec in DECODERS.items():
        s, z = against_bound(b, zf, dec), against_z(b, zf, Z, dec)
        print(f"| random distributions | {name} | {s['over_max']:.3f} (vs Z {z['over_max']:.3f}) | "
              f"over {s['over_mean']:.4f} | {s['leak_max']:.3f} | {s['leak_mean']:.4f} |")
    for sc in scenes:
        for name, dec in ((k, v) for k, v in DECODERS.items() if "clamp" not in k):
            s = scene_texels(sc, dec)
            print(f"| {sc} | {name} | {s['over_max']:.3f} (share > 0.05: {s['share_over_0.05']:.1e}) | "
                  f"{s['abs_mean']:.1e} | {s['leak_max']:.3f} (share > 0.05: {s['share_leak_0.05']:.1e}) | "
                  f"{s['leak_mean']:.1e} |")


def sample_table(seeds=range(8), decoder="schema 3 (HPG17 demo)"):
    """docs/formats.md's table of the decoder's excess over the bound per sampler (:func:`excess_over_bound`)."""
    lines = [f"| sampler ({len(seeds)} independent samples each, seeds {min(seeds)} to {max(seeds)}) | rows per sample "
             "| largest excess: median (min to max) over the samples | rows above 0.05 (95 % interval) |",
             "|---|---|---|---|"]
    for name, f in SAMPLERS.items():
        s = excess_over_bound(f, DECODERS[decoder], seeds)
        lo, hi = s["share_over_95"]
        lines.append(f"| {name} | {s['rows_per_sample']} | {s['max_median']:.3f} ({s['max_min']:.3f} to "
                     f"{s['max_max']:.3f}) | {s['share_over']:.1e} ({lo:.1e} to {hi:.1e}) |")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    import sys

    print(sample_table()) if sys.argv[1:] == ["--samples"] else main()
