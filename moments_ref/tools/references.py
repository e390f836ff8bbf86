"""Numbered References sections, written from docs/bib.md: ``python -m moments_ref.tools.references``.

Docstrings cite a work by its short name in docs/bib.md (``HPG17 Eq. (3)``,
``Slides, "Bias the moments"``, ``VWSS §4``). Each module docstring ends with a
References section in the numpydoc form scipy.special uses, one numbered entry per
work, the entry starting with the short name so that a citation in the text leads
to it::

    References
    ----------
    .. [1] HPG17: Christoph Peters. 2017. *Non-Linearly Quantized Moment Shadow
           Maps*. In Proceedings of High Performance Graphics (HPG '17). ACM. ...
    .. [2] Vulkan specification, "Fixed-Point Data Conversions".

:func:`expected_section` numbers first the works of docs/bib.md the module cites
(:data:`CITATIONS` finds them anywhere in its source outside the section), in the
order of their first citation; then, in the order they stand, the section's other
entries: works of the bibliography it names without citing them in the text, and
entries of its own (a specification, a paper outside the bibliography), whose text
is kept. A bibliography entry's text is the row of docs/bib.md; the entries are
wrapped to :data:`WIDTH` columns with the hanging indent of numpydoc.

``--check`` exits 1 naming the modules whose section differs; ``--write`` rewrites
those sections (adding one where a citing module has none) and touches nothing else.
"""

from __future__ import annotations

import ast
import re
import sys
import textwrap
from pathlib import Path

from . import layout

__all__ = ["BIB", "CITATIONS", "WIDTH", "EXEMPT", "read_bib", "names", "cited", "section_span",
           "section_entries", "expected_section", "missing_references", "check", "write", "main"]

#: The bibliography: a table of ``| short name | work |`` rows.
BIB = layout.ROOT.parent / "docs" / "bib.md"
#: Column limit of the generated entries.
WIDTH = 99
#: How the text cites each short name of docs/bib.md (a row may have two names, comma-separated).
CITATIONS = {
    "HPG17": r"HPG17(?! demo)", "HPG17 demo": r"HPG17 demo", "Slides": r"\bSlides\b", "VWSS": r"\bVWSS\b",
    "Peters and Klein 2015": r"Peters and Klein 2015", "Peters et al. 2016": r"Peters et al\. 2016",
    "MSM-JCGT": r"MSM-JCGT", "Peters et al. 2017": r"Peters et al\. 2017",
    "Donnelly and Lauritzen 2006": r"Donnelly and Lauritzen", "Annen et al. 2008": r"Annen et al",
    "Salvi 2008": r"Salvi 2008", "Lauritzen and McCool 2008": r"Lauritzen and McCool",
    "Reeves et al. 1987": r"Reeves et al", "Isidoro 2006": r"Isidoro 2006", "Fernando 2005": r"Fernando 2005",
    "Klehm et al. 2014": r"Klehm", "Duff et al. 2017": r"Duff et al", "FLIP": r"ꟻLIP|FLIP"}
#: Modules that name the works without citing them: this one, which holds the names.
EXEMPT = ("tools.references",)

_HEADING = "References\n----------\n"
_ENTRY = re.compile(r"\.\. \[(\d+)\] (.*)")


def _rst(markdown):
    """A bib.md cell as docstring text: ``<url>`` -> ``url``, ```code``` -> ````code````."""
    text = re.sub(r"<(https?://[^>\s]+)>", r"\1", markdown.strip())
    return re.sub(r"(?<!`)`([^`]+)`(?!`)", r"``\1``", text)


def read_bib(path=None):
    """``{label: text}`` of docs/bib.md (or ``path``) in its order: first column -> the work, as docstring text."""
    out = {}
    for line in Path(path or BIB).read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")] if line.startswith("|") else []
        if len(cells) != 2 or cells[0] in ("cited as", "---") or set(cells[0]) <= {"-"}:
            continue
        out[cells[0]] = _rst(cells[1])
    return out


def names(label):
    """The short names of one bib.md row (``"MSM-JCGT, Peters et al. 2017"`` has two)."""
    return tuple(n.strip() for n in label.split(","))


def section_span(source):
    """Where the References section of ``source``'s module docstring is: ``(start, end)`` offsets.

    The section runs from its heading to the docstring's last text, before the closing quotes;
    ``(end, end)`` where the docstring has none, ``None`` where the module has no docstring.
    """
    tree = ast.parse(source)
    if not (tree.body and isinstance(tree.body[0], ast.Expr) and isinstance(tree.body[0].value, ast.Constant)
            and isinstance(tree.body[0].value.value, str)):
        return None
    node = tree.body[0]
    lines = source.splitlines(keepends=True)
    offset = [0]
    for ln in lines:
        offset.append(offset[-1] + len(ln))
    end = offset[node.end_lineno - 1] + len(lines[node.end_lineno - 1].encode("utf-8")[:node.end_col_offset]
                                            .decode("utf-8")) - 3
    if source[end:end + 3] not in ('"""', "'''"):
        return None
    start = offset[node.lineno - 1] + node.col_offset
    doc = source[start:end]
    at = doc.find("\n" + _HEADING)
    if at < 0:
        return end, end
    return start + at + 1, start + len(doc.rstrip())


