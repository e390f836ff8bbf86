"""The columns of results.csv: one table naming each column, its type and what it holds.

:data:`COLUMN_TABLE` is the one list: :data:`COLUMNS` (the order of results.csv and of
report.md's results table), the float columns, how a column is parsed back
(:func:`parse_row`) and the column list of docs/report.md (:func:`columns_markdown`;
``python -m moments_ref.tools.apidoc --columns`` rewrites it, ``tests/test_report.py`` keeps it current) all come from it. A new column is one
:class:`Column` here and the code that computes its value (docs/architecture.md,
"How do I").

References
----------
.. [1] FLIP: Pontus Andersson, Jim Nilsson, Tomas Akenine-Möller, Magnus Oskarsson, Kalle Åström
       and Mark D. Fairchild. 2020. *ꟻLIP: A Difference Evaluator for Alternating Images*.
       Proceedings of the ACM on Computer Graphics and Interactive Techniques (HPG 2020) 3, 2. Used
       through the package ``flip-evaluator``.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..metrics import LEAK_THRESHOLD

__all__ = ["Column", "COLUMN_TABLE", "COLUMNS", "FLOAT_COLUMNS", "MARKERS", "parse_row", "columns_markdown", "write_docs"]


@dataclass(frozen=True)
class Column:
    """One column of results.csv.

    Attributes
    ----------
    name : str
    kind : {"text", "int", "float", "bool"}, how results.csv spells and parses it
    what : str, one line for docs/report.md
    """

    name: str
    kind: str
    what: str


def _timing(kind, what):
    median = Column(f"{kind}_seconds", "float", f"{what}: median over the repeats (CPU seconds)")
    return (median, Column(f"{kind}_seconds_min", "float", f"{what}: fastest repeat"),
            Column(f"{kind}_seconds_max", "float", f"{what}: slowest repeat"))


#: Every column, in the order of results.csv.
COLUMN_TABLE = (
    Column("scene", "text", "the scene's name"),
    Column("technique", "text", "the technique's registered name"),
    Column("bits_per_texel", "int", "storage per shadow-map texel (all MSAA samples or light-sample maps)"),
    Column("rmse", "float", "root mean square of e = shadow − reference over the receiver pixels"),
    Column("max_error", "float", "max |e|"),
    Column("p99_error", "float", "99th percentile of |e|"),
    Column("leak_fraction", "float", f"share of pixels lit more than {LEAK_THRESHOLD} above the reference"),
    Column("flip_mean", "float", "mean NVIDIA ꟻLIP (LDR) of the shaded image against the reference's"),
    *_timing("texel", "seconds of the technique's texture stages"),
    *_timing("fragment", "seconds of its lookups for all receiver pixels"),
    *_timing("own_total", "texel + fragment seconds extrapolated to the scene's own map size and camera"),
    Column("repeats", "int", "timed repeats after the warm-up"),
    Column("pareto", "bool", "on the three-objective Pareto front (RMSE, texel cost, fragment cost)"),
)

#: The column names, in order.
COLUMNS = tuple(c.name for c in COLUMN_TABLE)
#: The float columns.
FLOAT_COLUMNS = tuple(c.name for c in COLUMN_TABLE if c.kind == "float")

_PARSE = {"text": str, "int": int, "float": float, "bool": lambda s: s == "true"}


def parse_row(row):
    """A results.csv row (dict of strings) with each column parsed by its kind."""
    return {c.name: _PARSE[c.kind](row[c.name]) for c in COLUMN_TABLE}


def columns_markdown():
    """The column table of docs/report.md."""
    lines = ["| column | type | what |", "|---|---|---|"]
    lines += [f"| `{c.name}` | {c.kind} | {c.what} |" for c in COLUMN_TABLE]
    return "\n".join(lines)


#: The markers around the generated table in docs/report.md.
MARKERS = ("<!-- columns: begin -->\n", "\n<!-- columns: end -->")


def write_docs(path):
    """Rewrite the column table between :data:`MARKERS` in ``path`` (docs/report.md); return the path."""
    from .._io import write_between

    return write_between(path, MARKERS, columns_markdown())

