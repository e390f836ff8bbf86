"""Contract rows under each declared bias, and the conventions a profile declares, against
statements computed here from the papers' definitions (not from the code under test).

* Algorithm 1's contract (HPG17 §3.2; Peters and Klein 2015, Prop. 10): the biased moments
  b' = (1 − α) b + α b* lie inside the moment space, i.e. the Hankel matrix B(b') is positive
  definite: here by a Cholesky factorisation written out below (of B − PD_MIN·I, so the
  threshold is the contract's), with b* converted from [0, 1] depth by the binomial theorem
  in exact rationals.
* The e2e chains' contract: the unbiased input is the moments of a distribution (B(b)
  positive semidefinite); a bias never moves a row into it.
* Algorithm 3's contract: decoder outputs, y1 = −1 and y2 = 1 included, ξ4 in Ψ4⁻¹'s range.
* Converted inputs are rounded once, to nearest, from the exact rational value.
"""

from __future__ import annotations

from fractions import Fraction
from math import comb

import numpy as np
import pytest

from moments_ref.golden.cases import CASES
from moments_ref.golden.contract import PD_MIN, XI4_RANGE, rows_inside
from moments_ref.golden.conventions import contract_mask, convert_inputs, profiled_case, unused_keys
from moments_ref.golden.profile import DEFAULT, Bias, Profile, parse_profile, profile_from_args



# ---------------------------------------------------------------- independent statements

def _power_moments(z, w, n):
    """(rows, n) moments sum_i w_i z_i^j, j = 1..n (the papers' b(z), weights summing to 1)."""
    return np.stack([(w * z ** j).sum(axis=-1) for j in range(1, n + 1)], axis=-1)


def _hankel(b):
    """B(b) written out: entry (i, j) = b_{i+j}, b_0 = 1."""
    k = b.shape[-1] // 2 + 1
    full = np.concatenate([np.ones(b.shape[:-1] + (1,)), b], axis=-1)
    out = np.empty(b.shape[:-1] + (k, k))
    for i in range(k):
        for j in range(k):
            out[..., i, j] = full[..., i + j]
    return out


def _positive_definite(m):
    """Rows whose symmetric ``m`` is positive definite: Cholesky, row by row of L, vectorised over rows."""
    k = m.shape[-1]
    L = np.zeros_like(m)
    ok = np.ones(m.shape[:-2], bool)
    for j in range(k):
        d = m[..., j, j] - (L[..., j, :j] ** 2).sum(axis=-1)
        ok &= d > 0
        L[..., j, j] = np.sqrt(np.where(d > 0, d, 1.0))
        for i in range(j + 1, k):
            L[..., i, j] = (m[..., i, j] - (L[..., i, :j] * L[..., j, :j]).sum(axis=-1)) / L[..., j, j]
    return ok


def _inside(b, alpha=0.0, target=None, threshold=PD_MIN):
    """Algorithm 1's contract: B((1 − α) b + α b*) − threshold·I positive definite."""
    b = np.asarray(b, np.float64)
    if target is not None:
        b = (1 - alpha) * b + alpha * np.asarray(target, np.float64)
    m = _hankel(b)
    return _positive_definite(m - threshold * np.eye(m.shape[-1]))


def _ndc_from_unit_moments(t):
    """Moments of z = 2u − 1 from those of u (binomial theorem, exact rationals)."""
    u = [Fraction(1)] + [Fraction(float(x)) for x in t]
    return tuple(float(sum(comb(j, k) * Fraction(2) ** k * Fraction(-1) ** (j - k) * u[k] for k in range(j + 1)))
                 for j in range(1, len(t) + 1))


def _rows(n_moments):
    """Rows on both sides of the moment space's boundary: 1-, 2- and 3-point distributions
    (singular unless the support has n/2 + 1 points), interior rows, and rows pushed outside."""
    k = n_moments // 2 + 1
    rng = np.random.default_rng(38 + n_moments)  # the same rows whichever tests run, in any order
    out = []
    for points in (1, 2, k - 1, k, k + 2):
        z = rng.uniform(-0.95, 0.95, (40, points))
        w = rng.dirichlet(np.ones(points), 40)
        out.append(_power_moments(z, w, n_moments))
    b = out[2].copy()
    b[:, -1] -= rng.uniform(1e-9, 0.2, len(b))  # the last moment lowered: outside
    out.append(b)
    return np.concatenate(out)


def _case_width(case):
    return 6 if "6" in case.split("-")[0] else 4


def _target(width):
    return (0.0, 0.375, 0.0, 0.375) if width == 4 else (0.0, 0.5, 0.0, 0.375, 0.0, 0.3125)


MOMENTS_INSIDE = [n for n, c in CASES.items() if c.contract == "moments_inside" and "bias" in c.profile_keys]


# ---------------------------------------------------------------- Algorithm 1's contract


@pytest.mark.parametrize("name", MOMENTS_INSIDE)
def test_contract_rows_without_a_bias_are_the_nonsingular_moments(name):
    case = CASES[name]
    b = _rows(_case_width(name)).astype(case.dtype)
    got = contract_mask(case, {"b": b, "zf": np.zeros(len(b), case.dtype)}, DEFAULT)
    want = _inside(b)
    assert np.array_equal(got, want)
    if case.dtype == "float64":  # (float32 rounding moves some singular moments off the boundary)
        assert not want[:80].any()  # one and two points: singular (k ≥ 3)
        assert want[120:160].all()  # k points in general position: inside


