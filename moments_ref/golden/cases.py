"""The golden cases: one public function at one dtype on labelled rows.

A :class:`Case` names the function, its inputs in the order a port receives them,
its outputs, the rows, the reference (this package's own implementation, run in the
case's dtype) and the ground truth (the mpmath twin where one exists). ``kwargs``
are plain values a port can use (``{"bound": "lower"}``, a bias preset's α and b*),
never Python names.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
.. [3] Peters and Klein 2015: Christoph Peters and Reinhard Klein. 2015. *Moment Shadow Mapping*.
       In Proceedings of the 19th ACM SIGGRAPH Symposium on Interactive 3D Graphics and Games (i3D
       '15). ACM, 7–14. https://doi.org/10.1145/2699276.2699277
"""

from __future__ import annotations

import hashlib
import importlib
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .. import precise
from .._arrays import InputError
from ..moments import BIAS_FLOAT32, BIAS_UNORM16
from . import contract as _contract_mod
from . import bilinear, endtoend, engine, kernels, texel_codes, texel_truth
from .paper import alg1_paper_spread, alg3_paper_spread
from .variants import alg1_variant, bias_variant, phi_variant, pack64_variant, shade_variant, unpack32_variant, xi_decode_spread
from ._rows import (_alg1_rows, _hausdorff_rows, _moment6_rows, _moment_rows, _msm6_rows, _optimized_rows, _phi_rows, _r10_rows,
                   _unorm16_rows)
from ._rows_nonlinear import (_pack32_input_rows, _pack64_input_rows, _psi4_inverse_rows, _psi4_rows,
                             _reencode_rows, _representation_rows, _shade_rows)
from .notes import register as _register_note
from .truth import shade_clamped

__all__ = ["Case", "CASES", "bound_case", "case_rows", "case_table", "evaluate_reference", "expected_outputs", "call_implementation"]


@dataclass(frozen=True)
class Case:
    """One golden case: a public function evaluated at one dtype on labelled rows."""

    name: str
    function: str
    dtype: str
    inputs: tuple
    outputs: tuple
    rows: Callable  # (rng, dtype) -> Rows (inputs in float64 or int, cast later)
    reference: Callable  # (**inputs) -> tuple of outputs, in the inputs' dtype
    truth: Callable | None = None  # (**inputs) -> tuple of float64 outputs
    kwargs: dict = field(default_factory=dict)  # plain JSON values
    integer_inputs: dict = field(default_factory=dict)  # input name -> unsigned dtype
    description: str = ""
    metric: str = "abs"  # "abs", "ulps" or "exact" (integer outputs)
    value_range: tuple | None = None  # (lo, hi) every output value must lie in, if any
    perturb: bool = True  # measure the spread on inputs scaled by 1 ± 3 ulps (off for biasing)
    floor_scale: tuple | float = 1.0  # tolerance floors are ulps of max(|value|, scale), per component
    spread_hook: Callable | None = None  # (inputs, dtype) -> extra legitimate outputs (decoders' constants)
    margin: Callable | None = None  # integer outputs: (**inputs) -> per row, distance to a rounding boundary
    # Integer outputs, the per-component tie rule (golden.bands.tie_accepted): (**inputs) -> list of output tuples, the
    # exact codes with components on their own rounding tie taken across it (golden.texel_codes); None: the per-row rule
    tie_neighbours: Callable | None = None
    extra: Callable | None = None  # (inputs) -> more arrays for the golden file (a kernel's expected codes)
    row_inputs: bool = True  # False: inputs are whole-case arrays (points, views), not one entry per row
    contract: str | None = None  # kind of contract (golden.contract.TEXT): rows outside are robustness rows
    # How an engine profile (golden.profile) applies to the case (golden.conventions):
    depth_roles: dict = field(default_factory=dict)  # input -> "moments" | "depth" (a depth-free algorithm)
    default_bias: tuple | None = None  # ("inside" | "before", BiasPreset): the bias of the case's own chain
    bias_before: bool = False  # a caller's bias just before the call makes sense for the function
    variant: Callable | None = None  # (bias=, clamp=, fmt=) -> replacements of reference, truth, spread_hook
    profile_keys: tuple = ()  # the profile keys the case uses: "bias", "clamp", "format"
    width: int = 0  # moments per row (4 or 6) where a bias target must match
    aux: tuple = ()  # extra row arrays stored in the golden file, not given to the port (engine distributions)
    deriver: Callable | None = None  # replaces spread.derive: (case, arrays, category, comment, flags, contract)
    engine: dict = field(default_factory=dict)  # context of an engine case (golden.engine)
    depth: str = "[-1,1]"  # the depth convention the case's inputs are written in (a profile may declare it)
    notes: dict = field(default_factory=dict)  # flags its rows introduce: flag -> (description, effect, cause)
    # Chains whose expected value stays the float64 reference: an mpmath twin only bands.confirm uses,
    # (**inputs) -> per output (lo, hi), the least and largest exact value (golden.truth.nlq_chain).
    confirm_truth: Callable | None = None

    @property
    def contract_text(self):
        return _contract_mod.TEXT.get(self.contract, "every row (the algorithm defines every input of the case)")

    @property
    def integer_output(self):
        return self.metric == "exact"


