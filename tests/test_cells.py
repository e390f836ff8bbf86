"""The two published √v2 grids of the 32-bit texel (golden.cells) and the 32-bit kernel case derived
for a declared grid, checked by independent means (exhaustive codes, float64 Φ, the undeclared case)."""

from __future__ import annotations

import numpy as np
import pytest

from moments_ref import InputError
from moments_ref.golden import CASES, cells
from moments_ref.golden.conventions import profiled_arrays, profiled_case
from moments_ref.golden.profile import Profile, parse_profile


def test_codes_and_decoders_exhaustively():
    c = np.arange(128)
    # Each grid's decoded value encodes back to its code; the grid's end points are those of docs/formats.md.
    for cell, v2 in (("floor128", ((c + 0.5) / 128) ** 2), ("round127", (c / 127.0) ** 2)):
        assert (cells.v2_codes(v2, cell) == c).all(), cell
        t = cells.recode(np.full(128, 0xFFFFFFFF, np.uint32), v2, cell)
        assert (t & ~np.uint32(127 << 19) == np.uint32(0xFFFFFFFF) & ~np.uint32(127 << 19)).all()
        assert np.array_equal(cells.decode_v2(t, cell), v2)
    assert cells.v2_codes([0.0, 1.0, 1.5], "round127").tolist() == [0, 127, 127]
    assert cells.v2_codes([0.0, 1.0], "floor128").tolist() == [0, 127]
    # round(127 s) against min(floor(128 s), 127) on a fine grid of s: they differ by at most one cell.
    s = np.linspace(0, 1, 100001)
    d = cells.v2_codes(s * s, "round127").astype(int) - cells.v2_codes(s * s, "floor128").astype(int)
    assert set(np.unique(d)) == {-1, 0, 1}


def test_the_declared_case_is_the_global_path_on_that_grid():
    from moments_ref.gpu.filtering import blur, resolve_moments
    from moments_ref.moments import BIAS_FLOAT32, bias_moments
    from moments_ref.nonlinear import phi

    name = "kernel-filter-nlq32"
    _, base = profiled_arrays(name)
    _, decl = profiled_arrays(name, Profile(format=(("v2_cell", "round127"),)), disk=False)
    keep = ~np.uint32(127 << 19)
    # Only bits 19-25 change, and only on the declared grid.
    assert np.array_equal(base["texels"] & keep, decl["texels"] & keep)
    assert not np.array_equal(base["texels"], decl["texels"])
    # Independently: the code nearest √v2 on the grid c/127 (an exhaustive search over the 128 codes), v2 from
    # Φ of the float64 global path's moments rounded to float32 (the reference kernel's texels).
    h, w = CASES[name].kwargs["height"], CASES[name].kwargs["width"]
    m = blur(resolve_moments(np.asarray(decl["depth"], np.float64).reshape(h, w, -1))).reshape(-1, 4)
    v2 = np.clip(phi(bias_moments(m.astype(np.float32), BIAS_FLOAT32))[:, 2].astype(np.float64), 0, 1)
    nearest = np.argmin(np.abs(np.sqrt(v2)[:, None] - np.arange(128)[None] / 127.0), axis=1)
    assert np.array_equal((decl["texels"] >> 19) & 127, nearest)
    # Its expected intensities shade the declared texels read on the declared grid, not the format's.
    assert not np.allclose(base["intensity"], decl["intensity"])


def test_the_key_in_profiles():
    p = parse_profile({"format": {"v2_cell": "round127"}}, "engine.toml")
    assert dict(p.format) == {"v2_cell": "round127"}
    with pytest.raises(InputError, match="format.v2_cell"):
        parse_profile({"format": {"v2_cell": "round128"}}, "engine.toml")
    # A function case does not follow a declared grid: refused, not ignored.
    with pytest.raises(InputError, match="v2_cell"):
        profiled_case(CASES["unpack32-float32"], p)
    assert profiled_case(CASES["kernel-filter-nlq32"], p).kwargs["profile"]["format"] == {"v2_cell": "round127"}
