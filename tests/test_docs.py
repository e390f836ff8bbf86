"""docs/api.md lists every public name; the generated docs are what their generators write."""

import importlib
import pkgutil
from pathlib import Path

import pytest

import moments_ref
from moments_ref.tools import apidoc as _apidoc

ROOT = Path(__file__).resolve().parents[1]


def test_api_doc_is_current():
    assert (ROOT / "docs" / "api.md").read_text().strip() == _apidoc.render().strip(), \
        "regenerate: python -m moments_ref.tools.apidoc > docs/api.md"


def test_golden_contract_table_is_current():
    """docs/golden.md's contract table is generated from the cases' registry entries (golden.casedoc)."""
    from moments_ref.golden.casedoc import MARKERS, contracts_markdown

    text = (ROOT / "docs" / "golden.md").read_text()
    block = text.split(MARKERS[0], 1)[1].split(MARKERS[1], 1)[0]
    assert block == contracts_markdown(), "regenerate: python -m moments_ref.tools.apidoc --cases"


def test_every_public_module_is_documented():
    """Every public module with names of its own has a section in docs/api.md; the others are
    re-exported by their package (checked here name by name), the CLI, package data or a shim."""
    documented = set(_apidoc.public_modules())
    api = (ROOT / "docs" / "api.md").read_text()
    for m in pkgutil.walk_packages(moments_ref.__path__, "moments_ref."):
        name = m.name.removeprefix("moments_ref.")
        if any(part.startswith("_") for part in name.split(".")) or name in ("cli", "ports") \
                or _apidoc.layout.is_shim(name) or _apidoc.layout.is_shim(name.split(".")[0]):
            continue
        mod = importlib.import_module(m.name)
        names = set(getattr(mod, "__all__", ()))
        assert names or m.ispkg, f"moments_ref.{name} has no __all__"
        if name in documented:
            assert f"## `moments_ref.{name}`" in api
            continue
        parent = importlib.import_module(m.name.rsplit(".", 1)[0])
        assert names <= set(parent.__all__), f"moments_ref.{name} is missing from docs/api.md"


def test_design_table_names_are_exported():
    for name in ("power_moments", "hankel", "bias_moments", "BIAS_FLOAT32", "BIAS_UNORM16", "shadow_intensity",
                 "canonical_representation", "to_optimized", "from_optimized", "encode_unorm16", "decode_unorm16",
                 "phi", "phi_inverse", "psi4", "psi4_inverse", "shade", "pack64", "unpack64", "pack32", "unpack32"):
        assert name in moments_ref.__all__
    from moments_ref import golden, oracle

    assert callable(golden.write) and callable(golden.verify) and callable(oracle.check)


def _between_markers(path):
    text = (ROOT / path).read_text()
    return text.split("<!-- layout: begin -->\n", 1)[1].split("\n<!-- layout: end -->", 1)[0].strip()


def test_layout_tables_are_generated_from_the_folders():
    table = _apidoc.layout_markdown()
    assert _between_markers("docs/architecture.md") == table, \
        "regenerate the table in docs/architecture.md: python -m moments_ref.tools.apidoc --layout"
    readme = (ROOT / "README.md").read_text()
    assert "<!-- layout: begin -->" not in readme and "(docs/architecture.md)" in readme  # one home: a link
    rows = {p for _, p, _ in _apidoc.layout.layout_rows()}
    folders = {f"moments_ref/{p.name}/" for p in (ROOT / "moments_ref").iterdir()
               if (p / "__init__.py").is_file() and not _apidoc.layout.is_shim(p.name)}
    assert folders <= rows and "moments_ref/gpu/" in rows and "moments_ref/tools/" in rows


def test_shared_parameter_docs_are_written_once_and_filled():
    """`b`, `zf` and `r` are documented once (moments_ref._docs) and filled into every docstring that names them."""
    import inspect
    import textwrap

    from moments_ref import _docs, msm, nonlinear, precise

    filled = _docs.fill("    Parameters\n    ----------\n    %(zf)s\n        Cast to b's dtype.\n")
    assert filled.splitlines()[2] == "    zf : (...) float array"
    assert filled.splitlines()[3].startswith("        Fragment depth in the light's NDC")
    assert filled.rstrip().endswith("        Cast to b's dtype.")
    with pytest.raises(KeyError):
        _docs.fill("    %(nothing)s\n")
    for fn in (msm.shadow_intensity, nonlinear.shade, precise.shadow_intensity):
        doc = inspect.getdoc(fn)
        assert "%(" not in doc and "zf : (...) float array" in doc, fn.__name__
    sources = {p: p.read_text(encoding="utf-8") for p in (ROOT / "moments_ref").rglob("*.py")}
    for name, entry in _docs.PARAMETERS.items():
        description = textwrap.dedent(entry.split("\n", 1)[1]).split("\n")[0]
        where = [str(p) for p, s in sources.items() if description in s]
        assert where == [str(ROOT / "moments_ref" / "_docs.py")], (name, where)
    assert not [str(p) for p, s in sources.items() if "Fragment depth, broadcast against ``b" in s]
    for m in pkgutil.walk_packages(moments_ref.__path__, "moments_ref."):
        if m.name.endswith("__main__"):
            continue
        mod = importlib.import_module(m.name)
        for obj in vars(mod).values():
            if inspect.isfunction(obj) and obj.__module__ == m.name and obj.__doc__:
                assert "%(" not in obj.__doc__ or "fill" in obj.__name__, f"{m.name}.{obj.__name__}: unfilled"