_U16, _U32 = {"u": "uint16"}, {"p": "uint32"}


def _tuple(out):
    return out if isinstance(out, tuple) else (out,)


def _precise(name, **kwargs):
    def truth(*args, **kw):
        return _tuple(getattr(precise, name)(*args, **kw, **kwargs))

    return truth


def _wrap(path, **kwargs):
    """A reference calling ``moments_ref.<path>`` and returning a tuple."""
    module, name = path.rsplit(".", 1)

    def ref(*args, **kw):
        fn = getattr(importlib.import_module(f"moments_ref.{module}"), name)
        return _tuple(fn(*args, **kw, **kwargs))

    return ref


def _texel(name):
    """Ground truth ``moments_ref.golden.texel_truth.<name>`` (independent of packing and affine)."""
    return getattr(texel_truth, name)


def _margin(name, module=texel_truth):
    """Per row, how far the exact scaled values lie from a rounding boundary (texel_truth, ``margin=True``)."""
    fn = getattr(module, name)
    return lambda **inputs: fn(**inputs, margin=True)[1]


def _fast(name):
    """The exact codes of an encoder, vectorised (``moments_ref.golden.texel_codes.<name>``, equal to texel_truth's):
    ``(truth, margin, tie_neighbours)`` keyword arguments of its cases."""
    return {"truth": getattr(texel_codes, name), "margin": _margin(name, texel_codes),
            "tie_neighbours": getattr(texel_codes, f"{name}_neighbours")}


def _shade_truth(r, zf):
    return (shade_clamped(r, zf),)


def _preset_kwargs(preset):
    return {"preset": {"alpha": preset.alpha, "target": list(preset.target)}}


#: Floors of (y1, y2, v2, ξ4): ulps of 1 for the O(1) quantities, of ξ4 itself for ξ4.
_R_SCALE = (1.0, 1.0, 1.0, 0.0)


def _six_all_roots(bound):
    """Six moments with all three roots of the cubic, then the weights below zf summed.

    The reference needs one root (msm6, step 3) and so do the shipped ports; a port may
    solve for all three (two Newton steps each) and sum the weights of the roots below zf,
    which rounds differently in float32 (the shipped ports did so with the trigonometric
    closed form until the sweep confirmed rows 5e-5 outside this band, near a bound of 1,
    where 1 − w0 − w is exact and a sum of three weights is not). Evaluated through
    :func:`moments_ref.msm6.canonical_representation` on the inputs as given and scaled
    by 1 ± 3 ulps, like the reference's own variants (``golden.spread``).
    """

    def hook(inputs, dt):
        from ..msm6 import canonical_representation

        eps = 3 * float(np.finfo(dt).eps)
        out = []
        for f in (1.0, 1 + eps, 1 - eps):
            b = (np.asarray(inputs["b"], np.float64) * f).astype(dt)
            zf = np.asarray(inputs["zf"], np.float64)
            zf = np.where(np.abs(zf * f) > 1, zf, zf * f).astype(dt)  # depths in [-1, 1] stay there
            d, w = canonical_representation(b, zf)
            lower = (w[..., 1:] * (d[..., 1:] < d[..., :1])).sum(axis=-1)
            value = lower if bound == "lower" else lower + w[..., 0]
            out.append((np.clip(value, 0, 1),))
        return out

    return hook


