"""Side-by-side crops of the claims about images (HPG17 Figure 1 and Figure 9), for report.md's claims table.

Per claim, one window of camera pixels centred where the claim's leaker differs
most from the reference (or from its partner), shown as the shaded image
(:func:`moments_ref.metrics.shaded_image`) of the reference and of each technique
the claim compares, side by side, nearest-neighbour magnified, at five times the
exposure as HPG17 Figure 1's insets ("Exposure has been increased by a factor of
five for magnified insets"): a surface in full shadow shows its ambient term
(0.1, here 0.5) and any light leaking onto it brighter.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np

from ..metrics import FULL_SHADOW, shaded_image

__all__ = ["CROPS", "EXPOSURE", "scene_crops", "crop_pngs", "file_name"]

#: Per claim: its scene, the techniques shown, and how the centre is chosen:
#: ("leak", t) the largest light of ``t`` in full shadow, ("diff", a, b) the largest |a − b|.
CROPS = {
    "hpg17-evsm128-leaks-less": ("railing", ("evsm64", "evsm128", "msm128"), ("leak", "evsm64")),
    "hpg17-nlq64-close-to-msm128": ("railing", ("msm64", "msm128", "nlq64"), ("leak", "msm64")),
    "hpg17-nlq32-close-to-nlq64": ("railing", ("nlq64", "nlq32"), ("diff", "nlq32", "nlq64")),
    "hpg17-four-moment-leak-three-occluders": ("patio", ("pcf", "msm128", "nlq64"), ("leak", "nlq64")),
}
#: HPG17 Figure 1: "Exposure has been increased by a factor of five for magnified insets."
EXPOSURE = 5.0


def file_name(claim_id):
    """The PNG a claim's crop is written to."""
    return f"claim_{claim_id}.png"


def _centre(result, rule):
    ref = np.asarray(result.reference[rule[1]], np.float64)
    if rule[0] == "leak":
        s = np.asarray(result.shadow[rule[1]], np.float64)
        score = np.where(ref >= FULL_SHADOW, ref - s, -np.inf)
    else:
        score = np.abs(np.asarray(result.shadow[rule[1]], np.float64) - np.asarray(result.shadow[rule[2]], np.float64))
    return int(result.gbuffer.pixel[int(np.argmax(score))]) if score.size else None


def scene_crops(result):
    """``{claim id: {"names", "images" (k, side, side) float16, "pixel" [x, y], "side"}}`` for the claims on this scene."""
    out = {}
    gb = result.gbuffer
    w, h = gb.resolution
    side = max(24, h // 8)
    for cid, (scene, names, rule) in CROPS.items():
        if result.scene.name != scene or not all(n in result.shadow and n in result.reference for n in names):
            continue
        k = _centre(result, rule)
        if k is None:
            continue
        x, y = k % w, k // w
        x0, y0 = int(np.clip(x - side // 2, 0, max(w - side, 0))), int(np.clip(y - side // 2, 0, max(h - side, 0)))
        pics = [shaded_image(gb, result.reference[names[0]])] + [shaded_image(gb, result.shadow[n]) for n in names]
        crops = np.stack([p[y0:y0 + side, x0:x0 + side, 0] for p in pics])
        out[cid] = {"names": ["reference", *names], "images": np.clip(crops * EXPOSURE, 0, 1).astype(np.float16),
                    "pixel": [int(x), int(y)], "side": side}
    return out


def crop_pngs(measured):
    """``{file name: PNG bytes}``: one row of crops per claim measured on the scenes of ``measured``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .._io import REPORT_PNG_LEVEL, figure_png

    out = {}
    for scene in measured.values():
        for cid, c in (scene.get("crops") or {}).items():
            n = len(c["names"])
            fig, axes = plt.subplots(1, n, figsize=(1.9 * n, 2.2))
            for ax, name, img in zip(np.atleast_1d(axes), c["names"], c["images"]):
                ax.imshow(img.astype(np.float32), cmap="gray", vmin=0, vmax=1, interpolation="nearest")
                ax.set_title(name, fontsize=9)
                ax.set_xticks([])
                ax.set_yticks([])
            fig.suptitle(f"{cid}: {c['side']} px at {c['pixel']}, exposure x{EXPOSURE:g}", fontsize=8)
            try:
                out[file_name(cid)] = figure_png(fig, dpi=110, compress_level=REPORT_PNG_LEVEL)
            finally:
                plt.close(fig)
    return out
