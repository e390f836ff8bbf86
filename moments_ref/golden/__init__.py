"""Golden vectors for ports: write them, verify a foreign implementation's results.

``moments-ref golden --out DIR`` writes one ``.npz`` per case and ``manifest.json``;
``moments-ref verify`` compares a port's results with them (docs/golden.md).

================================  ================================================
:mod:`.cases`                     the cases: function, dtype, inputs in order, kwargs
``_rows``, ``_rows_nonlinear``    the labelled rows (category, comment, flags)
:mod:`.endtoend`                  whole chains compared as shadow intensities
:mod:`.engine`                    the engine's pipeline from depth distributions (a band of legitimate values)
:mod:`.truth`                     Algorithm 3 with its clamps in mpmath
:mod:`.notes`                     the row flags, defined once (manifest ``notes``)
:mod:`.contract`                  the inputs each published algorithm defines
:mod:`.spread`                    per-row tolerances from legitimate implementations
:mod:`.paper`, :mod:`.gpuspread`  the papers' own code and a GPU, as legitimate variants
:mod:`.profile`                   an engine's declared conventions (``--profile``)
:mod:`.conventions`               the cases under a profile: converted, derived, cached
:mod:`.variants`                  how a profile configures each case's reference
:mod:`.compare`                   the one comparator (verify, oracle, conformance)
:mod:`.diagnosis`                 failing rows grouped by cause; ``--json`` records
:mod:`.writer`                    :func:`write`
:mod:`.verifier`                  :func:`verify`, safe reading of a golden folder
:mod:`.mutation`                  mutation score of the oracle (``moments-ref mutants``)
================================  ================================================
"""

from .cases import CASES, Case, case_rows, case_table, evaluate_reference, expected_outputs
from .compare import Verdict, compare
from .notes import NOTES
from .profile import Profile, load_profile
from .verifier import CaseResult, VerifyReport, load_case_arrays, load_manifest, verify
from .writer import CATEGORIES, SCHEMA_VERSION, golden_arrays, manifest_entry, write

__all__ = ["Case", "CASES", "SCHEMA_VERSION", "CATEGORIES", "NOTES", "write", "verify", "compare", "Verdict",
           "case_rows", "case_table", "golden_arrays", "manifest_entry", "VerifyReport", "CaseResult",
           "evaluate_reference", "expected_outputs", "load_manifest", "load_case_arrays", "Profile", "load_profile"]
