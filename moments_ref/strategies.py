"""Hypothesis strategies for depth distributions and moment vectors.

Public so that other projects (ports, competing references) can test with the
same inputs. Each strategy draws *distributions* first and derives moments from
them, so the ground truth ``Z(z < zf)`` is always available.

Example
-------
>>> from hypothesis import given
>>> from moments_ref.strategies import depth_distributions
>>> @given(depth_distributions())
... def test_weights_sum_to_one(dist):
...     z, w = dist
...     assert abs(w.sum() - 1) < 1e-12
"""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from .moments import power_moments

__all__ = [
    "depths",
    "depth_distributions",
    "two_point_distributions",
    "moment_vectors",
    "exact_shadow",
]


def depths(min_value=-1.0, max_value=1.0):
    """Single depths in [min_value, max_value], boundaries included, no NaN."""
    return st.one_of(
        st.sampled_from([min_value, max_value, 0.0]),
        st.floats(min_value, max_value, allow_nan=False, allow_infinity=False),
    )


@st.composite
def _clustered(draw, n):
    centre = draw(st.floats(-1, 1))
    spread = draw(st.sampled_from([0.0, 1e-6, 1e-4, 1e-2]))
    offsets = draw(st.lists(st.floats(-1, 1), min_size=n, max_size=n))
    return [float(np.clip(centre + spread * o, -1, 1)) for o in offsets]


@st.composite
def depth_distributions(draw, min_points=1, max_points=8, kind=None):
    """A depth distribution on [-1, 1]: ``(z, w)`` float64 arrays, ``w`` summing to 1.

    Parameters
    ----------
    min_points, max_points : int
        Number of support points (before merging duplicates), 1..8 by default.
    kind : {"random", "clustered", "boundary"} or None
        Restrict to one family; None draws from all three. "clustered" puts all
        points within 1e-6..1e-2 of a centre (near-zero variance), "boundary"
        puts points at or next to ±1.
    """
    n = draw(st.integers(min_points, max_points))
    kind = kind or draw(st.sampled_from(["random", "clustered", "boundary"]))
    if kind == "random":
        z = draw(st.lists(depths(), min_size=n, max_size=n))
    elif kind == "clustered":
        z = draw(_clustered(n))
    elif kind == "boundary":
        z = draw(
            st.lists(
                st.sampled_from([-1.0, 1.0, -1.0 + 1e-6, 1.0 - 1e-6, 1.0 - 1e-3]) | depths(),
                min_size=n,
                max_size=n,
            )
        )
    else:
        raise ValueError(f"kind: expected random, clustered or boundary, got {kind!r}")
    raw = draw(
        st.lists(st.floats(1e-3, 1.0), min_size=n, max_size=n)
        | st.just([1.0] * n)
    )
    w = np.asarray(raw, dtype=np.float64)
    return np.asarray(z, dtype=np.float64), w / w.sum()


@st.composite
def two_point_distributions(draw, min_gap=1e-3):
    """``(z, w)`` with two distinct depths at least ``min_gap`` apart and weights in [0.01, 0.99]."""
    z1 = draw(st.floats(-1, 1 - min_gap))
    z2 = draw(st.floats(z1 + min_gap, 1))
    v2 = draw(st.floats(0.01, 0.99))
    return np.array([z1, z2]), np.array([1 - v2, v2])


@st.composite
def moment_vectors(draw, dtype=np.float64, n=4, distributions=None):
    """Moments b1..bn of a drawn distribution, as a (n,) array of ``dtype``."""
    z, w = draw(distributions if distributions is not None else depth_distributions())
    return power_moments(z, w, n=n).astype(dtype)


def exact_shadow(z, w, zf, strict=True):
    """The filtered hard shadow ``Z(z < zf)`` (or ``Z(z ≤ zf)``) of a distribution, by definition."""
    z = np.asarray(z)
    w = np.asarray(w)
    zf = np.asarray(zf)[..., None]
    hit = z < zf if strict else z <= zf
    return (w * hit).sum(axis=-1)
