"""The chunk sizes of the vectorized loops live in one table, moments_ref._kernels, each with its reason."""

import ast
import inspect
import re
from pathlib import Path

import moments_ref
from moments_ref import _kernels

ROOT = Path(moments_ref.__file__).parent
#: Chunk constants allowed elsewhere, with why they are not a kernel's chunk.
ELSEWHERE = {("scene/mesh.py", "OBJ_CHUNK"): "lines of an OBJ file per parse buffer, not a vectorized loop's chunk"}


def _chunk_literals(path):
    """``(name, line)`` of module-level assignments of a number expression to a name containing CHUNK."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and all(isinstance(t, ast.Name) for t in node.targets):
            for t in node.targets:
                literal = all(isinstance(n, (ast.Constant, ast.BinOp, ast.operator)) for n in ast.walk(node.value))
                if "CHUNK" in t.id and literal:
                    yield t.id, node.lineno


def test_chunk_sizes_are_defined_only_in_the_kernels_table():
    found = []
    for path in ROOT.rglob("*.py"):
        rel = path.relative_to(ROOT).as_posix()
        if rel == "_kernels.py":
            continue
        found += [(rel, name, line) for name, line in _chunk_literals(path) if (rel, name) not in ELSEWHERE]
    assert not found, f"chunk sizes defined outside moments_ref._kernels: {found}"


def test_every_chunk_size_of_the_table_states_its_reason():
    source = inspect.getsource(_kernels)
    for name in _kernels.__all__:
        if re.search(r"(CHUNK|BAND|BLOCK|BUDGET|BYTES|TEXELS)", name) and isinstance(getattr(_kernels, name), int):
            # a '#:' comment directly above the assignment (or above a group of assignments)
            lines = source.splitlines()
            at = next(i for i, ln in enumerate(lines) if ln.startswith(f"{name} = "))
            above = at - 1
            while lines[above].split(" = ")[0].isupper() and " = " in lines[above]:
                above -= 1
            assert lines[above].startswith("#:"), f"{name} has no reason above it"


def test_the_check_sees_a_chunk_literal(tmp_path):
    # The scan's power: a module defining its own chunk size is found.
    p = tmp_path / "m.py"
    p.write_text("CHUNK = 1 << 15\n_PHI_CHUNK = PHI_CHUNK\nX = 3\n", encoding="utf-8")
    assert list(_chunk_literals(p)) == [("CHUNK", 1)]
