"""Oracles the tests share: independent checks of the moment kernels and the golden folders they read.

* :func:`check_bounds`: the bounds of a moment kernel bracket the exact Z of the drawn
  distribution (``tools.strategies.exact_shadow``), for four and six moments alike;
* :func:`zf_candidates`: the drawn fragment depth plus every support point and its float
  neighbours (the hard spots of a bound);
* :func:`lp_lower` on :func:`lp_grid`: the lower bound as the minimum of a linear program over
  distributions on a grid (scipy HiGHS): the sharpness of Algorithm 1 and of msm6;
* :func:`golden_folder`: golden vectors written once per test run, shared by its xdist workers
  (conftest's fixtures).
"""

from __future__ import annotations

import functools
import tempfile
from pathlib import Path

import numpy as np
from scipy.optimize import linprog

from moments_ref.moments import bias_moments, power_moments
from moments_ref.tools.strategies import exact_shadow


def zf_candidates(z, zf):
    """The drawn ``zf`` plus every support point of ``z`` and its float neighbours, clipped to [-1, 1]."""
    zs = [zf] + list(z) + list(np.nextafter(z, 2.0)) + list(np.nextafter(z, -2.0))
    return np.clip(np.asarray(zs, dtype=np.float64), -1, 1)


def check_bounds(bounds, z, w, zf, dtype, slack, preset, n=4):
    """Assert lower ≤ Z(z < zf) ≤ Z(z ≤ zf) ≤ upper (up to ``slack``) for the biased moments of (z, w).

    ``bounds(b, zf) -> (lower, upper)``; the ``n`` moments are computed in float64, cast to
    ``dtype`` and biased there with ``preset``; the exact Z is taken at the depth the kernel
    sees (``zf`` rounded to ``dtype``).
    """
    b = bias_moments(power_moments(z, w, n=n).astype(dtype), preset)
    zf_d = zf.astype(dtype)
    zf_x = zf_d.astype(np.float64)
    lower, upper = (np.asarray(x, dtype=np.float64) for x in bounds(b, zf_d))
    z_lt, z_le = exact_shadow(z, w, zf_x), exact_shadow(z, w, zf_x, strict=False)
    assert np.isfinite(lower).all() and np.isfinite(upper).all()
    assert (lower <= z_lt + slack).all(), (b, zf_d[lower > z_lt + slack], lower, z_lt)
    assert (z_le <= upper + slack).all(), (b, zf_d[z_le > upper + slack], upper, z_le)
    assert (lower <= upper).all()


def lp_lower(b, zf, grid):
    """min Σ_{g < zf} x_g  s.t.  Σ x_g g^k = b_k (k = 0..n), x ≥ 0 (HiGHS), for the n moments ``b``."""
    A = np.vander(grid, len(b) + 1, increasing=True).T
    res = linprog((grid < zf).astype(float), A_eq=A, b_eq=np.concatenate([[1.0], b]), bounds=(0, None),
                  method="highs", options={"primal_feasibility_tolerance": 1e-10,
                                           "dual_feasibility_tolerance": 1e-10})
    assert res.status == 0, res.message
    return res.fun


def lp_grid(n):
    """``n`` grid points on [-3, 3]; an irrational shift keeps zf and the canonical points off the grid."""
    return np.linspace(-3, 3, n) + (6 / (n - 1)) * (np.sqrt(2) - 1)


#: Environment variable naming the folder of the test run that its xdist workers share (conftest).
RUN_FOLDER = "MOMENTS_REF_TEST_RUN"


def golden_folder(cases=None):
    """Goldens of ``cases`` (a tuple of names; None: every case), written once per test run.

    Several pytest sessions in one process (the mutation tool's runs) each remove their run folder at
    their end: a folder cached by an earlier session is written again.
    """
    d = _golden_folder(cases)
    if not (d.parent / f"{d.name}.done").exists():
        _golden_folder.cache_clear()
        d = _golden_folder(cases)
    return d


@functools.lru_cache(maxsize=None)
def _golden_folder(cases=None):
    """Goldens of ``cases`` (a tuple of names; None: every case), written once per test run.

    The first process of the run that asks writes them, under a lock, into the run's shared
    folder (``$MOMENTS_REF_TEST_RUN``, made by conftest; a private temporary folder without
    it); the other xdist workers wait for it and read the same files.
    """
    import fcntl
    import hashlib
    import os

    from moments_ref import golden

    run = os.environ.get(RUN_FOLDER)
    root = Path(run) if run else Path(tempfile.mkdtemp(prefix="moments-ref-test-golden-"))
    tag = "all" if cases is None else hashlib.sha256("\0".join(cases).encode()).hexdigest()[:16]
    d = root / f"golden-{tag}"
    with open(root / f"golden-{tag}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        done = root / f"golden-{tag}.done"
        if not done.exists():  # written last: its presence means the folder is complete
            d.mkdir(exist_ok=True)
            golden.write(d, None if cases is None else list(cases))
            done.touch()
    return d
