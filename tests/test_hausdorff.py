"""The Hausdorff bound (moments_ref.hausdorff) against a linear program, its mpmath twin and Algorithm 1."""

import numpy as np
import pytest
from scipy.optimize import linprog

from moments_ref import InputError, hausdorff, msm, precise
from moments_ref.moments import power_moments

#: The grid of the linear program: the sharp bound over distributions on these depths (and zf).
GRID = np.linspace(0.0, 1.0, 801)


def _distributions(rng, n):
    """``n`` moment vectors of 3 to 6 random depths in [0, 1], mixed with 2% of seven even depths (inside)."""
    k = rng.integers(3, 7, n)
    z = rng.uniform(0, 1, (n, 6))
    w = rng.dirichlet(np.ones(6), n) * (np.arange(6) < k[:, None])
    w /= w.sum(axis=1, keepdims=True)
    b = power_moments(z, w)
    return 0.98 * b + 0.02 * power_moments(np.linspace(0, 1, 7))


def _lp_bound(b, zf, bound):
    """min Z(z < zf) (lower) or max Z(z ≤ zf) (upper) over distributions on GRID ∪ {zf} with moments b."""
    t = np.union1d(GRID, [zf])
    a_eq = np.vstack([t ** k for k in range(5)])
    c = (t < zf).astype(float) if bound == "lower" else -(t <= zf).astype(float)
    res = linprog(c, A_eq=a_eq, b_eq=np.concatenate([[1.0], b]), bounds=(0, None), method="highs")
    assert res.status == 0, res.message
    return res.fun if bound == "lower" else -res.fun


def test_the_hausdorff_bound_is_the_sharp_bound_of_a_linear_program():
    """300 distributions: on the correct side of the grid's LP, within its resolution, and never looser
    than the Hamburger bound; four-point rows, receivers at 0 and at 1 included."""
    rng = np.random.default_rng(37)
    b = _distributions(rng, 300)
    zf = rng.uniform(0, 1, 300)
    zf[:25], zf[25:50] = 0.0, 1.0
    bounds = np.where(np.arange(300) % 2 == 0, "lower", "upper")
    depths, _ = msm.canonical_representation(b, zf)
    four = ((depths[:, 1:] < 0) | (depths[:, 1:] > 1)).any(axis=1)
    assert four.sum() >= 20  # the second representation is exercised
    for i in range(300):
        got = float(hausdorff.shadow_intensity(b[i], zf[i], bounds[i]))
        sharp = _lp_bound(b[i], zf[i], bounds[i])
        hamburger = float(msm.shadow_intensity(b[i], zf[i], bounds[i]))
        # valid: the grid restricts the distributions, so its lower bound is >= the true one
        if bounds[i] == "lower":
            assert got <= sharp + 1e-9 and got >= hamburger - 1e-12, (i, got, sharp, hamburger)
        else:
            assert got >= sharp - 1e-9 and got <= hamburger + 1e-12, (i, got, sharp, hamburger)
        assert abs(got - sharp) < 2e-4, (i, zf[i], bounds[i], got, sharp)  # sharp up to the grid


def test_the_four_point_representation_reproduces_the_moments():
    """The closed form's support (0, zf, x, 1) and weights, recomputed here in rationals of mpmath."""
    import mpmath

    rng = np.random.default_rng(5)
    b = _distributions(rng, 400)
    zf = rng.uniform(0.05, 0.95, 400)
    depths, _ = msm.canonical_representation(b, zf)
    four = ((depths[:, 1:] < 0) | (depths[:, 1:] > 1)).any(axis=1)
    b, zf = b[four][:20], zf[four][:20]
    x = hausdorff.free_point(b, zf)
    lower, upper = hausdorff.shadow_bounds(b, zf)
    with mpmath.workdps(40):
        for i in range(len(zf)):
            zs = [mpmath.mpf(0), mpmath.mpf(zf[i]), mpmath.mpf(x[i]), mpmath.mpf(1)]
            m = [mpmath.mpf(1)] + [mpmath.mpf(v) for v in b[i]]
            w = mpmath.lu_solve(mpmath.matrix([[z ** k for z in zs] for k in range(4)]), mpmath.matrix(m[:4]))
            assert all(wk >= -1e-12 for wk in w) and 0 <= x[i] <= 1
            assert abs(mpmath.fsum(wk * z ** 4 for wk, z in zip(w, zs)) - m[4]) < 1e-10  # b4 too
            exact_lower = w[0] + (w[2] if x[i] < zf[i] else 0)
            assert abs(float(exact_lower) - lower[i]) < 1e-10
            assert abs(float(exact_lower + w[1]) - upper[i]) < 1e-10


