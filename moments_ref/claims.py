"""Paper claims as machine-readable records: ``claims.json`` and a markdown table.

Each claim of the three documents that the reference can measure is one
:class:`Claim`: an ``id`` (``hpg17-…``, ``vwss-…``, ``slides-…``), the ``source``
it is stated in ("HPG17 §5", "VWSS Table 1", "Slides: Prefiltered single
scattering"), the ``statement`` in the paper's words, the paper's own figure
(``paper``, text), what was ``measured`` here (a number or a JSON object), the
``settings`` of the measurement, a ``verdict`` and ``why`` (one sentence).

Verdicts. ``"holds"`` and ``"does not hold"`` compare the measurement with the
paper's own figure, never with a threshold the paper does not state; where the
paper states no number (``"very little light leaking"``) the comparison is the
one the sentence makes (less than, close to, the same figure's other technique)
and ``why`` says how it was read. ``"not measurable here"`` means the scene or
technique the claim needs did not run, or the quantity has no counterpart on this
platform (a GPU timing on a NumPy implementation).

This module holds no measurement: :mod:`moments_ref.techniques.vwss.paper` builds the VWSS
claims, :mod:`moments_ref.report.paper_claims` those of HPG17 and the slides.

References
----------
.. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow Maps*. In Proceedings
       of High Performance Graphics (HPG '17). ACM. The non-linear quantization Φ, Ψ4, Algorithms
       1–3, the texel formats and the compute shader of §4.1.
.. [2] VWSS: Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft
       Shadowing for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28.
       http://jcgt.org/published/0007/03/01/
.. [3] Slides: Christoph Peters. *Rendering antialiased shadows with moment shadow mapping*,
       lecture slides (PDF version, with notes) on moment shadow mapping, translucent occluders,
       moment soft shadow mapping and prefiltered single scattering; http://MomentsInGraphics.de/.
       Cited by slide title, e.g. Slides, "Bias the moments".
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ._arrays import InputError
from ._io import write_text

__all__ = ["VERDICTS", "Claim", "to_json", "write_json", "markdown_table", "verdict_of", "find_row"]

#: The three verdicts a claim can have.
VERDICTS = ("holds", "does not hold", "not measurable here")


def _plain(x):
    """JSON-ready copy: NumPy scalars and arrays to Python, NaN/inf to None."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    return x


@dataclass
class Claim:
    """One paper claim and its measurement (module docstring)."""

    id: str
    source: str
    statement: str
    paper: str
    measured: object = None
    settings: dict = field(default_factory=dict)
    verdict: str = "not measurable here"
    why: str = ""

    def __post_init__(self):
        if self.verdict not in VERDICTS:
            raise InputError(f"verdict: expected one of {', '.join(map(repr, VERDICTS))}, got {self.verdict!r}")
        if not self.id or not isinstance(self.id, str):
            raise InputError(f"id: expected a non-empty string, got {self.id!r}")

    def as_dict(self) -> dict:
        """The record with JSON-ready values (NaN becomes null)."""
        return _plain(asdict(self))


def verdict_of(holds) -> str:
    """``True`` → "holds", ``False`` → "does not hold", ``None`` → "not measurable here"."""
    if holds is None:
        return "not measurable here"
    return "holds" if bool(holds) else "does not hold"


def to_json(claims) -> str:
    """``claims.json`` text: a list of objects with the :class:`Claim` fields, in order."""
    ids = [c.id for c in claims]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise InputError(f"claims: expected unique ids, got duplicates {dup}")
    return json.dumps([c.as_dict() for c in claims], indent=2, ensure_ascii=False) + "\n"


def write_json(claims, path):
    """Write ``claims.json`` atomically; return the path."""
    return write_text(path, to_json(claims))


def _cell(x) -> str:
    if isinstance(x, float):
        return "n/a" if not math.isfinite(x) else f"{x:.4g}"
    if isinstance(x, dict):
        return ", ".join(f"{k} {_cell(v)}" for k, v in x.items())
    if isinstance(x, (list, tuple)):
        return ", ".join(_cell(v) for v in x)
    return str(x).replace("|", "\\|").replace("\n", " ")


def markdown_table(claims) -> str:
    """The claims as a markdown table: id, source, statement, the paper's figure, ours, metric, setting, verdict, why.

    ``ours`` is ``measured["ours"]`` where the claim states one (else every measured
    value); ``metric`` is ``settings["metric"]`` and ``setting`` the other settings.
    """
    lines = ["| id | source | statement | paper | ours | metric | setting | verdict | why |",
             "|---|---|---|---|---|---|---|---|---|"]
    for c in claims:
        v = c.verdict if c.verdict == "holds" else f"**{c.verdict}**"
        m = c.measured if isinstance(c.measured, dict) else {}
        st = dict(c.settings) if isinstance(c.settings, dict) else {}
        metric = st.pop("metric", "")
        lines.append(f"| `{c.id}` | {_cell(c.source)} | {_cell(c.statement)} | {_cell(c.paper)} | "
                     f"{_cell(m['ours'] if 'ours' in m else _plain(c.measured))} | {_cell(metric)} | "
                     f"{_cell(_plain(st))} | {v} | {_cell(c.why)} |")
    return "\n".join(lines) + "\n"


def find_row(rows, scene, technique):
    """The results row (a dict with ``scene`` and ``technique``) of ``technique`` on ``scene``, or None."""
    return next((r for r in rows if r["scene"] == scene and r["technique"] == technique), None)