def cited(source, bib):
    """Labels of ``bib`` that ``source`` cites outside its References section, in order of first citation."""
    span = section_span(source)
    text = source[:span[0]] + source[span[1]:] if span else source
    first = {}
    for label in bib:
        hits = [m.start() for n in names(label) if n in CITATIONS for m in [re.search(CITATIONS[n], text)] if m]
        if hits:
            first[label] = min(hits)
    return sorted(first, key=first.get)


def section_entries(section):
    """The entries' texts of a References section, whitespace collapsed.

    Raises ``ValueError`` on a line that is neither an entry ``.. [n] text`` nor its indented
    continuation.
    """
    entries = []
    for line in section[len(_HEADING):].splitlines() if section.startswith(_HEADING) else ():
        m = _ENTRY.match(line)
        if m:
            entries.append(m.group(2).strip())
        elif line[:1].isspace() and line.strip() and entries:
            entries[-1] += " " + line.strip()
        elif line.strip():
            raise ValueError(f"References: {line.strip()!r} is not a numbered entry '.. [n] text'")
    return entries


def _label_of(entry, bib):
    for label in sorted(bib, key=len, reverse=True):
        if entry.startswith(label + ":") or entry == label:  # a bare label: --write fills in the text
            return label
    return None


def _format(number, text):
    head = f".. [{number}] "
    return textwrap.fill(text, WIDTH, initial_indent=head, subsequent_indent=" " * len(head),
                         break_long_words=False, break_on_hyphens=False)


def expected_section(source, bib):
    """The References section ``source`` should have (``""`` when it needs none), from ``bib``."""
    span = section_span(source)
    current = section_entries(source[span[0]:span[1]]) if span else []
    order = cited(source, bib)
    rest = []
    for entry in current:
        label = _label_of(entry, bib)
        if label is None:
            rest.append(entry)
        elif label not in order and label not in rest:
            rest.append(label)
    items = [f"{x}: {bib[x]}" if x in bib else x for x in order + rest]
    if not items:
        return ""
    return _HEADING + "\n".join(_format(i, t) for i, t in enumerate(items, 1))


def missing_references(source, bib=None):
    """The works ``source`` cites that its References section does not name (a label of docs/bib.md each)."""
    bib = read_bib() if bib is None else bib
    span = section_span(source)
    section = source[span[0]:span[1]] if span else ""
    return [label for label in cited(source, bib) if not any(n in section for n in names(label))]


def _sources(root):
    root = Path(root or layout.ROOT)
    for name in layout.module_names(root):
        if name not in EXEMPT:
            path = root / (name.replace(".", "/") + ".py")
            yield name, (path if path.is_file() else root / name.replace(".", "/") / "__init__.py")


def _rewritten(source, bib):
    span = section_span(source)
    if span is None:
        return source
    new = expected_section(source, bib)
    if source[span[0]:span[1]] == new:
        return source
    if span[0] == span[1] and new:  # no section yet: a blank line, then the section
        sep = "\n" if source[:span[0]].endswith("\n") else "\n\n"
        return source[:span[0]] + sep + new + "\n" + source[span[1]:]
    return source[:span[0]] + new + source[span[1]:]


def check(root=None, bib=None):
    """``[(module, why)]``: the modules below ``root`` whose References section is not the expected one."""
    bib = read_bib() if bib is None else bib
    bad = []
    for name, path in _sources(root):
        source = path.read_text(encoding="utf-8")
        try:
            if _rewritten(source, bib) != source:
                bad.append((name, "section differs: python -m moments_ref.tools.references --write"))
        except ValueError as e:
            bad.append((name, str(e)))
    return bad


def write(root=None, bib=None):
    """Rewrite the sections that differ; returns :func:`check`'s list of what could not be written."""
    bib = read_bib() if bib is None else bib
    left = []
    for name, path in _sources(root):
        source = path.read_text(encoding="utf-8")
        try:
            new = _rewritten(source, bib)
        except ValueError as e:
            left.append((name, str(e)))
            continue
        if new != source:
            path.write_text(new, encoding="utf-8")
    return left


def main(argv=None):
    """``--check`` (exit 1 listing the modules whose section differs) or ``--write``."""
    argv = sys.argv[1:] if argv is None else argv
    if argv not in (["--check"], ["--write"]):
        print("usage: python -m moments_ref.tools.references --check | --write", file=sys.stderr)
        return 2
    bad = check() if argv == ["--check"] else write()
    for name, why in bad:
        print(f"moments_ref.{name}: {why}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