@pytest.mark.parametrize("dtype, tol", [(np.float64, 1e-12), (np.float32, 2e-3)])
def test_the_kernel_matches_its_mpmath_twin(dtype, tol):
    rng = np.random.default_rng(11)
    b = _distributions(rng, 200).astype(dtype)
    zf = rng.uniform(0, 1, 200).astype(dtype)
    zf[:10], zf[10:20] = 0, 1
    for bound in ("lower", "upper"):
        got = hausdorff.shadow_intensity(b, zf, bound)
        assert got.dtype == dtype
        np.testing.assert_allclose(got, precise.hausdorff_intensity(b, zf, bound), atol=tol, rtol=0)


def test_a_receiver_at_depth_0_or_1_has_a_defined_bound():
    """Nothing lies below 0 (lower = 0); everything lies at or below 1 (upper = 1); no NaN anywhere."""
    b = _distributions(np.random.default_rng(2), 50)
    for dtype in (np.float32, np.float64):
        lo, up = hausdorff.shadow_bounds(b.astype(dtype), np.zeros(50, dtype))
        assert (lo == 0).all() and np.isfinite(up).all() and (up >= 0).all()
        lo, up = hausdorff.shadow_bounds(b.astype(dtype), np.ones(50, dtype))
        assert (up == 1).all() and np.isfinite(lo).all()


def test_bad_input_names_the_argument():
    with pytest.raises(InputError, match="bound"):
        hausdorff.shadow_intensity([0.5, 0.3, 0.2, 0.1], 0.5, bound="middle")
    with pytest.raises(InputError, match="b"):
        hausdorff.shadow_intensity([0.5, np.nan, 0.2, 0.1], 0.5)
    with pytest.raises(InputError, match="zf"):
        hausdorff.shadow_intensity([0.5, 0.3, 0.2, 0.1], [np.inf])


def test_a_case_registers_its_flags_in_the_manifest(tmp_path):
    """The Hausdorff cases bring their flag in their registry entry (Case(notes=...)): the manifest's
    notes table and the diagnosis's causes hold it; a second, different text for a flag is refused."""
    import json

    from moments_ref.golden import notes, writer

    writer.write(tmp_path, cases=["hausdorff-lower-float32"])
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert "receiver_at_depth_0" in manifest["notes"]
    assert "divide by zf" in notes.cause("receiver_at_depth_0", "stiff")
    with pytest.raises(ValueError, match="receiver_at_depth_0"):
        notes.register("receiver_at_depth_0", "another text", "another effect")


def test_the_bound_key_picks_the_hausdorff_cases_and_is_refused_when_misspelled():
    from moments_ref.golden.cases import CASES, bound_case
    from moments_ref.golden.conventions import unused_keys
    from moments_ref.golden.profile import Profile, parse_profile

    p = parse_profile({"bound": "hausdorff", "depth": "[0,1]"})
    assert p.bound == "hausdorff" and "bound hausdorff" in p.describe()
    assert Profile().key == parse_profile({}).key and Profile().canonical["bound"] is None
    assert bound_case("shadow_intensity-upper-float64", p.bound) == "hausdorff-upper-float64"
    assert bound_case("shadow_intensity6-lower-float32", p.bound) == "shadow_intensity6-lower-float32"
    assert bound_case("shadow_intensity-lower", None) == "shadow_intensity-lower"
    assert unused_keys(CASES["shade-float32"], p) == ["bound"]  # named in the verdict, not dropped
    assert unused_keys(CASES["hausdorff-lower-float32"], p) == []
    with pytest.raises(InputError, match="bound"):
        parse_profile({"bound": "hausdorf"})
    with pytest.raises(InputError, match="did you mean 'bound'"):
        parse_profile({"bond": "hausdorff"})


def test_oracle_check_judges_a_declared_hausdorff_port_by_the_hausdorff_cases():
    from moments_ref import oracle
    from moments_ref.golden.profile import parse_profile

    port = lambda b, zf: hausdorff.shadow_intensity(b, zf)  # noqa: E731
    declared = oracle.check(port, "shadow_intensity-lower", n_hypothesis=0,
                            profile=parse_profile({"bound": "hausdorff", "depth": "[0,1]"}))
    assert declared.passed
    undeclared = oracle.check(port, "shadow_intensity-lower", n_hypothesis=0,
                              profile=parse_profile({"depth": "[0,1]"}))
    assert not undeclared.passed  # Algorithm 1's bound is another function