_ALG1 = dict(contract="moments_inside")
#: Profile keys of a depth-free bound on moments b and a depth zf (any depth convention, any bias).
_BOUND = dict(depth_roles={"b": "moments", "zf": "depth"}, bias_before=True, profile_keys=("bias",))


def _float_cases(dt):
    cases = []
    for bound in ("lower", "upper"):
        cases.append(Case(
            f"shadow_intensity-{bound}-{dt}", "msm.shadow_intensity", dt, ("b", "zf"), ("intensity",),
            _alg1_rows, _wrap("msm.shadow_intensity", bound=bound), _precise("shadow_intensity", bound=bound),
            {"bound": bound}, description=f"HPG17 Algorithm 1, {bound} bound; expected values from the mpmath twin",
            value_range=(0, 1), spread_hook=alg1_paper_spread(bound), **_ALG1, **_BOUND,
            variant=alg1_variant(bound), width=4))
    for preset in (BIAS_FLOAT32, BIAS_UNORM16):
        cases.append(Case(
            f"bias_moments-{preset.name}-{dt}", "moments.bias_moments", dt, ("b",), ("b_biased",),
            _moment_rows, _wrap("moments.bias_moments", preset=preset), _precise("bias_moments", preset=preset),
            _preset_kwargs(preset), metric="ulps", perturb=False, depth_roles={"b": "moments"},
            profile_keys=("bias",), variant=bias_variant(), width=4, default_bias=("inside", preset),
            description=f"HPG17 §3.2 biasing b' = (1 - alpha) b + alpha b*, alpha = {preset.alpha:g}, "
                        f"b* = {list(preset.target)}; gated in ulps (the change is a few ulps)"))
    cases += [
        Case(f"to_optimized-{dt}", "affine.to_optimized", dt, ("b",), ("q",), _moment_rows,
             _wrap("affine.to_optimized"), _texel("to_optimized"),
             description="Slides, 'Compute moments in resolve'; expected from the slide's matrix in mpmath"),
        Case(f"from_optimized-{dt}", "affine.from_optimized", dt, ("q",), ("b",), _optimized_rows,
             _wrap("affine.from_optimized"), _texel("from_optimized"),
             description="Slides, 'Retrieve moments'; expected from the inverse of the slide's matrix in mpmath"),
        Case(f"encode_unorm16-{dt}", "affine.encode_unorm16", dt, ("b",), ("u",), _moment_rows,
             _wrap("affine.encode_unorm16"), _texel("encode_unorm16"), metric="exact",
             margin=_margin("encode_unorm16"), tie_neighbours=texel_codes.encode_unorm16_neighbours,
             description="64-bit affine texel: four UNORM16 of the optimized basis; expected codes exact"),
        Case(f"decode_unorm16-{dt}", "affine.decode_unorm16", dt, ("u",), ("b",), _unorm16_rows,
             _wrap("affine.decode_unorm16"), _texel("decode_unorm16"), integer_inputs=_U16,
             description="64-bit affine texel decode; expected from the slide's inverse in mpmath"),
        Case(f"to_optimized6-{dt}", "affine.to_optimized6", dt, ("b",), ("q",), _moment6_rows,
             _wrap("affine.to_optimized6"), _texel("to_optimized6"),
             description="Slides, six-moment 'Quantization transform'; expected from the printed matrices"),
        Case(f"encode_r10g10b10a2-{dt}", "affine.encode_r10g10b10a2", dt, ("b",), ("p",), _moment6_rows,
             _wrap("affine.encode_r10g10b10a2"), _texel("encode_r10g10b10a2"), metric="exact",
             margin=_margin("encode_r10g10b10a2"), tie_neighbours=texel_codes.encode_r10g10b10a2_neighbours,
             description="six moments in 2×R10G10B10A2_UNORM; expected codes exact"),
        Case(f"decode_r10g10b10a2-{dt}", "affine.decode_r10g10b10a2", dt, ("p",), ("b",), _r10_rows,
             _wrap("affine.decode_r10g10b10a2"), _texel("decode_r10g10b10a2"), integer_inputs=_U32,
             description="six moments from 2×R10G10B10A2_UNORM; expected from the printed matrices' inverses"),
        *[Case(f"shadow_intensity6-{bound}-{dt}", "msm.shadow_intensity", dt, ("b", "zf"), ("intensity",),
               _msm6_rows, _wrap("msm.shadow_intensity", bound=bound), _precise("shadow_intensity6", bound=bound),
               {"bound": bound}, value_range=(0, 1), spread_hook=_six_all_roots(bound), **_ALG1, **_BOUND,
               variant=alg1_variant(bound, six=True, base_hook=_six_all_roots(bound)), width=6,
               description=f"six-moment {bound} bound (slides, 'Prefiltered single scattering'); b (n, 6); "
                           "expected from the mpmath twin")
          for bound in ("lower", "upper")],
    ]
    return cases + _hausdorff_cases(dt) + _nonlinear_cases(dt)