@pytest.mark.parametrize("name", MOMENTS_INSIDE)
@pytest.mark.parametrize("applied", ["inside", "before"])
@pytest.mark.parametrize("alpha", [3e-7, 6e-5, 0.02])
def test_contract_rows_under_a_declared_bias_are_the_biased_moments_inside(name, applied, alpha):
    case = CASES[name]
    width = _case_width(name)
    if applied == "before" and not case.bias_before:
        pytest.skip("the case's function biases itself")
    b = _rows(width).astype(case.dtype)
    prof = Profile(bias=Bias(alpha, _target(width), applied))
    got = contract_mask(case, {"b": b, "zf": np.zeros(len(b), case.dtype)}, prof)
    want = _inside(b, alpha, _target(width))
    assert np.array_equal(got, want)
    assert want.any() and not want.all()
    if width == 4:
        # the bias moves one- and two-point moments inside (the point of biasing): no longer robustness rows
        assert want[:80].all() and not np.array_equal(want, _inside(b))
        # the weight goes to the target, not to the input: a bias toward b* by 1 − α would judge other rows
        assert not np.array_equal(want, _inside(b, 1 - alpha, _target(width)))


@pytest.mark.parametrize("name", ["shadow_intensity-lower-float64", "shadow_intensity6-upper-float32"])
def test_a_unit_depth_profiles_target_is_judged_in_the_papers_frame(name):
    """[0, 1] profile: the target is declared in [0, 1] depth; the contract is the papers' inputs
    biased toward the same distribution's moments in [-1, 1] depth."""
    case = CASES[name]
    width = _case_width(name)
    t_unit = tuple(1 / (j + 1) for j in range(1, width + 1))  # uniform on [0, 1]
    t_ndc = _ndc_from_unit_moments(t_unit)  # uniform on [-1, 1]: (0, 1/3, 0, 1/5, ...)
    assert np.allclose(t_ndc, [0 if j % 2 else 1 / (j + 1) for j in range(1, width + 1)])
    # and rows on a line out of the moment space from a singular row: where the biased row leaves it
    # depends on the target
    edge = _power_moments(np.array([[-0.5, 0.25]]), np.array([[0.5, 0.5]]), width)
    line = edge - np.linspace(0, 0.01, 400)[:, None] * (np.arange(width) == width - 1)
    b = np.concatenate([_rows(width), line]).astype(case.dtype)
    alpha = 0.01
    got = contract_mask(case, {"b": b, "zf": np.zeros(len(b), case.dtype)},
                        Profile(depth="[0,1]", bias=Bias(alpha, t_unit, "inside")))
    want = _inside(b, alpha, t_ndc)
    assert np.array_equal(got, want)
    assert not np.array_equal(want, _inside(b, alpha, t_unit))  # the unconverted target judges other rows


def test_a_row_just_outside_stays_outside_under_the_smallest_bias():
    """Outside by 1e-6 in λ: α = 3e-7 toward a target 0.375 inside moves λ by about 1e-7, not enough;
    a contract that swapped α and 1 − α (or forgot the input) would take the row."""
    b = np.array([[0.0, 1.0, 0.0, 1.0]])  # moments of ±1 with equal weights: singular
    b_out = b.copy()
    b_out[0, 3] -= 1e-5
    assert not _inside(b_out, 3e-7, _target(4))[0]
    assert not rows_inside("moments_inside", {"b": b_out}, (3e-7, _target(4)))[0]
    assert rows_inside("moments_inside", {"b": b}, (3e-7, _target(4)))[0]  # the singular row: inside once biased
    assert not rows_inside("moments_inside", {"b": b})[0]


def test_the_chains_contract_judges_the_unbiased_distribution():
    b = _rows(4)
    psd = _inside(b, threshold=-PD_MIN)
    assert psd[:200].all() and not psd[200:].all()
    for bias in (None, (0.5, _target(4))):
        assert np.array_equal(rows_inside("distribution", {"b": b}, bias), psd)
    # through a profile of an e2e case: the declared bias changes no contract row
    case = CASES["e2e-nlq64-float64"]
    got = contract_mask(case, {"b": b, "zf": np.zeros((len(b), 1))}, Profile(bias=Bias(0.5, _target(4), "inside")))
    assert np.array_equal(got, psd)


def test_algorithm3s_contract_includes_the_ends_of_the_nonlinear_domain():
    lo, hi = XI4_RANGE
    below = lambda x: np.nextafter(x, -np.inf)  # noqa: E731
    above = lambda x: np.nextafter(x, np.inf)  # noqa: E731
    rows = [  # (y1, y2, v2, xi4), inside?
        ((-1.0, 1.0, 0.5, 0.1), True), ((below(-1.0), 1.0, 0.5, 0.1), False),
        ((-0.5, 1.0, 0.5, 0.1), True), ((-0.5, above(1.0), 0.5, 0.1), False),
        ((0.25, 0.25, 0.5, 0.1), True), ((above(0.25), 0.25, 0.5, 0.1), False),
        ((0.0, 0.5, 0.0, 0.1), True), ((0.0, 0.5, below(0.0), 0.1), False),
        ((0.0, 0.5, 1.0, 0.1), True), ((0.0, 0.5, above(1.0), 0.1), False),
        ((0.0, 0.5, 0.5, 1.2e-7), True), ((0.0, 0.5, 0.5, lo), True), ((0.0, 0.5, 0.5, below(lo)), False),
        ((0.0, 0.5, 0.5, 0.25), True), ((0.0, 0.5, 0.5, hi), True), ((0.0, 0.5, 0.5, above(hi)), False),
        ((0.0, 0.5, 0.5, 0.0), False), ((0.0, 0.5, 0.5, np.nan), False),
    ]
    r = np.array([x for x, _ in rows])
    want = np.array([w for _, w in rows])
    assert np.array_equal(rows_inside("representation", {"r": r}), want)


