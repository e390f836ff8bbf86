"""Numerical-honesty evidence: float32 and float64 kernels against the mpmath twins.

:func:`measure` evaluates each fast function on seeded inputs, grouped in
categories that hit the hard cases of the algorithm, and compares it with
:mod:`moments_ref.precise` *on the very same input values* (the float32 kernel's
float32-rounded moments are converted exactly), so the error is that of the
kernel's arithmetic and branch decisions, not of input rounding. A second table
compares Algorithm 1 on biased two-point moments with the exact ``Z(z < zf)`` of
the unbiased distribution, against the distance of zf from the nearest support
point: the price of biasing.

``moments-ref stability --out docs/`` calls :func:`main`, which writes
``docs/stability.md`` with :func:`write_markdown`. Everything is seeded; the same
version writes the same file.

Input generation follows the pipeline: moments are computed in float64, cast to
the working dtype and biased there with ``BIAS_FLOAT32`` (HPG17 §3.2: the bias for
moments stored in floats, also the input of Algorithm 2).

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .. import msm, precise
from .._io import write_text
from ..moments import BIAS_FLOAT32, bias_moments, hankel, power_moments
from ._stability_inputs import DISTRIBUTIONS, MSM_CATEGORIES, NONLINEAR_CATEGORIES, category_rng, shade_zf
from .intervals import CONFIDENCE, exceedance_bound, quantile_interval

__all__ = ["measure", "measure_msm", "measure_two_point", "measure_nonlinear", "write_markdown", "main",
           "DISTRIBUTIONS", "distributions_markdown"]


DTYPES = (np.float32, np.float64)
#: Distance bins (upper edges) of the two-point table.
DISTANCE_EDGES = (0.0, 1e-8, 1e-6, 1e-4, 1e-2, 1e-1, 2.0)


def distributions_markdown(n=300, seed=0):
    """The report's section naming each category's distribution, count and intervals (docs/stability.md)."""
    out = ["## Sampled distributions", "", (
        f"Every table row is one category in one dtype: n = {n} seeded rows (seed {seed}; the two-point table {5 * n} "
        f"rows, binned). 'p99 95 % CI' is a distribution-free {CONFIDENCE:.0%} interval for the category's 99th "
        "percentile from the order statistics (binomial ranks; ∞ where n rows cannot bound it from above). 'max' is "
        f"the largest error of the sample, not of the category: with {CONFIDENCE:.0%} confidence a fresh row of the "
        f"category exceeds it with probability at most {exceedance_bound(n):.1%} (1 − 0.05^(1/n))."), "",
        "| functions | category | distribution |", "|---|---|---|"]
    for fam, label in (("msm", "msm.shadow_intensity"), ("nonlinear", "nonlinear.phi, nonlinear.shade")):
        out += [f"| {label} | {c} | {d} |" for c, d in DISTRIBUTIONS[fam].items()]
    return "\n".join(out) + "\n"


def _worst(err, fast, exact, inputs, **meta):
    """Summary row: worst abs error, its input, 99th percentile, count of non-finite.

    ``fast``/``exact`` are (n,) or (n, k); a row with any non-finite output counts
    as an infinite error.
    """
    fast = np.asarray(fast)
    bad = ~np.isfinite(fast.reshape(len(fast), -1)).all(axis=1)
    err = np.where(bad, np.inf, err)
    i = int(np.argmax(err))
    row = dict(meta)
    row.update(
        n=int(err.size),
        max_abs_error=float(err[i]),
        p99_abs_error=float(np.quantile(err, 0.99)),
        p99_interval=quantile_interval(err, 0.99),
        nonfinite=int(bad.sum()),
        worst_input={k: [v.item() for v in np.atleast_1d(a[i])] for k, a in inputs.items()},
        worst_fast=fast[i].tolist() if fast.ndim > 1 else float(fast[i]),
        worst_exact=np.asarray(exact)[i].tolist() if fast.ndim > 1 else float(exact[i]),
    )
    return row


def _within_singular_threshold(b):
    """How many inputs lie inside msm's singular threshold of their dtype, by their exact pivots.

    msm treats ``σ² ≤ rtol·b2`` or ``ξ4 ≤ rtol·max(b4, σ²)`` (``rtol = SINGULAR_RTOL·eps``)
    as singular and returns the exact Z of the unique distribution there; for
    inputs whose exact pivots are positive that is a branch decision, not rounding.
    """
    rtol = msm.singular_thresholds(b.dtype)
    p = precise.pivots(b)
    bx = b.astype(np.float64)
    sigma2, xi4 = p[:, 0], p[:, 1]
    single = sigma2 <= rtol * bx[:, 1]
    with np.errstate(invalid="ignore"):
        two = ~single & (xi4 <= rtol * np.maximum(bx[:, 3], sigma2))
    return int((single | two).sum())


def _threshold_text():
    """msm's float32 singular threshold and BIAS_FLOAT32's lift of ξ4, their figures read from the code."""
    tau = float(msm.singular_thresholds(np.float32))
    lift = BIAS_FLOAT32.alpha * float(np.linalg.eigvalsh(hankel(np.asarray(BIAS_FLOAT32.target))).min())
    where = ("ξ4 ≤ 0 or σ² ≤ 0: the relative threshold SINGULAR_RTOL·eps is 0 in float32" if tau == 0 else
             f"ξ4 ≤ τ·max(b4, σ²) with τ = SINGULAR_RTOL·eps = {tau:.2g}")
    return (f"{where}; BIAS_FLOAT32's lift of ξ4, about α·λmin(B(b*)) = {lift:.1g}, does not clear them")


def measure_msm(seed=0, n=300, progress=None):
    """Rows for ``msm.shadow_intensity`` (lower and upper) per category and dtype."""
    rows = []
    for name, gen in MSM_CATEGORIES.items():
        b64, zf64 = gen(category_rng(seed, name), n)
        for dt in DTYPES:
            b = bias_moments(b64.astype(dt), BIAS_FLOAT32)
            zf = zf64.astype(dt)
            lo_x, up_x = precise.shadow_bounds(b, zf)
            within = _within_singular_threshold(b)
            for bound, exact in (("lower", lo_x), ("upper", up_x)):
                with np.errstate(all="ignore"):
                    fast = msm.shadow_intensity(b, zf, bound=bound).astype(np.float64)
                rows.append(_worst(np.abs(fast - exact), fast, exact, {"b": b, "zf": zf},
                                   table="error", function=f"msm.shadow_intensity ({bound})",
                                   category=name, dtype=np.dtype(dt).name, within_threshold=within))
        if progress:
            progress(name)
    return rows


GAP_CLASSES = (("gap ≥ 0.1", 0.1, 2.0), ("gap in [1e-3, 0.1)", 1e-3, 0.1))


def measure_two_point(seed=0, n=1500, progress=None):
    """Two-point distributions after ``BIAS_FLOAT32``: deviation from the exact Z by distance.

    Depths y1 < y2 with a log-uniform gap in [1e-3, 1] (split into two gap classes:
    the bias smears a step over a width that does not shrink with the gap) and
    weights v2 ∈ [0.01, 0.99]; zf at a support point plus a signed log-uniform
    offset in [1e-10, 1] (or exactly 0). Per gap class and distance bin: the worst
    ``|lower − Z(z < zf)|`` and ``|upper − Z(z ≤ zf)|`` of the kernel and of the
    exact bound of the biased moments (precise), which separates the effect of
    biasing from float rounding, and the largest ``lower − Z(z < zf)`` (a lower
    bound should not exceed Z by more than the bias's O(α)).
    """
    rng = category_rng(seed, "two-point")
    gap = 10.0 ** rng.uniform(-3, 0, n)
    y1 = rng.uniform(-1, 1 - gap)
    y2 = y1 + gap
    v2 = rng.uniform(0.01, 0.99, n)
    z = np.stack([y1, y2], axis=1)
    w = np.stack([1 - v2, v2], axis=1)
    b64 = power_moments(z, w)
    which = rng.integers(0, 2, n)
    support = z[np.arange(n), which]
    mag = np.where(rng.random(n) < 0.1, 0.0, 10.0 ** rng.uniform(-10, 0, n))
    zf64 = np.clip(support + rng.choice([-1.0, 1.0], n) * mag, -1, 1)
    rows = []
    for dt in DTYPES:
        b = bias_moments(b64.astype(dt), BIAS_FLOAT32)
        zf = zf64.astype(dt)
        zfx = zf.astype(np.float64)
        # Exact Z of the unbiased distribution at the zf actually used (float32-rounded or not).
        z_lt = (w * (z < zfx[:, None])).sum(axis=1)
        z_le = (w * (z <= zfx[:, None])).sum(axis=1)
        dist = np.abs(z - zfx[:, None]).min(axis=1)
        lo = msm.shadow_intensity(b, zf, "lower").astype(np.float64)
        up = msm.shadow_intensity(b, zf, "upper").astype(np.float64)
        lo_x, up_x = precise.shadow_bounds(b, zf)
        for gname, glo, ghi in GAP_CLASSES:
            in_gap = (gap >= glo) & (gap < ghi)
            for i, hi in enumerate(DISTANCE_EDGES):
                lo_edge = DISTANCE_EDGES[i - 1] if i else None
                m = in_gap & ((dist == 0) if hi == 0.0 else (dist > lo_edge) & (dist <= hi))
                if not m.any():
                    continue
                rows.append(dict(
                    table="two_point", dtype=np.dtype(dt).name, gap=gname,
                    distance="0" if hi == 0.0 else f"({lo_edge:g}, {hi:g}]", n=int(m.sum()),
                    lower_dev=float(np.abs(lo - z_lt)[m].max()),
                    lower_dev_exact=float(np.abs(lo_x - z_lt)[m].max()),
                    upper_dev=float(np.abs(up - z_le)[m].max()),
                    upper_dev_exact=float(np.abs(up_x - z_le)[m].max()),
                    lower_above_Z=float(np.max(lo - z_lt, initial=0.0, where=m)),
                    lower_above_Z_exact=float(np.max(lo_x - z_lt, initial=0.0, where=m)),
                ))
        if progress:
            progress(f"two-point {np.dtype(dt).name}")
    return rows


# ---------------------------------------------------------------------------
# non-linear representation (moments_ref.nonlinear, another module's kernels)


def measure_nonlinear(seed=0, n=300, progress=None):
    """Rows for ``nonlinear.phi`` and ``nonlinear.shade`` (needs :mod:`moments_ref.nonlinear`).

    ``phi`` gets the moments of Eq. (4) (rounded to float64, cast, biased with
    BIAS_FLOAT32 in the working dtype as HPG17 §3.1 prescribes) and is compared
    with precise.phi on the same moments: y1, y2, v2 by absolute error, ξ4 by the
    absolute error after the warp Ψ4 (the stored quantity; 16-bit step 1.5e-5).
    ``shade`` gets the representation itself, cast to the dtype, and is compared
    with precise.shade (Algorithm 1 on Eq. (4) in mpmath, no clamps).
    """
    from .. import nonlinear

    rows = []
    cats = dict(NONLINEAR_CATEGORIES)
    for name, gen in cats.items():
        rng = category_rng(seed, "nl " + name)
        r64 = gen(rng, n)
        zf64 = shade_zf(rng, r64)
        b64 = precise.phi_inverse(r64)
        for dt in DTYPES:
            dname = np.dtype(dt).name
            b = bias_moments(b64.astype(dt), BIAS_FLOAT32)
            exact = precise.phi(b)
            with np.errstate(all="ignore"):
                fast = np.asarray(nonlinear.phi(b)).astype(np.float64)
            err = np.abs(fast[:, :3] - exact[:, :3]).max(axis=1)
            rows.append(_worst(err, fast[:, :3], exact[:, :3], {"b": b}, table="error",
                               function="nonlinear.phi (y1, y2, v2)", category=name, dtype=dname))
            u_fast = precise.psi4(np.where(np.isfinite(fast[:, 3]), fast[:, 3], 0.0))
            u_exact = precise.psi4(exact[:, 3])
            u_fast = np.where(np.isfinite(fast[:, 3]), u_fast, np.nan)
            rows.append(_worst(np.abs(u_fast - u_exact), u_fast, u_exact, {"b": b},
                               table="error", function="nonlinear.phi (Ψ4(ξ4))", category=name,
                               dtype=dname))
        # shade: the representation as stored, zf near the support points or random.
        for sname, zf_src in ((name, zf64),) + (((
                "zf at y1 or y2", np.where(rng.random(n) < 0.5, r64[:, 0], r64[:, 1])),) if name == "random" else ()):
            for dt in DTYPES:
                r = r64.astype(dt)
                zf = zf_src.astype(dt)
                exact = precise.shade(r, zf)
                with np.errstate(all="ignore"):
                    fast = np.asarray(nonlinear.shade(r, zf)).astype(np.float64)
                rows.append(_worst(np.abs(fast - exact), fast, exact, {"r": r, "zf": zf},
                                   table="error", function="nonlinear.shade", category=sname,
                                   dtype=np.dtype(dt).name))
        if progress:
            progress("nonlinear " + name)
    return rows


def nonlinear_available():
    """True when :mod:`moments_ref.nonlinear` imports and offers phi and shade."""
    try:
        from .. import nonlinear
    except ImportError:
        return False
    return hasattr(nonlinear, "phi") and hasattr(nonlinear, "shade")


def measure(seed=0, n=300, progress=None, include_nonlinear=None):
    """All rows: Algorithm 1 per category/dtype, the two-point table, the non-linear kernels.

    Parameters
    ----------
    seed : int
        Seed of every input family (deterministic output).
    n : int
        Inputs per category (the two-point table uses 5·n).
    progress : callable(str), optional
        Called after each category.
    include_nonlinear : bool, optional
        Measure ``nonlinear.phi`` and ``nonlinear.shade``; default: when the module imports.

    Returns
    -------
    rows : list of dict
        ``table="error"`` rows: function, category, dtype, n, max_abs_error,
        p99_abs_error, nonfinite, worst_input, worst_fast, worst_exact.
        ``table="two_point"`` rows: dtype, distance bin, n and the worst deviations.
    """
    rows = measure_msm(seed, n, progress)
    rows += measure_two_point(seed, 5 * n, progress)
    if include_nonlinear is None:
        include_nonlinear = nonlinear_available()
    if include_nonlinear:
        rows += measure_nonlinear(seed, n, progress)
    return rows


# ---------------------------------------------------------------------------
# report


def _e(x):
    if isinstance(x, list):
        return "(" + ", ".join(_e(v) for v in x) + ")"
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "nan"
    if x == 0:
        return "0"
    return f"{x:.2g}" if abs(x) < 1e-3 or abs(x) >= 1e4 else f"{x:.3g}"


def _input_text(row):
    parts = []
    for k, v in row["worst_input"].items():
        # Shortest repr that round-trips in the row's dtype, so the input can be replayed.
        vals = [str(np.float32(x)) if row["dtype"] == "float32" else repr(float(x)) for x in v]
        parts.append(f"{k}=" + (vals[0] if len(vals) == 1 else "(" + ", ".join(vals) + ")"))
    return "`" + " ".join(parts) + "`"


def _interpretation(rows):
    """Sentences drawn from the numbers (thresholds: 1e-3 fine, 1e-2 broken)."""
    err = [r for r in rows if r["table"] == "error"]
    lines = []
    for fn in dict.fromkeys(r["function"] for r in err):
        rs = [r for r in err if r["function"] == fn]
        r64 = [r for r in rs if r["dtype"] == "float64"]
        r32 = [r for r in rs if r["dtype"] == "float32"]
        f64 = max(r64, key=lambda r: r["max_abs_error"])
        bad32 = [r for r in r32 if r["max_abs_error"] > 1e-2]
        good32 = [r for r in r32 if r["max_abs_error"] <= 1e-3]
        nonfinite = sum(r["nonfinite"] for r in rs)
        s = (f"**{fn}**: float64 stays within {_e(f64['max_abs_error'])} of the exact value "
             f"(worst category: {f64['category']}).")
        if bad32:
            worst = max(bad32, key=lambda r: (r["max_abs_error"], r["p99_abs_error"]))
            s += (" float32 breaks down (error above 1e-2) in: "
                  + ", ".join(f"{r['category']} (max {_e(r['max_abs_error'])}, p99 {_e(r['p99_abs_error'])})"
                              for r in bad32)
                  + f"; in '{worst['category']}' the worst input gives {_e(worst['worst_fast'])} where "
                  f"the exact value is {_e(worst['worst_exact'])}.")
            within = [r for r in bad32 if r.get("within_threshold")]
            if within:
                s += (" Of these inputs, " + ", ".join(
                    f"{r['within_threshold']}/{r['n']} ({r['category']})" for r in within)
                    + f" have exact pivots inside msm's float32 singular threshold ({_threshold_text()}): "
                    "there the kernel returns Z of the two-point distribution instead of the bound of the "
                    "biased moments, so the error is a branch decision rather than rounding.")
        if good32:
            s += " float32 is within 1e-3 in: " + ", ".join(r["category"] for r in good32) + "."
        s += " No NaN or inf was produced." if nonfinite == 0 else f" {nonfinite} results were NaN or inf."
        lines.append(s)
    tp = [r for r in rows if r["table"] == "two_point"]
    for dname in ("float64", "float32"):
        for gname, _, _ in GAP_CLASSES:
            t = [r for r in tp if r["dtype"] == dname and r["gap"] == gname]
            if not t:
                continue
            fine = [r for r in t if r["distance"] != "0" and r["lower_dev"] <= 1e-3 and r["upper_dev"] <= 1e-3]
            s = f"**Two-point, {dname}, {gname}**: "
            s += (f"Algorithm 1 on the biased moments is within 1e-3 of the exact Z of the unbiased "
                  f"distribution for distances {', '.join(r['distance'] for r in fine)}; "
                  if fine else "no distance bin is within 1e-3 of the exact Z; ")
            near = max((r for r in t if r["distance"] != "0"), key=lambda r: r["lower_dev_exact"])
            s += (f"closer in, the bias smears the steps (worst {_e(near['lower_dev_exact'])} for the "
                  f"exact bound of the biased moments at distances {near['distance']}).")
            kv = max(r["lower_above_Z"] for r in t)
            xv = max(r["lower_above_Z_exact"] for r in t)
            s += (f" The computed lower bound exceeds the true Z(z < zf) by at most {_e(kv)} "
                  f"(exact bound of the biased moments: {_e(xv)}).")
            lines.append(s)
    return lines


def write_markdown(path, rows):
    """Write the stability report (atomically) and return its path.

    Parameters
    ----------
    path : str or Path
        Target file (``docs/stability.md``).
    rows : list of dict
        The output of :func:`measure`.
    """
    out = ["# Numerical stability of the kernels against mpmath", "",
           "Generated by `moments-ref stability --out docs/` (`moments_ref.tools.stability.main`, seed 0);",
           "do not edit by hand. Every fast function is evaluated in float32 and float64 on seeded inputs",
           "and compared with its mpmath twin in `moments_ref.precise` (50 digits) **on the same input",
           "values** (float32 inputs are converted exactly), so the errors are those of the kernel's",
           "arithmetic and branch decisions, not of rounding the inputs. Moments are computed in float64,",
           "cast to the working dtype and biased there with `BIAS_FLOAT32` (HPG17 §3.2). 'max' is the worst",
           "absolute error, 'p99' its 99th percentile, 'NaN/inf' the number of non-finite results,",
           "'in thr.' the number of inputs whose exact pivots σ², ξ4 lie inside msm's singular threshold",
           "for the dtype; the worst input is printed so that it can be replayed, with the kernel's and",
           "the exact result.", "", distributions_markdown(rows[0]["n"] if rows else 300)]
    err = [r for r in rows if r["table"] == "error"]
    for fn in dict.fromkeys(r["function"] for r in err):
        rs = [r for r in err if r["function"] == fn]
        thr = "within_threshold" in rs[0]
        out += [f"## {fn}", "",
                "| category | dtype | n | max | p99 | p99 95 % CI | NaN/inf |" + (" in thr. |" if thr else "")
                + " worst input | kernel | exact |",
                "|---|---|---|---|---|---|---|" + ("---|" if thr else "") + "---|---|---|"]
        for r in rs:
            lo, hi = r["p99_interval"]
            out.append(f"| {r['category']} | {r['dtype']} | {r['n']} | {_e(r['max_abs_error'])} | "
                       f"{_e(r['p99_abs_error'])} | [{_e(lo)}, {'∞' if math.isinf(hi) else _e(hi)}] | "
                       f"{r['nonfinite']} |"
                       + (f" {r['within_threshold']} |" if thr else "")
                       + f" {_input_text(r)} | {_e(r['worst_fast'])} | {_e(r['worst_exact'])} |")
        out.append("")
    tp = [r for r in rows if r["table"] == "two_point"]
    if tp:
        out += ["## Two-point distribution after BIAS_FLOAT32: deviation from the exact Z", "",
                "Worst `|lower − Z(z < zf)|` and `|upper − Z(z ≤ zf)|` of the *unbiased* two-point distribution",
                "against the distance of zf from the nearest support point. 'kernel' is msm.shadow_intensity,",
                "'exact' is precise on the same biased moments (what an error-free kernel would return), so",
                "'exact' is the price of biasing and 'kernel' − 'exact' that of rounding and branch decisions.",
                "'lower − Z' is the largest amount by which the lower bound exceeds the true Z.", "",
                "| dtype | gap y2 − y1 | distance | n | lower: kernel | lower: exact | upper: kernel | "
                "upper: exact | lower − Z: kernel | lower − Z: exact |",
                "|---|---|---|---|---|---|---|---|---|---|"]
        for r in tp:
            out.append(f"| {r['dtype']} | {r['gap']} | {r['distance']} | {r['n']} | {_e(r['lower_dev'])} | "
                       f"{_e(r['lower_dev_exact'])} | {_e(r['upper_dev'])} | {_e(r['upper_dev_exact'])} | "
                       f"{_e(r['lower_above_Z'])} | {_e(r['lower_above_Z_exact'])} |")
        out.append("")
    out += ["## Interpretation", ""] + [f"- {s}" for s in _interpretation(rows)] + [""]
    return write_text(path, "\n".join(out))


def main(out_dir, seed=0, n=300, progress=None):
    """Measure and write ``<out_dir>/stability.md``; return its path (CLI ``moments-ref stability``)."""
    rows = measure(seed=seed, n=n, progress=progress)
    return write_markdown(Path(out_dir) / "stability.md", rows)
