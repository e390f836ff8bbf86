"""sweep.shrink.candidates: the simpler neighbours of a failing texel, by the rules of its docstring."""

from __future__ import annotations

import numpy as np

from moments_ref.sweep.shrink import candidates


def _plain(row):
    z, w, zf, fmt = row
    keep = w > 0
    return (tuple(np.round(z[keep], 12)), tuple(np.round(w[keep], 12)), round(zf, 12), fmt)


TEXEL = {"depths": [0.123, -0.5], "weights": [0.25, 0.75], "zf": 0.3, "format": 2}


def test_the_plain_texel_comes_first_then_one_depth_fewer_and_equal_weights():
    got = [_plain(r) for r in candidates(TEXEL)]
    assert got[0] == ((0.123, -0.5), (0.25, 0.75), 0.3, 0)  # the plain float32 texel
    assert ((-0.5,), (1.0,), 0.3, 2) in got[1:3] and ((0.123,), (1.0,), 0.3, 2) in got[1:3]
    assert got[3] == ((0.123, -0.5), (0.5, 0.5), 0.3, 2)
    # depths rounded to fewer decimals (0, 1 and 2 digits change them), weights to one digit, zf to none
    assert ((0.1, -0.5), (0.25, 0.75), 0.3, 2) in got and ((0.12, -0.5), (0.25, 0.75), 0.3, 2) in got
    assert ((0.123, -0.5), (0.2, 0.8), 0.3, 2) in got and ((0.123, -0.5), (0.25, 0.75), 0.0, 2) in got
    # zf moved to a round offset above the nearest depth (0.123), closer than it is: 1e-8 ... 0.1
    near = sorted(r[2] for r in got if r[:2] == ((0.123, -0.5), (0.25, 0.75)) and r[3] == 2 and r[2] not in (0.0,))
    assert near == sorted(round(0.123 + 10.0**e, 12) for e in range(-8, 0))


def test_every_candidate_is_a_valid_row_offered_once():
    rows = candidates({"depths": [0.9999, -0.7, 0.3], "weights": [0.1, 0.2, 0.7], "zf": 0.99999, "format": 1})
    keys = [_plain(r) for r in rows]
    assert len(keys) == len(set(keys)) and ((0.9999, -0.7, 0.3), (0.1, 0.2, 0.7), 0.99999, 1) not in keys
    for z, w, zf, fmt in rows:
        assert z.shape == w.shape == (6,) and abs(w.sum() - 1) < 1e-12 and (w >= 0).all()
        assert -1 <= zf <= 1 and fmt in (0, 1) and (np.abs(z) <= 1).all()
    # rows already seen are not offered again
    seen = set()
    first = candidates(TEXEL, seen)
    assert first and candidates(TEXEL, seen) == []


def test_a_single_round_depth_at_the_receiver_of_the_plain_format_has_no_simpler_texel():
    rows = candidates({"depths": [0.0], "weights": [1.0], "zf": 0.0, "format": 0})
    assert rows == []
