"""Hypothesis strategies for depth distributions and moment vectors.

Public so that other projects (ports, competing references) can test with the
same inputs. Each strategy draws *distributions* first and derives moments from
them, so the ground truth ``Z(z < zf)`` is always available.

Example
-------
>>> from hypothesis import given
>>> from moments_ref.tools.strategies import depth_distributions
>>> @given(depth_distributions())
... def test_weights_sum_to_one(dist):
...     z, w = dist
...     assert abs(w.sum() - 1) < 1e-12

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
"""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from ..moments import power_moments

__all__ = [
    "depths",
    "depth_distributions",
    "two_point_distributions",
    "moment_vectors",
    "exact_shadow",
    "representations",
    "input_strategy",
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


@st.composite
def representations(draw):
    """A non-linear representation ``(y1, y2, v2, ξ4)`` (HPG17 §3.1): y1 ≤ y2 in [-1, 1],
    v2 in [0, 1], ξ4 in [0, 0.25], with the clamp values of Algorithm 3 and Ψ4 drawn often."""
    y = sorted(draw(st.lists(depths(), min_size=2, max_size=2)))
    if draw(st.booleans()):
        y[1] = y[0] + draw(st.sampled_from([0.0, 5e-7, 1e-6, 1e-4]))
        y[1] = min(y[1], 1.0)
    v2 = draw(st.sampled_from([0.0, 1.0, 1e-6, 0.5]) | st.floats(0, 1))
    xi4 = draw(st.sampled_from([0.0, 1.2e-7, 0.25]) | st.floats(0, 0.25))
    return np.array([y[0], y[1], v2, xi4])


def _block(seed):
    from ..golden.endtoend import BLOCK, GUARD

    rng = np.random.default_rng(seed)
    h, w = BLOCK
    depth = np.clip(rng.uniform(-1, 1) + rng.uniform(-1, 1, (h, w, 4)) * 10 ** rng.uniform(-5, 0), -1, 1)
    zf = rng.uniform(-1, 1, (h - 2 * GUARD, w - 2 * GUARD))
    return {"depth": depth, "zf": zf}


def input_strategy(case):
    """A strategy of one input row (dict of arrays) for the golden case named ``case``.

    Every case has one, chosen by the function the case tests (the input names are
    those of the case, in its order).
    """
    from ..golden.cases import CASES
    from ..moments import BIAS_FLOAT32, bias_moments

    c = CASES[case]
    fn = c.function.split(".")[-1]
    if fn.startswith("block"):
        return st.integers(0, 2**32 - 1).map(_block)
    six = c.name.startswith(("shadow_intensity6", "to_optimized6", "encode_r10g10b10a2"))
    b = moment_vectors(n=6 if six else 4)
    zf = depths(-1.5, 1.5).map(np.float64)
    u16 = st.lists(st.integers(0, 65535), min_size=4, max_size=4).map(lambda x: np.array(x, np.uint16))
    table = {
        "texels": st.lists(moment_vectors(), min_size=4, max_size=4).map(np.concatenate),
        "fraction": st.lists(_fractions(), min_size=2, max_size=2).map(np.array),
        "b": b.map(lambda v: bias_moments(v, BIAS_FLOAT32)) if fn == "phi" else b,
        "zf": zf,
        "r": representations(),
        "xi4": st.sampled_from([0.0, 1.2e-7, 0.25]) | st.floats(0, 0.25),
        "u": u16 if c.integer_inputs.get("u") else st.floats(0, 1),
        "q": u16 if c.integer_inputs.get("q") else moment_vectors().map(_optimized),
        "p": (st.lists(st.integers(0, (1 << 30) - 1), min_size=2, max_size=2).map(lambda x: np.array(x, np.uint32))
              if fn.startswith("decode_r10") else representations().map(_pack32)),
    }
    return st.fixed_dictionaries({k: table[k] for k in c.inputs})


def _fractions():
    """A bilinear weight: a multiple of 2^-16 in [0, 1) (an exact texture coordinate, golden.bilinear)."""
    return (st.sampled_from([0, 1, 2**15, 2**16 - 1, 77 * 2**8, 77 * 2**8 + 2**7]) | st.integers(0, 2**16 - 1)).map(
        lambda k: k / 2.0**16)


def _optimized(b):
    from ..affine import to_optimized

    return to_optimized(b)


def _pack32(r):
    from ..packing import pack32

    return pack32(r)