#: The flag of the Hausdorff rows at a receiver at depth 0: (description, effect, the diagnosis's cause).
_DEPTH_0 = {"receiver_at_depth_0": (
    "Hausdorff bound: a receiver at depth 0, where the four-point representation (0, zf, x, 1) divides by zf; "
    "the bound is defined there (no mass lies below 0: the lower bound is 0, the upper bound Algorithm 1's "
    "principal representation through 0)",
    "gated: a port that takes the four-point branch at zf = 0 returns inf or NaN and fails here",
    "a receiver at depth 0: the Hausdorff bound's four-point weights divide by zf there; the bound is defined "
    "(lower 0: nothing lies below 0), so take the three-point branch or return it at zf <= 0")}


def _hausdorff_cases(dt):
    """The Hausdorff bound (Peters and Klein 2015), depths in [0, 1]: a port declares ``bound = "hausdorff"``."""
    return [Case(f"hausdorff-{bound}-{dt}", "hausdorff.shadow_intensity", dt, ("b", "zf"), ("intensity",),
                 _hausdorff_rows, _wrap("hausdorff.shadow_intensity", bound=bound),
                 _precise("hausdorff_intensity", bound=bound), {"bound": bound}, value_range=(0, 1),
                 contract="hausdorff", depth="[0,1]", width=4, notes=_DEPTH_0,
                 description=f"Peters and Klein 2015, the Hausdorff {bound} bound (depths and zf in [0, 1]); "
                             "expected values from the mpmath twin")
            for bound in ("lower", "upper")]


