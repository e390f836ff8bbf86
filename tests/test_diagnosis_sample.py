"""golden.diagnosis: the sampled refusal of a candidate declaration never refuses what the judge on every row accepts.

A candidate declaration (a clamp, a receiver offset, the caller's clamp, ...) is first judged on a few failing
rows alone (``SAMPLE_ROWS``), then on every row. The judge on every row lets failing rows keep their own cause
(rows flagged ``printed_hazard``, and ill-conditioned rows a candidate leaves unjudged: under
``bound = "hausdorff"`` an Algorithm 1 case's exact values are not the port's, so its ``wide_spread`` rows keep their
stored band alone); the sample must not refuse a candidate because of such a row. The port here is the golden's own
float32 reference with a cause built in by hand (the caller's clamp left out on some fully shadowed rows, a receiver
offset, and wrong values on chosen rows), so which declaration is right is known before the diagnosis runs.
"""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import golden
from moments_ref.golden import diagnosis
from moments_ref.golden.profile import DEFAULT, parse_profile

from _oracles import golden_folder

CASE = "shadow_intensity-lower-float32"
HAUSDORFF = {"bound": "hausdorff"}


@pytest.fixture(scope="module")
def base():
    return _base()


def _base():
    gdir = golden_folder((CASE,))
    with np.load(gdir / f"{CASE}.npz") as g:
        arrays = {k: g[k] for k in g.files}
    c = golden.CASES[CASE]
    ref = golden.evaluate_reference(c, {"b": arrays["b"], "zf": arrays["zf"]}, c.dtype)[0]
    flags = arrays["flags"].astype(str)
    return gdir, arrays, np.asarray(ref, np.float32), np.char.find(flags, "wide_spread") >= 0, \
        np.char.find(flags, "printed_hazard") >= 0


def _verify(tmp_path, gdir, got, profile):
    np.savez(tmp_path / "r.npz", **{f"{CASE}.intensity": np.asarray(got, np.float32)})
    return golden.verify(gdir, tmp_path / "r.npz", profile=profile).cases[0]


def _wrong(v):
    """A value far outside any band of a bounded output at ``v``: the other end of [0, 1]."""
    return np.where(v > 0.5, np.float32(0), np.float32(1)).astype(np.float32)


def test_a_right_declaration_is_not_refused_by_an_unjudged_ill_row_in_the_sample(tmp_path, base):
    # Under bound = "hausdorff" the ill-conditioned rows of the Algorithm 1 case keep their stored band alone. The
    # port: the reference, the caller's clamp left out (+0.01) on the fully shadowed rows after the first ill row,
    # and that ill row wrong. Every failing row but the ill one passes under output_clamp = true; the ill row keeps
    # its own cause. It is among the first SAMPLE_ROWS failing rows, where the sample used to refuse the advice.
    gdir, arrays, ref, ill, hazard = base
    i0 = int(np.flatnonzero(ill & ~hazard)[0])
    full = np.flatnonzero((ref >= 1 - 1e-6) & ~ill & ~hazard)
    got = ref.copy()
    got[i0] = _wrong(ref[i0])
    got[full[full > i0]] += np.float32(0.01)
    profile = parse_profile(HAUSDORFF)
    case = _verify(tmp_path, gdir, got, profile)
    failing = np.flatnonzero(~case.verdict.row_pass).tolist()
    assert case.status == "fail" and failing[0] == i0 and len(failing) <= diagnosis.SAMPLE_ROWS
    advice = [g for g in case.groups if g.level == "convention"]
    assert [(g.flags, g.rows) for g in advice] == [("output_clamp = true", failing[1:])]
    # the advice is right: declared, exactly the ill row still fails
    declared = _verify(tmp_path, gdir, got, parse_profile(dict(HAUSDORFF, output_clamp=True)))
    assert np.flatnonzero(~declared.verdict.row_pass).tolist() == [i0]


def _port(rng, ref, arrays, ill, hazard):
    """A random port: the reference with one convention (a receiver offset, the caller's clamp left out on
    fully shadowed rows) and 0 to 3 rows made wrong, mostly ill-conditioned or hazard ones."""
    kind = rng.choice(["offset", "clamp", "clamp"])
    c = golden.CASES[CASE]
    if kind == "offset":
        offset = np.float32(rng.choice(diagnosis.OFFSET_CANDIDATES))
        got = np.asarray(golden.evaluate_reference(c, {"b": arrays["b"], "zf": arrays["zf"] - offset}, c.dtype)[0],
                         np.float32)
    else:
        got = ref.copy()
        if kind == "clamp":
            full = np.flatnonzero(ref >= 1 - 1e-6)
            got[rng.choice(full, rng.integers(1, len(full) + 1), replace=False)] += np.float32(0.01)
    pools = [np.flatnonzero(ill), np.flatnonzero(hazard), np.arange(len(ref))]
    for _ in range(rng.integers(0, 4)):
        pool = pools[rng.choice(3, p=[0.65, 0.3, 0.05])]
        i = rng.choice(pool[:12])  # early rows: where the sample is drawn
        got[i] = _wrong(got[i])
    return got


@pytest.mark.parametrize("seed", range(16))
def test_the_sampled_refusal_agrees_with_the_judge_on_every_row(tmp_path, base, monkeypatch, seed):
    # the advice with the sample equals the advice without it (every sampled judgement made to refuse nothing)
    gdir, arrays, ref, ill, hazard = base
    rng = np.random.default_rng(seed)
    profile = parse_profile(HAUSDORFF) if seed % 3 else DEFAULT
    got = _port(rng, ref, arrays, ill, hazard)
    with_sample = [(g.level, g.flags, g.rows) for g in _verify(tmp_path, gdir, got, profile).groups]
    judge = diagnosis._judge
    monkeypatch.setattr(diagnosis, "_judge", lambda name, p, rows, *a: (
        judge(name, p, rows, *a) if rows is None else type("Nothing", (), {"failures": 0})()))
    without = [(g.level, g.flags, g.rows) for g in _verify(tmp_path, gdir, got, profile).groups]
    assert with_sample == without


def test_kept_mutant_ill_rows_in_the_sample_refuse_the_right_declaration(tmp_path, base):
    from _mutants import kept_mutant

    with kept_mutant("moments_ref/golden/diagnosis.py", "_declaration_groups::~ill -> ill#0"):
        with pytest.raises(AssertionError):
            test_a_right_declaration_is_not_refused_by_an_unjudged_ill_row_in_the_sample(tmp_path, base)
