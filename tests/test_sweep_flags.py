"""The last unconfirmed flags of the sweep: one neighbourhood for the band, the ill rows and the confirmation.

An unconfirmed flag is a defect of the tolerance model: the band missed a value that the confirmation's
neighbourhood (the exact values over the input's joint 1–3-ulp scalings and its component-wise
neighbours) explains. Each row below was one, found by ``moments-ref sweep`` (seed 0) and written out
here; its exact values come from mpmath (:mod:`moments_ref.precise`), not from the band under test.
"""

from __future__ import annotations

import numpy as np

from moments_ref import precise
from moments_ref.golden import bands
from moments_ref.golden.cases import CASES
from moments_ref.sweep import engine, judge

EPS32 = float(np.finfo(np.float32).eps)
CAP = bands.CAP

#: (a) engine-lower-float32, 10^6 rows, seed 0 (cluster/end): two depths -1 and 0.634, the receiver
#: 4.4e-5 behind the near plane. llvmpipe and lavapipe return GOT_A; the band, capped at 0.02 about 0.0205,
#: missed it, and the derivation (b moved by one ulp per component, zf alone) did not flag the row ill.
A_SUPPORT = np.array([[-1.0, 0.6340605324376034]])
A_MASS = np.array([[0.5585784795467559, 0.4414215204532442]])
A_ZF = np.array([-0.999956295])
A_B = [-0.2786904275417328, 0.7360442876815796, -0.44605422019958496, 0.6299254894256592]
GOT_A = 0.04861091449856758


def _engine_row():
    case = CASES["engine-lower-float32"]
    return case, engine.engine_inputs(case, A_SUPPORT, A_MASS, A_ZF)


def _joint(x, k):
    """``x`` (float32) scaled by 1 + k float32 ulps, rounded to float32, as float64."""
    return (np.asarray(x, np.float64) * (1 + k * EPS32)).astype(np.float32).astype(np.float64)


def test_engine_row_a_is_ill_over_the_confirmations_neighbourhood():
    case, inputs = _engine_row()
    assert inputs["b"][0].tolist() == A_B and float(inputs["zf"][0]) == -0.9999563097953796
    # mpmath: the exact lower bound at the port's input scaled jointly by k ulps (the confirmation's points)
    exact = {k: float(precise.shadow_bounds(_joint(inputs["b"], k), _joint(inputs["zf"], k))[0][0])
             for k in (-3, -2, -1, 1, 2, 3)}
    assert exact[2] > 0.55 and exact[-3] < 0.01  # the exact values spread over half the range
    assert min(exact.values()) < GOT_A < max(exact.values())  # the drivers' value is one of them
    bands_, ill = judge.legitimate_interval(case, inputs)
    assert ill.all()  # ill-conditioned: reported apart, never counted as a pass or as wrong
    lo, hi = bands_["intensity"]
    assert lo[0] <= min(exact.values()) and max(exact.values()) <= hi[0]
    got = {"intensity": np.array([GOT_A], np.float32)}
    assert not judge.flagged_rows(case, inputs, bands_, ill, got).any()
    assert not judge.confirm(case, inputs, got).any()
    # the confirmation keeps its power on the row: a value beyond every exact value is wrong
    assert judge.confirm(case, inputs, {"intensity": np.array([0.9], np.float32)}).all()


#: (b) shadow_intensity-lower-float32, 10^8 rows, seed 0, llvmpipe (chunk 276, row 18232, cluster/near): three
#: depths -0.88408, -0.88513 and 0.42923 (weights 0.528, 0.468, 0.0043), the receiver on the first; the driver
#: returns GOT_B, the shipped plain-Cholesky evaluation without fma, which the band (capped at 0.02 about 0.41987)
#: missed.
B_B = np.array([[-0.878868579864502, 0.7798765897750854, -0.6888092160224915, 0.6097564697265625]], np.float32)
B_ZF = np.array([-0.8840803503990173], np.float32)
GOT_B = 0.4405953586101532


def test_moment_row_b_is_ill_over_the_confirmations_neighbourhood():
    from moments_ref.golden.paper import cholesky_bound

    case = CASES["shadow_intensity-lower-float32"]
    inputs = {"b": B_B, "zf": B_ZF}
    assert cholesky_bound(B_B, B_ZF, "lower", np.float32)[0] == np.float32(GOT_B)
    # mpmath: the exact lower bound on the row and on it scaled jointly by k float32 ulps (the confirmation's points)
    row = float(precise.shadow_bounds(B_B.astype(np.float64), B_ZF.astype(np.float64))[0][0])
    exact = {k: float(precise.shadow_bounds(_joint(B_B, k), _joint(B_ZF, k))[0][0]) for k in (-3, -2, -1, 1, 2, 3)}
    assert exact[2] > row + CAP  # 0.4464: one neighbour beyond the cap, so the row is ill-conditioned
    assert min(exact.values()) < GOT_B < max(exact.values())
    contract = judge.contract_rows(case, inputs)
    bands_, ill = judge.legitimate_interval(case, inputs, "float32", contract)
    got = {"intensity": np.array([GOT_B], np.float32)}
    assert judge.wrong_rows(case, bands_, ill, got).all() and not ill.any()  # the default band: the old flag
    full, full_ill = bands.legitimate_interval(case, inputs, "float32", contract=contract, full=True)
    assert full_ill.all() and full["intensity"][1][0] >= max(exact.values())
    assert not judge.flagged_rows(case, inputs, bands_, ill, got, contract, "float32", contract).any()
    assert not judge.confirm(case, inputs, got).any()
    assert judge.confirm(case, inputs, {"intensity": np.array([0.9], np.float32)}).all()