def _nonlinear_cases(dt):
    """Cases of HPG17 §3: Φ, Φ⁻¹, Ψ4, Ψ4⁻¹, Algorithm 3 and the texel formats."""
    return [
        Case(f"phi-{dt}", "nonlinear.phi", dt, ("b",), ("r",), _phi_rows, _wrap("nonlinear.phi"),
             _precise("phi"), floor_scale=_R_SCALE, **_ALG1, profile_keys=("bias",), variant=phi_variant(),
             description="HPG17 Algorithm 2 on BIAS_FLOAT32-biased moments; expected from mpmath"),
        Case(f"phi_inverse-{dt}", "nonlinear.phi_inverse", dt, ("r",), ("b",), _representation_rows,
             _wrap("nonlinear.phi_inverse"), _precise("phi_inverse"), description="HPG17 Eq. (4)"),
        Case(f"psi4-{dt}", "nonlinear.psi4", dt, ("xi4",), ("u",), _psi4_rows, _wrap("nonlinear.psi4"),
             _precise("psi4"), description="HPG17 §3.3 warp of ξ4, clamped at 1.2e-7", value_range=(0, 1)),
        Case(f"psi4_inverse-{dt}", "nonlinear.psi4_inverse", dt, ("u",), ("xi4",), _psi4_inverse_rows,
             _wrap("nonlinear.psi4_inverse"), _precise("psi4_inverse"), metric="ulps",
             description="inverse of Ψ4; gated in ulps (ξ4 spans six decades)"),
        Case(f"shade-{dt}", "nonlinear.shade", dt, ("r", "zf"), ("intensity",), _shade_rows,
             _wrap("nonlinear.shade"), _shade_truth, value_range=(0, 1), contract="representation",
             variant=shade_variant(), profile_keys=("clamp",), spread_hook=alg3_paper_spread(),
             description="HPG17 Algorithm 3 with its §3.4 clamps (v2 in [1e-6, 1 - 1e-6], y2 - y1 >= 1e-6); "
                         "expected: Algorithm 3 with the clamps in mpmath"),
        Case(f"pack64-{dt}", "packing.pack64", dt, ("r",), ("q",), _representation_rows,
             _wrap("packing.pack64"), metric="exact", **_fast("pack64"),
             variant=pack64_variant(), profile_keys=("format",),
             description="64-bit texel, docs/formats.md; expected codes exact"),
        Case(f"reencode64-{dt}", "packing.pack64", dt, ("r",), ("q",), _reencode_rows,
             _wrap("packing.pack64"), metric="exact", **_fast("pack64"),
             variant=pack64_variant(), profile_keys=("format",),
             description="64-bit texel of representations whose ξ4 is a decoded code, or one ulp above one "
                         "(the encoder's decode check of docs/formats.md)"),
        Case(f"unpack64-{dt}", "packing.unpack64", dt, ("q",), ("r",), _pack64_input_rows,
             _wrap("packing.unpack64"), _texel("unpack64"), integer_inputs={"q": "uint16"}, floor_scale=_R_SCALE,
             spread_hook=xi_decode_spread("64"),
             description="64-bit texel decode, docs/formats.md; expected from the layout in mpmath"),
        Case(f"pack32-{dt}", "packing.pack32", dt, ("r",), ("p",), _representation_rows,
             _wrap("packing.pack32"), metric="exact", **_fast("pack32"),
             description="32-bit texel with the triangle fold, docs/formats.md; expected codes exact"),
        Case(f"reencode32-{dt}", "packing.pack32", dt, ("r",), ("p",), _reencode_rows,
             _wrap("packing.pack32"), metric="exact", **_fast("pack32"),
             description="32-bit texel of decoded representations and of ξ4 on 6-bit Ψ4 cell boundaries"),
        Case(f"unpack32-{dt}", "packing.unpack32", dt, ("p",), ("r",), _pack32_input_rows,
             _wrap("packing.unpack32"), _texel("unpack32"), integer_inputs={"p": "uint32"}, floor_scale=_R_SCALE,
             spread_hook=xi_decode_spread("32"), variant=unpack32_variant(), profile_keys=("format",),
             description="32-bit texel decode (depths and ξ4 at the upper end of their cell, √v2 at its centre), "
                         "docs/formats.md; expected from the layout in mpmath"),
    ]


def _cases():
    cases = []
    for dt in ("float32", "float64"):
        cases += _float_cases(dt)
        cases += [Case(**spec) for spec in endtoend.case_specs(dt)]
        cases += [Case(**spec) for spec in engine.engine_specs(dt)]
    cases += [Case(**spec) for spec in bilinear.case_specs()]
    return cases + [Case(**spec) for spec in kernels.case_specs()]