def test_an_unknown_contract_kind_is_refused():
    with pytest.raises(ValueError, match="unknown contract kind 'moments'"):
        rows_inside("moments", {"b": np.zeros((1, 4))})


# ---------------------------------------------------------------- conventions


def _round32(q):
    """The float32 nearest to the rational q (ties to even), by comparing its neighbours exactly."""
    x = np.float32(float(q))
    cands = [np.nextafter(x, np.float32(-np.inf)), x, np.nextafter(x, np.float32(np.inf))]
    best = min(cands, key=lambda c: (abs(Fraction(float(c)) - q), int(np.float32(c).view(np.int32)) & 1))
    return np.float32(best)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_bias_before_hands_the_port_the_correctly_rounded_biased_moments(dtype):
    case = CASES[f"shadow_intensity-lower-{np.dtype(dtype).name}"]
    b = _rows(4)[::23].astype(dtype)
    zf = np.linspace(-0.9, 0.9, len(b)).astype(dtype)
    alpha, target = 0.1, (0.0, 0.375, 0.0, 0.375)
    got = convert_inputs(case, {"b": b, "zf": zf}, Profile(bias=Bias(alpha, target, "before")))
    a = Fraction(alpha)
    exact = [[(1 - a) * Fraction(float(x)) + a * Fraction(t) for x, t in zip(row, target)] for row in b]
    if dtype == np.float32:
        want = np.array([[_round32(q) for q in row] for row in exact], np.float32)
    else:
        want = np.array([[q.numerator / q.denominator for q in row] for row in exact])
    assert got["b"].dtype == dtype and np.array_equal(got["b"], want)
    assert np.array_equal(got["zf"], zf)
    # the bias applied inside: the port receives the papers' moments unchanged
    inside = convert_inputs(case, {"b": b, "zf": zf}, Profile(bias=Bias(alpha, target, "inside")))
    assert np.array_equal(inside["b"], b)


def test_unit_depth_inputs_are_the_exact_conversion_rounded_once():
    case = CASES["shadow_intensity-lower-float32"]
    b = _rows(4)[::17].astype(np.float32)
    zf = np.array([-1.0, -0.3, np.float32(1 / 3), 0.7, 1.0] * 2, np.float32)[: len(b)]
    got = convert_inputs(case, {"b": b, "zf": zf}, Profile(depth="[0,1]"))
    half = Fraction(1, 2)
    for row, out in zip(b, got["b"]):
        bb = [Fraction(1)] + [Fraction(float(x)) for x in row]
        exact = [sum(comb(j, k) * half ** k * half ** (j - k) * bb[k] for k in range(j + 1)) for j in range(1, 5)]
        assert [float(x) for x in out] == [float(_round32(q)) for q in exact]
    assert got["zf"].dtype == np.float32
    assert [float(x) for x in got["zf"]] == [float(_round32((Fraction(float(z)) + 1) / 2)) for z in zf]


def test_the_clamp_test_key_applies_to_cases_with_a_clamp_only():
    clamped = Profile(clamp_test="clamped")
    assert unused_keys(CASES["shadow_intensity-lower-float32"], clamped) == ["clamp_test"]
    assert unused_keys(CASES["shade-float32"], clamped) == []
    assert unused_keys(CASES["shade-float32"], Profile(clamp=5e-6)) == []
    assert unused_keys(CASES["shadow_intensity-lower-float32"], Profile(clamp=5e-6)) == ["clamp"]
    assert unused_keys(CASES["shade-float32"], Profile(bias=Bias(0.1, _target(4), "inside"))) == ["bias"]
    assert unused_keys(CASES["shade-float32"], Profile(format=(("xi_rounding", "nearest"),))) == ["format"]
    pc = profiled_case(CASES["shade-float32"], clamped)
    assert pc.kwargs["profile"] == {"clamp_test": "clamped"}


def test_shade_under_the_clamped_test_differs_exactly_where_zf_lies_between_y2_and_y1_plus_the_clamp():
    """Algorithm 3's case test compares zf with y2 (stored) or with max(y2, y1 + clamp) (clamped)."""
    stored = profiled_case(CASES["shade-float64"], Profile(clamp_test="stored"))
    clamped = profiled_case(CASES["shade-float64"], Profile(clamp_test="clamped"))
    clamp = 1e-6
    r = np.array([[0.3, 0.3, 0.5, 0.01], [0.3, 0.3, 0.5, 0.01], [0.3, 0.8, 0.5, 0.01]])
    zf = np.array([0.3 + clamp / 2, 0.9, 0.3 + clamp / 2])
    a = np.asarray(stored.reference(r=r, zf=zf)[0])
    c = np.asarray(clamped.reference(r=r, zf=zf)[0])
    assert a[0] != c[0] and a[1] == c[1] and a[2] == c[2]


