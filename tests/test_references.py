"""The numbered References sections of moments_ref.tools.references.

Expected values are typed here: two rows of docs/bib.md as a reader copies them, and
the sections a synthetic module must get from a bibliography of two made-up works.
"""

from __future__ import annotations

import pytest

from moments_ref.tools import references

#: A bibliography of two works, the second with two short names.
BIB = {"Smith 2001": "Ann Smith. 2001. *A Paper*. A Journal 1, 2.",
       "LONG, Jones et al. 2002": "Bob Jones and Cy Lee. 2002. *A Second Paper With A Rather Long Title "
                                  "That Needs Wrapping*. Another Journal."}

SOURCE = '''"""A module.

It uses Jones et al. 2002 first, then Smith 2001 (Eq. 3), then LONG again.

References
----------
.. [1] Smith 2001: an old text of the entry.
.. [2] Vulkan specification, "Fixed-Point
       Data Conversions".
"""

X = 1  # Smith 2001 once more
'''

EXPECTED = '''References
----------
.. [1] LONG, Jones et al. 2002: Bob Jones and Cy Lee. 2002. *A Second Paper With A Rather Long
       Title That Needs Wrapping*. Another Journal.
.. [2] Smith 2001: Ann Smith. 2001. *A Paper*. A Journal 1, 2.
.. [3] Vulkan specification, "Fixed-Point Data Conversions".'''


@pytest.fixture
def patterns(monkeypatch):
    monkeypatch.setattr(references, "CITATIONS", {"Smith 2001": r"Smith 2001", "LONG": r"\bLONG\b",
                                                  "Jones et al. 2002": r"Jones et al\. 2002"})


def test_bib_md_rows_are_read_as_written():
    bib = references.read_bib()
    assert bib["VWSS"] == (
        "Adam Marrs, Benjamin Watson and Christopher Healey. 2018. *View-warped Multi-view Soft Shadowing "
        "for Local Area Lights*. Journal of Computer Graphics Techniques (JCGT) 7, 3, 1–28. "
        "http://jcgt.org/published/0007/03/01/")
    assert bib["MSM-JCGT, Peters et al. 2017"] == (
        "Christoph Peters, Cedrick Münstermann, Nico Wetzstein and Reinhard Klein. 2017. *Improved Moment "
        "Shadow Maps for Translucent Occluders, Soft Shadows and Single Scattering*. Journal of Computer "
        "Graphics Techniques (JCGT) 6, 1, 17–67. http://jcgt.org/published/0006/01/03/")
    assert references.names("MSM-JCGT, Peters et al. 2017") == ("MSM-JCGT", "Peters et al. 2017")
    assert "cited as" not in bib and len(bib) == 17


def test_section_numbers_cited_works_first_then_keeps_the_others(patterns):
    assert references.cited(SOURCE, BIB) == ["LONG, Jones et al. 2002", "Smith 2001"]
    assert references.expected_section(SOURCE, BIB) == EXPECTED


def test_write_touches_only_the_section_and_check_then_passes(tmp_path, patterns):
    (tmp_path / "mod.py").write_text(SOURCE, encoding="utf-8")
    (tmp_path / "bare.py").write_text('"""Cites Smith 2001."""\n\nY = 2\n', encoding="utf-8")
    (tmp_path / "bare2.py").write_text('"""Cites Smith 2001.\n\nMore.\n"""\n', encoding="utf-8")
    (tmp_path / "plain.py").write_text('"""Cites nothing."""\n', encoding="utf-8")
    assert references.check(tmp_path, BIB) == [
        ("bare", "section differs: python -m moments_ref.tools.references --write"),
        ("bare2", "section differs: python -m moments_ref.tools.references --write"),
        ("mod", "section differs: python -m moments_ref.tools.references --write")]
    assert references.write(tmp_path, BIB) == []
    head, tail = SOURCE.split("References\n")[0], '\n"""\n\nX = 1  # Smith 2001 once more\n'
    assert (tmp_path / "mod.py").read_text(encoding="utf-8") == head + EXPECTED + tail
    assert (tmp_path / "bare.py").read_text(encoding="utf-8") == (
        '"""Cites Smith 2001.\n\nReferences\n----------\n'
        '.. [1] Smith 2001: Ann Smith. 2001. *A Paper*. A Journal 1, 2.\n"""\n\nY = 2\n')
    assert (tmp_path / "bare2.py").read_text(encoding="utf-8") == (
        '"""Cites Smith 2001.\n\nMore.\n\nReferences\n----------\n'
        '.. [1] Smith 2001: Ann Smith. 2001. *A Paper*. A Journal 1, 2.\n"""\n')
    assert (tmp_path / "plain.py").read_text(encoding="utf-8") == '"""Cites nothing."""\n'
    assert references.check(tmp_path, BIB) == []


def test_a_cited_work_missing_from_the_section_fails(tmp_path, patterns):
    source = '"""Uses LONG.\n\nReferences\n----------\n.. [1] Smith 2001: x\n"""\n# Smith 2001\n'
    assert references.missing_references(source, BIB) == ["LONG, Jones et al. 2002"]
    (tmp_path / "m.py").write_text(source, encoding="utf-8")
    assert [name for name, _ in references.check(tmp_path, BIB)] == ["m"]


def test_a_line_that_is_no_numbered_entry_is_reported(tmp_path, patterns):
    (tmp_path / "old.py").write_text('"""Smith 2001.\n\nReferences\n----------\nSmith 2001 : see bib.\n"""\n')
    assert references.check(tmp_path, BIB) == [
        ("old", "References: 'Smith 2001 : see bib.' is not a numbered entry '.. [n] text'")]
    assert references.write(tmp_path, BIB) == references.check(tmp_path, BIB)


def test_the_package_sections_are_current_and_the_command_says_so(capsys):
    assert references.main(["--check"]) == 0
    assert references.main(["--frobnicate"]) == 2
    assert "usage" in capsys.readouterr().err


def test_a_bare_short_name_is_filled_in_not_repeated(patterns):
    # A contributor may write only the short name; --write fills in its text, once.
    source = SOURCE.replace(".. [1] Smith 2001: an old text of the entry.", ".. [1] Smith 2001")
    assert references.expected_section(source, BIB) == EXPECTED