def test_stability_figures_state_their_distribution_count_and_interval():
    """docs/stability.md's figures from random rows: the distributions block is the command's, and every
    error row carries its count and a 95 % interval around its 99th percentile."""
    import re

    from moments_ref.tools import stability

    doc = (ROOT / "docs" / "stability.md").read_text(encoding="utf-8")
    assert stability.distributions_markdown(300, 0).strip() in doc, \
        "regenerate: moments-ref stability --out docs/"
    for cat in (*stability.MSM_CATEGORIES, *stability.NONLINEAR_CATEGORIES):
        assert f"| {cat} |" in doc.split("## Sampled distributions", 1)[1].split("\n## ", 1)[0]
    row = r"^\| [^|]+ \| float(?:32|64) \| (\d+) \| [^|]+ \| ([^|]+) \| \[([^,]+), ([^\]]+)\] \|"
    rows = re.findall(row, doc, re.M)
    assert len(rows) > 50
    for n, p99, lo, hi in rows:
        assert int(n) == 300 and hi.strip() == "∞"  # 300 rows cannot bound a 99th percentile from above
        assert float(lo) <= float(p99)


def _ranks_brute_force(n, q, tail):
    """The order-statistic ranks of the quantile interval, from the binomial sums written out (no SciPy)."""
    from math import comb

    pmf = [comb(n, k) * q ** k * (1 - q) ** (n - k) for k in range(n + 1)]
    cdf = [sum(pmf[:k + 1]) for k in range(n + 1)]
    lo = next(k for k in range(n + 1) if cdf[k] >= tail)  # P(B < lo) <= tail
    hi = next(k for k in range(n + 1) if cdf[k] >= 1 - tail) + 1  # P(B >= hi) <= tail
    return lo, hi


@pytest.mark.parametrize("n, q", [(300, 0.99), (300, 0.9), (50, 0.5), (1000, 0.99)])
def test_quantile_interval_ranks_and_coverage(n, q):
    import numpy as np

    from moments_ref.tools import intervals as stability

    x = np.arange(1.0, n + 1)  # x_(k) = k: the interval's ends are its ranks
    lo, hi = stability.quantile_interval(x, q)
    want_lo, want_hi = _ranks_brute_force(n, q, 0.025)
    assert lo == want_lo and (hi == want_hi if want_hi <= n else hi == np.inf)
    # coverage of the true quantile of uniform draws, at least the stated 95 % (up to the simulation's noise)
    rng = np.random.default_rng(7)
    hits = [lo_ <= q <= hi_ for lo_, hi_ in (stability.quantile_interval(rng.random(n), q) for _ in range(400))]
    assert np.mean(hits) >= 0.92
    # the largest of n uniform draws is exceeded by a fresh one with probability 1/(n+1): within the bound
    assert 1 / (n + 1) <= stability.exceedance_bound(n) <= 3.1 / n


def test_intervals_refuse_bad_input():
    import numpy as np

    from moments_ref import InputError
    from moments_ref.tools import intervals

    for args, match in ((([],), "x: expected at least one"), (([1.0, np.nan],), "NaN"),
                        (([1.0], 1.0), "q: expected a value in"), (([1.0], 0.5, 0), "confidence")):
        with pytest.raises(InputError, match=match):
            intervals.quantile_interval(*args)
    with pytest.raises(InputError, match="n: expected a positive integer"):
        intervals.exceedance_bound(0)
    assert intervals.quantile_interval([np.inf, 1.0, 2.0], 0.5)[1] == np.inf  # an infinite error is a value


@pytest.mark.parametrize("page, markers, block", [("msm6.md", "UNORM10_MARKERS", "unorm10_block"),
                                                  ("msm6.md", "CUBIC_MARKERS", "cubic_block"),
                                                  ("msm6.md", "STIFF_MARKERS", "stiff_block"),
                                                  ("ports.md", "MIX_MARKERS", "mix_block")])
def test_random_figures_are_the_commands(page, markers, block):
    from moments_ref.tools import random_figures

    doc = (ROOT / "docs" / page).read_text(encoding="utf-8")
    begin, end = getattr(random_figures, markers)
    assert doc.split(begin, 1)[1].split(end, 1)[0].strip() == getattr(random_figures, block)().strip(), \
        "regenerate: python -m moments_ref.tools.random_figures"