# ---------------------------------------------------------------- a profile's format keys


def test_a_functions_format_keys_override_the_files_and_keep_the_others():
    prof = parse_profile({"format": {"xi_rounding": "up", "depth_decode": "lower"},
                          "functions": {"f": {"format": {"xi_rounding": "nearest", "v2_decode": "upper"}}}})
    f = prof.for_function("f")
    assert dict(f.format) == {"xi_rounding": "nearest", "depth_decode": "lower", "v2_decode": "upper"}
    assert dict(prof.for_function("g").format) == {"xi_rounding": "up", "depth_decode": "lower"}


def test_a_format_flag_overrides_the_files_key(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text('[format]\nxi_rounding = "up"\ndepth_decode = "lower"\n')
    p = profile_from_args(path, format_depth_decode="upper")
    assert dict(p.format) == {"xi_rounding": "up", "depth_decode": "upper"}
    p = profile_from_args(path, format_subtexel_bits="6")
    assert dict(p.format) == {"xi_rounding": "up", "depth_decode": "lower", "subtexel_bits": 6}


def test_the_smallest_eigenvalue_broadcasts_over_leading_axes_and_is_float64():
    """λ_min of B(b) for a (2, 3, 4) and a (5, 6) stack equals the written-out Cholesky's verdict
    row by row, and is computed in float64 from float32 input (no narrowing)."""
    from moments_ref.golden.contract import hankel_lambda_min

    for width in (4, 6):
        b = _rows(width)[::13][:6]
        lam = hankel_lambda_min(b.reshape(2, 3, width))
        assert lam.shape == (2, 3) and lam.dtype == np.float64
        assert np.array_equal(lam.reshape(-1), hankel_lambda_min(b))
        assert np.array_equal(lam.reshape(-1) > PD_MIN, _inside(b))
        for x in b:
            assert np.isclose(hankel_lambda_min(x[None])[0], np.linalg.eigvalsh(_hankel(x))[0], rtol=0, atol=1e-15)
    # float32 input: the eigenvalue of its exact values (a float32 evaluation is off by about 1e-8)
    b32 = np.array([[0.0, 1.0, 0.0, 1.0]], np.float32)  # ±1: singular
    assert abs(hankel_lambda_min(b32)[0]) < 1e-15


def test_the_closed_moment_space_takes_rows_within_its_threshold_only():
    """The chains' contract: B(b) positive semidefinite up to PD_MIN; a row pushed out by more is outside,
    and nothing biases it back."""
    b = np.array([[0.0, 1.0, 0.0, 1.0]] * 3)  # ±1 with equal weights: λ_min = 0
    b[1, 3] -= 1e-14  # λ_min about −5e-15: inside the closed space within the threshold
    b[2, 3] -= 1e-9  # λ_min about −5e-10: outside
    assert list(rows_inside("distribution", {"b": b})) == [True, True, False]
    assert list(rows_inside("moments_inside", {"b": b})) == [False, False, False]
    assert list(rows_inside("moments_inside", {"b": b}, (0.01, _target(4)))) == [True, True, True]


@pytest.fixture(scope="module")
def lower64():
    from moments_ref.golden.spread import golden_arrays

    case = CASES["shadow_intensity-lower-float64"]
    arrays = golden_arrays(case)
    flags = np.asarray(arrays["flags"]).astype(str)
    singular = np.flatnonzero(np.char.find(flags, "singular_hankel") >= 0)[:6]
    regular = np.flatnonzero(np.char.find(flags, "singular_hankel") < 0)[:4]
    idx = np.concatenate([singular, regular])
    n = len(flags)
    return case, {k: np.asarray(v)[idx] for k, v in arrays.items() if np.ndim(v) and len(v) == n}


@pytest.mark.parametrize("bias", [None, Bias(0.0, (), "inside"), Bias(3e-7, (0.0, 0.375, 0.0, 0.375), "inside"),
                                  Bias(3e-7, (0.0, 0.375, 0.0, 0.375), "before")])
def test_singular_rows_are_robustness_rows_for_unbiased_input_only(lower64, bias):
    """One- and two-point moments (B(b) singular, outside Algorithm 1's contract) are flagged
    ``singular_hankel`` and ``robustness`` while nothing biases them; under a bias they are the
    moments at the bias floor, inside the contract (``bias_floor``), gated like any row."""
    from moments_ref.golden.conventions import profile_arrays

    case, arrays = lower64
    b = np.asarray(arrays["b"], np.float64)
    singular = ~_inside(b)
    assert list(singular) == [True] * 6 + [False] * 4  # the flags of the golden rows, by the definition
    profile = Profile(bias=bias, depth="[0,1]") if bias is None else Profile(bias=bias)
    _, out = profile_arrays(case, arrays, profile)
    flags = [set(str(f).split(",")) for f in out["flags"]]
    biased = bias is not None and bias.alpha > 0
    for i, f in enumerate(flags):
        if singular[i] and not biased:
            assert {"singular_hankel", "robustness"} <= f and "bias_floor" not in f, (i, f)
        elif singular[i]:
            assert "bias_floor" in f and not f & {"singular_hankel", "robustness", "support_point"}, (i, f)
            assert _inside(b[i:i + 1], bias.alpha, bias.target)[0]
        else:
            assert not f & {"singular_hankel", "bias_floor", "robustness"}, (i, f)


def test_visibility_is_one_minus_the_intensity_of_the_same_rows():
    case = CASES["shadow_intensity-lower-float64"]
    b = _rows(4)[120:130]
    zf = np.linspace(-0.9, 0.9, len(b))
    vis = profiled_case(case, Profile(output="visibility"))
    assert np.array_equal(np.asarray(vis.reference(b=b, zf=zf)[0]), 1 - np.asarray(case.reference(b=b, zf=zf)[0]))


@pytest.mark.parametrize("name, profile, message", [
    ("phi-float32", Profile(depth="[0,1]"), r"depth = '\[0,1\]' contradicts case 'phi-float32'"),
    ("phi-float64", Profile(output="visibility"), "output = 'visibility' contradicts case 'phi-float64'"),
    ("shadow_intensity6-lower-float64", Profile(bias=Bias(0.1, (0.0, 0.375, 0.0, 0.375), "inside")),
     "bias.target with 4 values contradicts case 'shadow_intensity6-lower-float64': it takes 6 moments"),
    ("e2e-msm64-float32", Profile(bias=Bias(0.1, (0.0, 0.375, 0.0, 0.375), "before")),
     "bias.applied = 'before' contradicts case 'e2e-msm64-float32'"),
])
def test_a_profile_contradicting_a_case_is_refused_naming_the_key(name, profile, message):
    from moments_ref import InputError

    with pytest.raises(InputError, match=message):
        profiled_case(CASES[name], profile)


def test_the_bias_target_is_taken_in_float64():
    """Rows whose biased moments straddle the threshold by less than a float32 rounding of the target:
    a target of 1/3 and 1/5 (uniform on [-1, 1]) narrowed to float32 moves them by about 1e-9."""
    alpha, t = 0.5, (0.0, 1 / 3, 0.0, 1 / 5)
    m = np.tile(_power_moments(np.array([[-0.5, 0.25]]), np.array([[0.5, 0.5]]), 4), (400, 1))
    m[:, 3] += np.linspace(-2e-8, 2e-8, 400)  # λ_min of the biased rows across ±1e-8 around 0
    b = (m - alpha * np.asarray(t)) / (1 - alpha)
    got = rows_inside("moments_inside", {"b": b}, (alpha, t))
    assert np.array_equal(got, _inside(b, alpha, t)) and got.any() and not got.all()
    t32 = np.asarray(t, np.float32).astype(np.float64)
    assert not np.array_equal(got, _inside(b, alpha, t32))  # the narrowed target judges other rows


# ---------------------------------------------------------------- derived goldens' cache


def test_derived_goldens_are_cached_on_disk_by_content_and_derived_again_when_the_file_is_foreign(
        lower64, tmp_path, monkeypatch):
    from moments_ref import InputError
    from moments_ref.golden.conventions import cache_dir, profiled_arrays

    monkeypatch.setenv("MOMENTS_REF_CACHE", str(tmp_path))
    assert cache_dir() == tmp_path / "profiles"
    monkeypatch.delenv("MOMENTS_REF_CACHE")
    assert str(cache_dir()).endswith("/.cache/moments_ref/profiles")
    monkeypatch.setenv("MOMENTS_REF_CACHE", str(tmp_path))
    case, arrays = lower64
    name = case.name
    prof = Profile(bias=Bias(0.25, (0.0, 0.375, 0.0, 0.375), "inside"))
    assert profiled_arrays(name, DEFAULT, arrays)[1] is arrays  # the papers' conventions: the golden arrays
    _, first = profiled_arrays(name, prof, arrays)
    files = sorted((tmp_path / "profiles").glob("*.npz"))
    assert len(files) == 1
    with np.load(files[0]) as g:
        assert sorted(set(g.files) - {"cache_key"}) == sorted(first) and all(
            np.array_equal(g[k], first[k]) for k in first)
    # other rows: another key, another file, other values
    other = {k: v[::-1].copy() for k, v in arrays.items()}
    _, second = profiled_arrays(name, prof, other, disk=False)
    assert len(list((tmp_path / "profiles").glob("*.npz"))) == 1  # disk=False writes nothing
    assert not np.array_equal(second["intensity"], first["intensity"])
    assert np.array_equal(second["intensity"], first["intensity"][::-1])
    # another profile's content: another key
    _, third = profiled_arrays(name, Profile(bias=Bias(0.5, (0.0, 0.375, 0.0, 0.375), "inside")), arrays)
    assert len(list((tmp_path / "profiles").glob("*.npz"))) == 2
    assert not np.array_equal(third["intensity_tolerance_float32"], first["intensity_tolerance_float32"]) or \
        not np.array_equal(third["intensity"], first["intensity"])
    with pytest.raises(InputError, match="unknown case 'nope'"):
        profiled_arrays("nope", prof)


def _straddling(alpha, t_ndc, width=4):
    """Rows whose moments biased toward ``t_ndc`` by ``alpha`` straddle the moment space's boundary
    by about 1e-8: a target rounded to float32 (about 1e-8 off for 1/3) judges some of them otherwise."""
    m = np.tile(_power_moments(np.array([[-0.5, 0.25]]), np.array([[0.5, 0.5]]), width), (400, 1))
    m[:, -1] += np.linspace(-2e-8, 2e-8, 400)
    return (m - alpha * np.asarray(t_ndc)) / (1 - alpha)


@pytest.mark.parametrize("depth", [None, "[0,1]"])
def test_a_declared_target_is_judged_in_float64_in_either_depth_convention(depth):
    case = CASES["shadow_intensity-lower-float64"]
    alpha = 0.5
    t_unit = (1 / 2, 1 / 3, 1 / 4, 1 / 5)
    t_ndc = _ndc_from_unit_moments(t_unit) if depth else (0.0, 1 / 3, 0.0, 1 / 5)
    b = _straddling(alpha, t_ndc)
    prof = Profile(depth=depth, bias=Bias(alpha, t_unit if depth else t_ndc, "inside"))
    got = contract_mask(case, {"b": b, "zf": np.zeros(len(b))}, prof)
    assert np.array_equal(got, _inside(b, alpha, t_ndc)) and got.any() and not got.all()
    t32 = _ndc_from_unit_moments(tuple(float(np.float32(x)) for x in t_unit)) if depth else \
        tuple(float(np.float32(x)) for x in t_ndc)
    assert not np.array_equal(got, _inside(b, alpha, t32))


def test_phi_under_a_declared_bias_is_judged_on_the_biased_moments():
    """phi: Algorithm 2 of a Φ that biases inside (the author's demo does) when the profile declares the
    bias: its contract is Algorithm 1's on the biased moments, and the key is used, not reported unused."""
    case = CASES["phi-float64"]
    b = _rows(4)
    prof = Profile(bias=Bias(0.02, _target(4), "inside"))
    got = contract_mask(case, {"b": b}, prof)
    assert np.array_equal(got, _inside(b, 0.02, _target(4)))
    assert not np.array_equal(got, _inside(b))  # the bias changes which rows are inside
    assert unused_keys(case, prof) == []


def test_a_bias_target_must_have_as_many_values_as_the_case_takes_moments():
    from moments_ref import InputError

    four, six = Bias(0.1, _target(4), "inside"), Bias(0.1, _target(6), "inside")
    profiled_case(CASES["shadow_intensity-lower-float64"], Profile(bias=four))
    profiled_case(CASES["shadow_intensity6-lower-float64"], Profile(bias=six))
    with pytest.raises(InputError, match="bias.target with 6 values contradicts case 'shadow_intensity-lower-float64'"
                                         ": it takes 4 moments"):
        profiled_case(CASES["shadow_intensity-lower-float64"], Profile(bias=six))


def test_unit_depth_float64_inputs_are_rounded_once_to_float64():
    case = CASES["shadow_intensity-lower-float64"]
    zf = np.array([-1.0, -0.3, 1 / 3, 0.7, 1 - 2.0 ** -30, 1.0])
    b = np.tile(_rows(4)[130], (len(zf), 1))
    got = convert_inputs(case, {"b": b, "zf": zf}, Profile(depth="[0,1]"))
    assert got["zf"].dtype == np.float64
    want = [(Fraction(float(z)) + 1) / 2 for z in zf]
    assert [float(x) for x in got["zf"]] == [q.numerator / q.denominator for q in want]


# ---------------------------------------------------------------- a profile refused, naming its key

_B = {"alpha": 0.1, "target": [0.0, 0.375, 0.0, 0.375], "applied": "inside"}


@pytest.mark.parametrize("data, message", [
    ([1, 2], "profile p: expected a table of keys"),
    ({"bias": 3}, r"profile p: bias: expected a table \(alpha, target, applied\)"),
    ({"bias": {**_B, "beta": 1}}, r"profile p: bias.beta: unknown key"),
    ({"bias": {"alpha": 0.1, "target": _B["target"]}}, r"profile p: bias.applied: missing"),
    ({"bias": {**_B, "applied": "after"}}, r"profile p: bias.applied: expected one of 'inside', 'before', got 'after'"),
    ({"bias": {**_B, "target": [0.0, 0.5, 0.0, 0.2]}}, r"bias.target: \[0.0, 0.5, 0.0, 0.2\] is not a moment vector"),
    ({"format": "up"}, r"profile p: format: expected a table of texel-format choices"),
    ({"format": {"rounding": "up"}}, r"profile p: format.rounding: unknown key"),
    ({"functions": {"f": {"functions": {}}}}, r"profile p: functions.f.functions: unknown key"),
])
def test_a_profile_is_refused_naming_the_key(data, message):
    from moments_ref import InputError

    with pytest.raises(InputError, match=message):
        parse_profile(data, "p")


def test_a_singular_target_is_a_moment_vector_and_a_slightly_negative_one_is_not():
    """b* = (0, 1, 0, 1) (±1, equal weights): λ_min = 0, on the boundary: allowed; b4 lowered by 1e-6:
    λ_min about −5e-7 < 0: no distribution on the real line has it."""
    from moments_ref import InputError

    ok = parse_profile({"bias": {**_B, "target": [0.0, 1.0, 0.0, 1.0]}}, "p")
    assert ok.bias.target == (0.0, 1.0, 0.0, 1.0)
    with pytest.raises(InputError, match="negative eigenvalue"):
        parse_profile({"bias": {**_B, "target": [0.0, 1.0, 0.0, 1.0 - 1e-6]}}, "p")


def test_a_profile_file_must_be_a_regular_file(tmp_path):
    from moments_ref import InputError
    from moments_ref.golden.profile import load_profile

    with pytest.raises(InputError, match="expected a regular file"):
        load_profile(tmp_path)
    (tmp_path / "p.toml").write_text('depth = "[0,1]"\n[functions.f]\noutput = "visibility"\n')
    assert load_profile(tmp_path / "p.toml").depth == "[0,1]"
    p = profile_from_args(tmp_path / "p.toml", function="f")
    assert (p.depth, p.output, p.functions) == ("[0,1]", "visibility", ())
    assert profile_from_args(tmp_path / "p.toml").output is None


def test_visibility_spreads_are_one_minus_the_intensitys():
    """The legitimate evaluations the tolerance spans (spread_hook) turn into visibilities the same way."""
    case = CASES["shadow_intensity-lower-float64"]
    vis = profiled_case(case, Profile(output="visibility"))
    ins = {"b": _rows(4)[120:126], "zf": np.linspace(-0.5, 0.5, 6)}
    a, c = case.spread_hook(ins, np.float64), vis.spread_hook(ins, np.float64)
    assert len(a) == len(c) > 0
    for x, y in zip(a, c):
        assert all(np.array_equal(1 - np.asarray(u), np.asarray(w), equal_nan=True) for u, w in zip(x, y))


@pytest.mark.parametrize("name", ["bias_moments-float32-float64", "bias_moments-unorm16-float64"])
def test_a_default_bias_under_unit_depth_biases_toward_the_same_distribution(name):
    """The bias is affine in the moments: in [0, 1] depth it must be the [-1, 1] bias seen through
    z -> (z + 1)/2 (the preset's target converted with the moments), for any target."""
    from moments_ref.scene.depth import moments_affine

    case = CASES[name]
    unit = profiled_case(case, Profile(depth="[0,1]"))
    b = _rows(4)[120:140]
    r_ndc = np.asarray(case.reference(b=b)[0], np.float64)
    r_unit = np.asarray(unit.reference(b=moments_affine(b, 0.5, 0.5))[0], np.float64)
    assert np.abs(r_unit - moments_affine(r_ndc, 0.5, 0.5)).max() < 1e-15  # rounding only


def _at_the_threshold(width, threshold, rng, count=24):
    """Rows whose eigensolver λ_min lies within a few units of roundoff of ``threshold``: singular two-point
    moments biased toward the interior by the α that bisection finds at the crossing, then the α's float64
    neighbours on both sides (the rows a certificate with too little margin would decide wrongly)."""
    from moments_ref.golden.contract import hankel_lambda_min

    b = _power_moments(rng.uniform(-0.9, 0.9, (count, 2)), rng.dirichlet(np.ones(2), count), width)
    t = np.asarray(_target(width))
    lo, hi = np.zeros(count), np.ones(count)
    for _ in range(80):
        mid = (lo + hi) / 2
        above = hankel_lambda_min((1 - mid[:, None]) * b + mid[:, None] * t) > threshold
        hi, lo = np.where(above, mid, hi), np.where(above, lo, mid)
    out = []
    for k in range(-4, 5):
        a = hi * (1 + k * 2.0**-50)
        out.append((1 - a[:, None]) * b + a[:, None] * t)
    return np.concatenate(out)


@pytest.mark.parametrize("width", [4, 6])
def test_the_certificate_decides_as_the_eigensolver(width):
    """``hankel_above`` equals ``hankel_lambda_min(b) > threshold`` on every row: interior, singular and outside
    rows, rows whose eigensolver value is within a few roundoffs of the threshold (both thresholds of the
    contracts), large and small scales, float32 input and non-finite moments; and the Cholesky certificate alone
    never calls a row inside that the eigensolver puts outside, while deciding the clearly interior rows itself."""
    from moments_ref.golden.contract import CERTIFY_MARGIN, _cholesky_succeeds, _hankel, hankel_above, hankel_lambda_min

    rng = np.random.default_rng(7 + width)
    base = _rows(width)
    scaled = [base * np.array([s ** j for j in range(1, width + 1)]) for s in (1e-3, 1e3)]
    odd = base[:6].copy()
    odd[0, 1], odd[1, -1], odd[2, 0] = np.nan, np.inf, -np.inf
    for threshold in (PD_MIN, -PD_MIN):
        rows = np.concatenate([base, *scaled, odd, _at_the_threshold(width, threshold, rng)])
        with np.errstate(invalid="ignore"):
            want = np.array([np.all(np.isfinite(r)) and hankel_lambda_min(r[None])[0] > threshold for r in rows])
        got = hankel_above(rows, threshold)
        assert np.array_equal(got, want)
        assert np.array_equal(hankel_above(rows.reshape(-1, 1, width), threshold).reshape(-1), want)
        h = _hankel(rows)
        with np.errstate(invalid="ignore"):  # the non-finite rows: inf − inf
            s = threshold + CERTIFY_MARGIN * np.abs(np.trace(h, axis1=-2, axis2=-1))
            cert = _cholesky_succeeds(h - s[:, None, None] * np.eye(h.shape[-1]))
        assert not (cert & ~want).any()
        # The fast path decides every row whose λ_min clears the threshold by 100 margins (relative to the trace:
        # below that the eigensolver's own rounding decides, and only it can reproduce itself).
        finite = np.isfinite(h).all(axis=(1, 2))
        lam = np.linalg.eigvalsh(np.where(finite[:, None, None], h, 0))[:, 0]
        clear = finite & (lam - threshold > 100 * CERTIFY_MARGIN * np.abs(np.trace(h, axis1=1, axis2=2)))
        assert clear.sum() >= len(base) // 4 and cert[clear].all()
    b32 = _rows(width).astype(np.float32)
    assert np.array_equal(hankel_above(b32, PD_MIN), hankel_lambda_min(b32) > PD_MIN)
    inf2 = _rows(width)[:1].copy()
    inf2[0, 1] = np.inf  # b2 = +inf: the eigensolver does not converge; the row is outside without asking it
    assert not hankel_above(inf2, PD_MIN)[0]


def _localizing_min(z, w):
    """Smallest eigenvalue of Σ w z (1 − z) [[1, z], [z, z²]] (the localizing matrix of z (1 − z) of a
    distribution, from its points), by the 2×2 closed form."""
    a, c, d = ((w * z * (1 - z) * z**k).sum(axis=-1) for k in (0, 1, 2))
    return (a + d) / 2 - np.sqrt(((a - d) / 2) ** 2 + c**2)


def test_the_hausdorff_contract_is_a_distribution_on_the_unit_interval_and_a_receiver_on_it():
    """Peters and Klein 2015's Hausdorff contract against statements computed from the distributions: B(b) positive
    definite (the written-out Cholesky), the localizing matrix of z (1 − z) positive semidefinite up to float32
    rounding (its eigenvalue from the points), zf in [0, 1] with both ends included."""
    from moments_ref.golden.contract import HAUSDORFF_SLACK

    rng = np.random.default_rng(41)
    n = 60
    z = rng.uniform(0, 1, (n, 4))
    w = rng.dirichlet(np.ones(4), n)
    z[:10, 0], z[10:20, 1] = 0.0, 1.0  # texels touching the ends of [0, 1]
    z[20:30, 2] = rng.uniform(1.05, 1.5, 10)  # a depth behind the far plane: outside where its weight tells
    z[30:40, 3] = rng.uniform(-0.5, -0.05, 10)  # and one in front of the near plane
    z[40:45, 1:] = z[40:45, :1]  # one point: B(b) singular, outside
    zf = rng.uniform(0, 1, n)
    zf[:5], zf[5:10], zf[50:55], zf[55:] = 0.0, 1.0, -1e-3, 1 + 1e-3
    b = _power_moments(z, w, 4).astype(np.float32)
    want = (_inside(b) & (_localizing_min(z, w) >= -HAUSDORFF_SLACK) & (zf >= 0) & (zf <= 1))
    assert want[10:20].all() and (~want[20:40]).sum() >= 10 and not want[40:45].any() and not want[50:].any()
    assert np.array_equal(rows_inside("hausdorff", {"b": b, "zf": zf.astype(np.float32)}), want)
    # float32 rounding of a texel on the boundary: depths 0, 1 and one interior depth have a localizing matrix
    # of rank one (λ_min 0); stored in float32 its λ_min is a few 1e-8 negative: inside. Pushed by 1e-5: outside.
    edge = _power_moments(np.array([[0.0, 0.37, 1.0]]), np.array([[0.3, 0.3, 0.4]]), 4)
    pushed = edge.copy()
    pushed[0, 0] -= 1e-5  # b1 − b2 below its value by 1e-5: λ_min of the localizing matrix about −1e-5
    rows = np.concatenate([edge, pushed]).astype(np.float32)
    assert rows_inside("hausdorff", {"b": rows, "zf": np.float32([0.5, 0.5])}).tolist() == [True, False]
    # float64 input is judged in float64 (a receiver 1e-9 past 1 is not rounded onto it), and leading axes broadcast
    b64, zf64 = _power_moments(z[:3], w[:3], 4), np.array([1 + 1e-9, -1e-9, 0.5])
    assert rows_inside("hausdorff", {"b": b64, "zf": zf64}).tolist() == [False, False, True]
    got = rows_inside("hausdorff", {"b": b.reshape(3, 20, 4), "zf": zf.astype(np.float32).reshape(3, 20)})
    assert got.shape == (3, 20) and np.array_equal(got.reshape(-1), want)


def test_the_eigensolver_sees_only_the_rows_the_certificate_leaves(monkeypatch):
    """Interior rows are decided by the factorization alone: the eigensolver is called on the singular and
    outside rows of the sample (and the rows at the threshold), never on a row clear of it."""
    from moments_ref.golden import contract

    seen = []
    real = contract.hankel_lambda_min
    monkeypatch.setattr(contract, "hankel_lambda_min", lambda b: seen.append(np.array(b)) or real(b))
    for width in (4, 6):
        rows = _rows(width)
        lam = real(rows)
        clear = lam - PD_MIN > 1e-9
        seen.clear()
        assert np.array_equal(contract.hankel_above(rows, PD_MIN), lam > PD_MIN)
        asked = np.concatenate(seen) if seen else np.empty((0, width))
        assert clear.sum() >= len(rows) // 4 and len(asked) == (~clear).sum()
        assert {tuple(x) for x in asked} == {tuple(x) for x in rows[~clear]}