CASES = {c.name: c for c in _cases()}
for _case in CASES.values():  # the flags a case's entry brings, into the notes table (golden.notes.register)
    for _flag, _text in _case.notes.items():
        _register_note(_flag, *_text)


def bound_case(name, bound):
    """The case a port of ``msm.shadow_intensity`` is judged by when its profile declares ``bound``.

    ``bound = "hausdorff"`` (docs/ports.md) maps ``shadow_intensity-{lower,upper}[-dtype]`` to
    ``hausdorff-{lower,upper}[-dtype]``; any other name, or no declaration, is returned as given.
    """
    if bound == "hausdorff" and name.startswith("shadow_intensity-"):
        return "hausdorff-" + name.removeprefix("shadow_intensity-")
    return name


def _seed(name):
    return int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "little")


def case_table(case: Case):
    """The rows of ``case``: (inputs cast to the case's dtypes, category, comment, flags)."""
    rng = np.random.default_rng(_seed(case.name))
    rows = case.rows(rng, np.dtype(case.dtype))
    inputs = {}
    for k in case.inputs:
        v = np.asarray(rows.inputs[k])
        inputs[k] = v.astype(case.integer_inputs[k] if k in case.integer_inputs else case.dtype)
    for k in case.aux:  # stored as generated (float64 distributions, int32 row indices)
        inputs[k] = np.asarray(rows.inputs[k])
    return inputs, np.asarray(rows.category), np.asarray(rows.comment), list(rows.flags)


def case_rows(case: Case):
    """The rows of ``case``: (inputs dict cast to the case's dtypes, category, comment)."""
    inputs, category, comment, _ = case_table(case)
    return inputs, category, comment


def evaluate_reference(case, inputs, dtype):
    """The reference's outputs (tuple) for ``inputs`` evaluated in ``dtype``.

    Float inputs are cast to ``dtype``; decoders (integer inputs) get ``dtype=``.
    """
    args = {k: (v if k in case.integer_inputs else np.asarray(v).astype(dtype)) for k, v in inputs.items()}
    if case.integer_inputs:
        return case.reference(**args, dtype=np.dtype(dtype))
    return case.reference(**args)


def expected_outputs(case, inputs):
    """Expected values: the ground truth (exact codes for encoders) where there is one, else the reference.

    Without a ground truth, encoders' codes are the reference's in the case's dtype and
    other outputs the reference's in float64.
    """
    if case.integer_output and case.truth is None:
        return evaluate_reference(case, inputs, case.dtype)
    if case.integer_output:
        return case.truth(**inputs)
    if case.truth is not None:
        as64 = {k: (v if k in case.integer_inputs else np.asarray(v).astype(np.float64)) for k, v in inputs.items()}
        return case.truth(**as64)
    return evaluate_reference(case, inputs, np.float64)


def call_implementation(fn, case, inputs, vectorized=True, argument="fn"):
    """A foreign implementation's outputs on the case's rows, as ``{output: array}``.

    ``fn(*inputs)`` in the case's input order; with ``vectorized=False`` once per row, the rows
    stacked. ``argument`` names ``fn`` in the refusal of a wrong number of outputs (``oracle.check``
    calls it ``candidate``).
    """
    args = [inputs[k] for k in case.inputs]
    if vectorized:
        got = fn(*args)
    else:
        rows = [fn(*[a[i] for a in args]) for i in range(len(args[0]))]
        got = (tuple(np.stack([np.asarray(r[j]) for r in rows]) for j in range(len(case.outputs)))
               if len(case.outputs) > 1 else np.stack([np.asarray(r) for r in rows]))
    got = tuple(got) if isinstance(got, (tuple, list)) else (got,)
    if len(got) != len(case.outputs):
        raise InputError(f"{argument}: expected {len(case.outputs)} output(s) {case.outputs}, got {len(got)}")
    return dict(zip(case.outputs, (np.asarray(g) for g in got)))