@pytest.mark.parametrize("k, n", [(3032, 4000), (0, 100), (50, 100), (4000, 4000), (1, 7)])
def test_wilson_interval_is_the_set_the_score_test_accepts(k, n):
    """Independently of the closed form: the ends solve |k/n − p| = z √(p (1 − p) / n), and p inside passes."""
    import numpy as np

    from moments_ref.tools import intervals

    lo, hi = intervals.wilson_interval(k, n)
    z, p_hat = 1.959963984540054, k / n
    p = np.linspace(0, 1, 200001)
    accepted = p[np.abs(p_hat - p) <= z * np.sqrt(p * (1 - p) / n)]
    assert lo == pytest.approx(accepted.min(), abs=2e-5) and hi == pytest.approx(accepted.max(), abs=2e-5)


def test_a_generated_block_is_written_between_its_markers_and_refused_without_them(tmp_path):
    from moments_ref import InputError
    from moments_ref._io import write_between

    p = tmp_path / "doc.md"
    p.write_text("intro\n<!-- a -->old<!-- b -->\nend\n", encoding="utf-8")
    write_between(p, ("<!-- a -->", "<!-- b -->"), "\nnew\n")
    assert p.read_text(encoding="utf-8") == "intro\n<!-- a -->\nnew\n<!-- b -->\nend\n"
    for bad in ("no markers\n", "<!-- b --> then <!-- a -->\n", "<!-- a --><!-- a --><!-- b -->\n"):
        p.write_text(bad, encoding="utf-8")
        with pytest.raises(InputError, match="expected one"):
            write_between(p, ("<!-- a -->", "<!-- b -->"), "x")
        assert p.read_text(encoding="utf-8") == bad  # nothing written


def test_conformance_probe_counts_carry_their_wilson_interval():
    """Every 'k of n' in docs/conformance.md's probe table states the 95 % Wilson interval of k / n."""
    import re

    from moments_ref.tools.intervals import wilson_interval

    doc = (ROOT / "docs" / "conformance.md").read_text(encoding="utf-8")
    section = doc.split("## Floating-point behaviour of the drivers (measured)", 1)[1].split("\n## ", 1)[0]
    counts = re.findall(r"(\d+) of (\d+) \(max \d+ ulp(?:; 95 % interval ([^ ]+) % to ([^ ]+) %)?\)", section)
    assert len(counts) >= 2, "the probe table lost its division and sqrt columns"
    for k, n, lo, hi in counts:
        want = wilson_interval(int(k), int(n))
        assert (lo, hi) == (f"{100 * want[0]:.2g}", f"{100 * want[1]:.2g}"), \
            f"{k} of {n}: regenerate with moments-ref conformance --all --out docs/"
    xi4 = doc.split("## The ξ4 code through `log` (measured)", 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"\| (\d+) of (\d+) \([^)]*\) \| ([^ ]+) % to ([^ ]+) % \|", xi4)
    assert len(rows) >= 2, "the ξ4 table lost its rows"
    for k, n, lo, hi in rows:
        want = wilson_interval(int(k), int(n))
        assert (lo, hi) == (f"{100 * want[0]:.2g}", f"{100 * want[1]:.2g}"), f"ξ4: {k} of {n}"


def test_stiff_cases_are_drawn_as_stated_and_their_excess_sees_a_too_weak_bias():
    """The sampler's documented shape, checked by brute force; α = 3e-7 in float32 is known to break the bounds."""
    import numpy as np

    from moments_ref import msm6
    from moments_ref.moments import BiasPreset, bias_moments, power_moments
    from moments_ref.tools import random_figures

    z, w, zf = random_figures.stiff_cases(300, seed=4)
    used = w > 0
    assert z.dtype == np.float32 and set(used.sum(axis=1)) == set(range(1, 7))
    assert np.allclose(w.sum(axis=1), 1) and (w[used] >= 0.05 / 6).all()
    spread = np.where(used, z, np.nan)
    assert (np.nanmax(spread, axis=1) - np.nanmin(spread, axis=1) <= 0.2 + 1e-6).all()
    assert 0.2 < np.mean((np.abs(z[:, 0]) > 0.9)) < 0.6  # about a third clustered at ±1
    for i in range(6):  # every used depth and its float32 neighbours are fragment depths
        rows = used[:, i]
        assert (zf[rows, 3 * i + 1] == z[rows, i]).all()
        assert (zf[rows, 3 * i] <= z[rows, i]).all() and (zf[rows, 3 * i + 2] >= z[rows, i]).all()
    # A loop over rows (not the block's broadcasting) for the true Z, and a bias known to be useless in float32.
    b = bias_moments(power_moments(z.astype(np.float64), w, n=6).astype(np.float32),
                     BiasPreset(3e-7, msm6.BIAS6_TARGET))
    worst = 0.0
    for r in range(len(z)):
        lower, _ = msm6.shadow_bounds(b[r], zf[r])
        truth = np.array([w[r][z[r] < f].sum() for f in zf[r]])
        worst = max(worst, float((lower - truth).max()))
    assert worst > 0.5