def test_a_rows_confirmation_points_do_not_depend_on_the_other_rows():
    case = CASES["shadow_intensity-lower-float32"]
    rng = np.random.default_rng(3)
    b = np.tile(np.array([[0.1, 0.5, 0.05, 0.4]], np.float32), (5, 1)) * rng.uniform(0.9, 1.0, (5, 1)).astype(
        np.float32)
    zf = rng.uniform(-1, 1, 5).astype(np.float32)
    alone = bands.confirm_points(case, {"b": b[3:4], "zf": zf[3:4]})
    batch = bands.confirm_points(case, {"b": b, "zf": zf})
    assert len(alone) == len(batch) == 1 + 2 * bands.PERTURB_ULPS + bands.NEIGHBOURS
    for p, q in zip(alone, batch):
        assert np.array_equal(p["b"], q["b"][3:4]) and np.array_equal(p["zf"], q["zf"][3:4])
    assert len({np.asarray(p["b"][3]).tobytes() for p in batch}) > 10  # component-wise points, not one scaling


#: (c) e2e-msm64-float32 through a GLSL wrapper of the shipped msm.glsl (docs/sweep.md), 262144 rows, seed 0,
#: llvmpipe: the shrunk row the sweep "confirmed" wrong (three/uniform), and an unconfirmed flag (cluster/near).
#: (b, zf, got, the channel whose code the GPU stored on the other side of a rounding tie, whether got lies outside
#: the exact values over the tie's texels: the float32 evaluation on the other texel explains it, which the band and
#: the confirmation lacked)
C_ROWS = [([0.4929254651069641, 0.532565176486969, 0.5118938684463501, 0.49934056401252747], -0.10000000149011612,
           0.02004101686179638, 1, True),
          ([0.3714542090892792, 0.8761855959892273, 0.2621643543243408, 0.7731295824050903], 0.9568029046058655,
           0.9976081252098083, 0, False)]


def _other_code_chain(b, zf, channel):
    """float32 Algorithm 1 (the shipped ports' plain Cholesky) after decoding the texel of ``b`` with ``channel``'s
    code on the other side of its rounding tie, and that channel's exact distance from the tie (in codes)."""
    from moments_ref.affine import decode_unorm16, encode_unorm16, to_optimized
    from moments_ref.golden.paper import cholesky_bound
    from moments_ref.moments import BIAS_UNORM16, bias_moments

    codes = encode_unorm16(b).astype(np.int64)
    scaled = np.clip(to_optimized(b.astype(np.float64)), 0, 1) * 65535
    low = np.floor(scaled[0, channel])
    codes[0, channel] = low + 1 if codes[0, channel] == low else low
    bq = bias_moments(decode_unorm16(codes.astype(np.uint16), dtype=np.float32), BIAS_UNORM16)
    return float(cholesky_bound(bq, zf, "lower", np.float32)[0]), abs(scaled[0, channel] - low - 0.5)


def test_e2e_msm64_rows_c_the_other_code_of_a_tie_is_legitimate():
    from moments_ref.golden.truth import CHAIN_TIE, msm64_chain
    from moments_ref.moments import BIAS_UNORM16

    case = CASES["e2e-msm64-float32"]
    for b, zf, got, channel, beyond_exact in C_ROWS:
        inputs = {"b": np.array([b], np.float32), "zf": np.array([zf], np.float32)}
        value, off = _other_code_chain(inputs["b"], inputs["zf"], channel)
        assert value == np.float32(got) and off < CHAIN_TIE * 65535  # the GPU stored the tie's other code
        # mpmath: the exact chain over the texels the tie admits; the driver's float32 value lies outside it
        lo, hi = msm64_chain(inputs["b"].astype(np.float64), inputs["zf"].astype(np.float64), BIAS_UNORM16,
                             tie=CHAIN_TIE)
        assert (got > hi[0] + 8 * EPS32 or got < lo[0] - 8 * EPS32) == beyond_exact
        bands_, ill = judge.legitimate_interval(case, inputs)
        g = {"intensity": np.array([got], np.float32)}
        assert judge.wrong_rows(case, bands_, ill, g).all()  # the band of the row's own texel misses it ...
        contract = judge.contract_rows(case, inputs)
        # ... the full band holds it
        assert not judge.flagged_rows(case, inputs, bands_, ill, g, contract, "float32", contract).any()
        assert not judge.confirm(case, inputs, g).any()
        far = {"intensity": np.array([got + 0.05], np.float32)}  # power kept: a value far off is flagged and wrong
        assert judge.flagged_rows(case, inputs, bands_, ill, far, contract, "float32", contract).all()
        assert judge.confirm(case, inputs, far).all()
