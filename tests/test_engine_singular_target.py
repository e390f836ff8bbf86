"""golden.engine.target_support and singular_target_rows against hand-built distributions.

Independent statements (HPG17 §3.2: a bias target is a moment vector, b' = (1 − α) b + α b*):

* a target that is the moment vector (z, z², z³, z⁴) of one point, or Σ w_i z_i^k of two points, is
  singular and its support is exactly those points and weights (the moment problem's unique
  distribution); the point of a target whose 3×3 Hankel matrix has the kernel (−a, 1, 0) is a;
  a target strictly inside the moment space (the papers' BIAS_FLOAT32 target) has no support;
* the biased moments of a row are those of the mixture (1 − α)·row + α·target, and a 3×3 Hankel
  matrix of moments of a distribution is singular exactly when it has at most two distinct points:
  so a row stays singular under a singular target iff its points and the target's number ≤ 2,
  counted here by hand, not by eigenvalues.

Kept mutants (tests/_mutants.py): the weights' formula with a sign flipped, and the target's
mixture with its sign flipped, each shown failing these statements.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpmath import mp, mpf

from moments_ref.golden.engine import singular_target_rows, target_support
from moments_ref.moments import BIAS_FLOAT32, BiasPreset
from _mutants import kept_mutant

ENGINE = "moments_ref/golden/engine.py"


def _target(points, weights):
    """Σ w z^k (k = 1..4) in mpmath, rounded once to float64: the target of a hand-built distribution."""
    mp.dps = 40
    return tuple(float(sum(mpf(w) * mpf(z) ** k for z, w in zip(points, weights))) for k in range(1, 5))


ONE_POINT = [-0.75, -0.2, 0.0, 0.3, 0.5, 0.9]
TWO_POINTS = [((-0.5, 0.5), (0.5, 0.5)), ((-0.9, 0.2), (0.25, 0.75)), ((0.1, 0.7), (0.6, 0.4)),
              ((-0.3, 0.0), (0.9, 0.1)), ((0.2, 0.95), (0.3, 0.7)), ((-1.0, 1.0), (0.125, 0.875)),
              ((-0.75, 0.5), (0.5, 0.5)), ((-0.25, 0.5), (0.75, 0.25))]  # the last two: eigh's kernel has c2 < 0


@pytest.mark.parametrize("z", ONE_POINT)
def test_a_one_point_target_is_its_point(z):
    support = target_support(_target([z], [1.0]))
    assert support is not None and len(support) == 1
    assert support[0][0] == pytest.approx(z, abs=1e-9) and support[0][1] == 1.0


@pytest.mark.parametrize("points, weights", TWO_POINTS)
def test_a_two_point_target_is_its_points_and_weights(points, weights):
    support = target_support(_target(points, weights))
    assert support is not None and len(support) == 2
    (z0, w0), (z1, w1) = support
    assert (z0, z1) == pytest.approx(points, abs=1e-6)
    assert (w0, w1) == pytest.approx(weights, abs=1e-6)


def test_a_linear_kernel_gives_its_root():
    # B = [[1, a, a²], [a, a², a³], [a², a³, a⁴ + 1]]: rank 2, kernel (−a, 1, 0): the point a, weight 1
    a = 0.3
    support = target_support((a, a * a, a ** 3, a ** 4 + 0.5))
    assert support is not None and len(support) == 1
    assert support[0][0] == pytest.approx(a, abs=1e-9) and support[0][1] == 1.0


@pytest.mark.parametrize("target", [BIAS_FLOAT32.target, (0.1, 0.3, 0.05, 0.2), _target((-0.5, 0.0, 0.5), (0.3, 0.4, 0.3))])
def test_an_interior_target_has_no_support(target):
    assert target_support(target) is None


def _rows():
    """Hand-built rows: one, two or three points (mass 0 pads), and how many distinct points each has."""
    support = np.array([[0.5, 0.5, 0.5], [-0.2, 0.5, 0.0], [-0.2, 0.3, 0.0], [0.3, 0.3, 0.0],
                        [-0.2, 0.3, 0.5], [-0.6, 0.1, 0.7], [0.5, -0.2, 0.5], [0.1, 0.0, 0.0]])
    mass = np.array([[1, 1, 1], [1, 2, 0], [3, 1, 0], [1, 1, 0], [1, 1, 1], [1, 2, 1], [1, 1, 2], [1, 0, 0]], float)
    return {"support": support, "mass": mass, "zf": np.zeros(len(support))}


def _distinct(arrays, extra):
    """Per row, the number of distinct points of positive mass together with the target's points ``extra``."""
    return np.array([len({float(z) for z, m in zip(zs, ms) if m > 0} | set(extra))
                     for zs, ms in zip(arrays["support"], arrays["mass"])])


@pytest.mark.parametrize("alpha", [1e-3, 0.25])
def test_rows_stay_singular_iff_two_points_with_a_one_point_target(alpha):
    arrays = _rows()
    bias = BiasPreset(alpha, _target([0.5], [1.0]))
    got = singular_target_rows(arrays, bias)
    assert got.tolist() == (_distinct(arrays, {0.5}) <= 2).tolist()
    assert got.any() and not got.all()


def test_rows_stay_singular_iff_two_points_with_a_two_point_target():
    arrays = _rows()
    bias = BiasPreset(0.01, _target((-0.2, 0.3), (0.5, 0.5)))
    assert singular_target_rows(arrays, bias).tolist() == (_distinct(arrays, {-0.2, 0.3}) <= 2).tolist()


def test_no_row_is_flagged_under_an_interior_target_even_a_faint_one():
    # the docstring: empty unless the target is singular (α = 1e-13 leaves one-point rows' λ_min below PD_MIN)
    arrays = _rows()
    assert not singular_target_rows(arrays, BiasPreset(1e-13, BIAS_FLOAT32.target)).any()


def test_kept_mutants_fail_these_statements():
    points, weights = TWO_POINTS[1]
    with kept_mutant(ENGINE, "target_support::1 - w2 -> 1 + w2#0"):
        support = target_support(_target(points, weights))
        assert support[0][1] != pytest.approx(weights[0], abs=1e-6)
    arrays = _rows()
    bias = BiasPreset(1e-3, _target([0.5], [1.0]))
    mutant = ("singular_target_rows::(1 - bias.alpha) * b + bias.alpha * np.asarray(bias.target, np.float64) -> "
              "(1 - bias.alpha) * b - bias.alpha * np.asarray(bias.target, np.float64)#0")
    with kept_mutant(ENGINE, mutant):
        assert singular_target_rows(arrays, bias).tolist() != (_distinct(arrays, {0.5}) <= 2).tolist()
