"""One-change mutants of a Python module, generated from its syntax tree.

Each mutant changes one operator, one constant or one name inside a function body:
the changes a slip of the hand makes (``<`` for ``<=``, ``&`` for ``|``, a dropped
``-`` or ``~``, ``n`` for ``n + 1`` or ``n - 1``, ``floor`` for ``ceil``, ``any`` for
``all``), and the slips a one-token swap rarely writes: a slice bound one off
(``x[a:b]`` -> ``x[a:b + 1]``), a float constant doubled or halved, a guard skipped or
always taken (``if bad: return``/``raise`` -> ``if False``, ``if True`` for a return:
an early return), a flag ignored or inverted (``if flag`` -> ``if not flag``), a call
whose result is unused dropped (a check skipped), NaN handling changed
(``isfinite(x)`` -> ``~isnan(x)``, ``nanmax`` -> ``max``, ``fmax`` -> ``maximum``,
``nan_to_num`` dropped), float64 narrowed to float32, ``max`` -> ``mean``, and the two
branches of ``where(c, a, b)`` swapped.
Strings, docstrings, annotations, decorators, default values and module-level code
are not mutated: they are messages, types and settings, not the computation.

A mutant's id names the file, the function, the change and its text, and the
occurrence of that same change in that function (``#0``, ``#1``, ...): it survives
edits elsewhere in the file, so a reason kept beside it (the equivalents file) stays
attached to the same mutant while the code around it moves.
"""

from __future__ import annotations

import ast
import copy
from dataclasses import dataclass

__all__ = ["Mutant", "mutants_of", "mutated_code"]

_CMP = {ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt, ast.Eq: ast.NotEq,
        ast.NotEq: ast.Eq, ast.Is: ast.IsNot, ast.IsNot: ast.Is, ast.In: ast.NotIn, ast.NotIn: ast.In}
_BIN = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult, ast.FloorDiv: ast.Mult,
        ast.Mod: ast.FloorDiv, ast.Pow: ast.Mult, ast.BitAnd: ast.BitOr, ast.BitOr: ast.BitAnd,
        ast.BitXor: ast.BitOr, ast.LShift: ast.RShift, ast.RShift: ast.LShift}
_BOOL = {ast.And: ast.Or, ast.Or: ast.And}
# Names (plain or attributes, ``np.floor``, ``x.any``) whose partner is the likely slip.
_SWAP = {"min": "max", "max": "min", "minimum": "maximum", "maximum": "minimum", "amin": "amax",
         "amax": "amin", "argmin": "argmax", "argmax": "argmin", "floor": "ceil", "ceil": "floor",
         "any": "all", "all": "any", "nanmin": "nanmax", "nanmax": "nanmin", "isinf": "isnan",
         "isnan": "isinf", "float32": "float64", "float64": "float32", "nonzero": "flatnonzero"}
_DROP_CALL = {"abs", "fabs", "round", "rint", "copysign", "nan_to_num"}
# A second partner for some names: NaN handling dropped, a maximum averaged.
_SWAP2 = {"nanmax": "max", "nanmin": "min", "fmax": "maximum", "fmin": "minimum", "nanmean": "mean",
          "nansum": "sum", "max": "mean", "amax": "mean"}
_STOPS = (ast.Return, ast.Raise, ast.Continue, ast.Break)


@dataclass(frozen=True)
class Mutant:
    """One mutant: its stable ``id``, where it is and what it changes.

    ``path``, ``function`` (qualified name), ``top`` (the outermost function around it:
    the one whose code is swapped), ``lines`` (first and last line of the statement it
    changes, the header of a compound one), ``before`` and ``after`` (the changed
    expression's text).
    """

    id: str
    path: str
    function: str
    top: str
    lines: tuple
    before: str
    after: str
    index: int  # position of the changed node in ast.walk order (with ``change``, how to redo it)
    change: tuple


def _text(node):
    try:
        return ast.unparse(node)
    except Exception:  # pragma: no cover - unparse covers every node a module can parse to
        return type(node).__name__


def _changes(node):
    """The changes one slip can make to ``node``: ``("cmp", j)``, ``("op",)``, ``("const",)``, ..."""
    if isinstance(node, ast.Compare):
        return [("cmp", j) for j, op in enumerate(node.ops) if type(op) in _CMP]
    if isinstance(node, (ast.BinOp, ast.AugAssign)) and type(node.op) in _BIN or isinstance(node, ast.BoolOp):
        return [("op",)]
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.Not, ast.Invert)):
        return [("unwrap", "operand")]
    if isinstance(node, ast.Constant) and type(node.value) in (bool, int, float):
        if isinstance(node.value, bool):
            return [("const",)]
        if isinstance(node.value, int):  # one off either way
            return [("const",), ("const", -1)]
        return [("const",)] + ([("const", 0.5)] if node.value != 0.0 else [])  # doubled, halved
    if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load):
        return [("name", t) for t in (_SWAP, _SWAP2) if node.id in t]
    if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Load):
        return [("attr", t) for t in (_SWAP, _SWAP2) if node.attr in t]
    if isinstance(node, ast.Call):
        return _call_changes(node)
    if isinstance(node, ast.Slice):  # a bound one off (a constant bound is a constant's change)
        return [("slice", f, d) for f in ("lower", "upper") if getattr(node, f) is not None
                and not isinstance(getattr(node, f), ast.Constant) for d in (1, -1)]
    if isinstance(node, ast.If) and node.body and isinstance(node.body[-1], _STOPS):
        # a guard skipped; a return always taken (an early return)
        return [("test", False)] + ([("test", True)] if isinstance(node.body[-1], ast.Return) else [])
    if isinstance(node, (ast.If, ast.IfExp, ast.While)) and isinstance(node.test, (ast.Name, ast.Attribute)):
        return [("flag",)]  # a flag inverted
    if isinstance(node, ast.Expr) and isinstance(node.value, ast.Call):
        return [("drop",)]  # a call for its effect (a check) dropped
    return []


def _call_changes(node):
    out = []
    name = _called(node)
    if node.args and not node.keywords and name in _DROP_CALL:
        out.append(("unwrap", "arg0"))
    if name == "isfinite" and len(node.args) == 1:  # finiteness reduced to NaN
        out.append(("nan",))
    if name == "where" and len(node.args) == 3:
        out.append(("swap",))
    return out


def _called(call):
    f = call.func
    return f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else None


def _new_const(v, factor=None):
    if isinstance(v, bool):
        return not v
    if isinstance(v, int):
        return v + (1 if factor is None else factor)
    if factor is not None:
        return v * factor
    return 1.0 if v == 0.0 else 2.0 * v


def _apply(node, change, parent):
    """Apply ``change`` to ``node`` in place (or in ``parent``); returns the node now standing there."""
    kind = change[0]
    if kind == "cmp":
        node.ops[change[1]] = _CMP[type(node.ops[change[1]])]()
    elif kind == "op":
        node.op = (_BOOL if isinstance(node, ast.BoolOp) else _BIN)[type(node.op)]()
    elif kind == "const":
        node.value = _new_const(node.value, *change[1:])
    elif kind == "name":
        node.id = change[1][node.id]
    elif kind == "attr":
        node.attr = change[1][node.attr]
    elif kind == "unwrap":
        inner = node.operand if change[1] == "operand" else node.args[0]
        _replace(parent, node, inner)
        return inner
    elif kind == "slice":
        op = ast.Add() if change[2] > 0 else ast.Sub()
        setattr(node, change[1], ast.BinOp(getattr(node, change[1]), op, ast.Constant(1)))
    elif kind == "test":
        node.test = ast.Constant(change[1])
    elif kind == "flag":
        node.test = ast.UnaryOp(ast.Not(), node.test)
    elif kind == "nan":
        f = node.func
        if isinstance(f, ast.Name):
            f.id = "isnan"
        else:
            f.attr = "isnan"
        new = ast.UnaryOp(ast.Invert(), node)
        _replace(parent, node, new)
        return new
    elif kind == "swap":
        node.args[1], node.args[2] = node.args[2], node.args[1]
    elif kind == "drop":
        new = ast.Pass()
        _replace(parent, node, new)
        return new
    return node


def _replace(parent, old, new):
    for field, value in ast.iter_fields(parent):
        if value is old:
            setattr(parent, field, new)
            return
        if isinstance(value, list):
            for i, v in enumerate(value):
                if v is old:
                    value[i] = new
                    return
    raise AssertionError("child not found in its parent")  # pragma: no cover


def _skipped_children(node):
    """Children that are not computation: docstrings, annotations, decorators, defaults."""
    skip = []
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        skip += node.decorator_list
        if not isinstance(node, ast.ClassDef):
            skip += [node.args, node.returns] if node.returns else [node.args]
    if isinstance(node, (ast.AnnAssign, ast.arg)):
        skip.append(node.annotation)
    if isinstance(node, ast.JoinedStr):  # f-string: a message
        skip += node.values
    return {id(n) for n in skip if n is not None}


def _statement_lines(stmt):
    """Lines of ``stmt`` that run when it does: all of a simple one, the header of a compound one."""
    body = getattr(stmt, "body", None)
    if isinstance(body, list) and body:
        return (stmt.lineno, max(stmt.lineno, body[0].lineno - 1))
    return (stmt.lineno, stmt.end_lineno or stmt.lineno)


def _walk(tree, no_mutate):
    """``(index, node, function, top function, statement lines)`` without the skipped parts."""
    order = {id(n): i for i, n in enumerate(ast.walk(tree))}
    stack = [(tree, None, None, None)]
    out = []
    while stack:
        node, func, top, lines = stack.pop()
        out.append((order[id(node)], node, func, top, lines))
        skip = _skipped_children(node)
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            func = f"{func}.{node.name}" if func else node.name
            if top is None and not isinstance(node, ast.ClassDef):
                top = func
        for child in ast.iter_child_nodes(node):
            if id(child) in skip or (isinstance(child, ast.stmt) and child.lineno in no_mutate):
                continue
            stack.append((child, func, top, _statement_lines(child) if isinstance(child, ast.stmt) else lines))
    return sorted(out, key=lambda t: t[0])


def mutants_of(source, path):
    """Every one-change mutant of ``source`` (the text of file ``path``), in source order."""
    tree = ast.parse(source)
    no_mutate = {i + 1 for i, text in enumerate(source.splitlines()) if "pragma: no mutate" in text}
    seen = {}
    out = []
    for index, node, func, top, lines in _walk(tree, no_mutate):
        if top is None:  # module and class level: settings, tables, imports, fields
            continue
        for change in _changes(node):
            before = _text(node) if not isinstance(node, (ast.If, ast.While)) else ""
            mutated = copy.deepcopy(node)
            holder = ast.Module(body=[ast.Expr(mutated)], type_ignores=[])
            after = _text(_apply(mutated, change, holder.body[0]))
            if change[0] in ("test", "flag"):  # the statement's test, not the whole statement
                before, after = _text(node.test), _text(mutated.test)
            if after == before:
                continue
            key = (func, before, after)
            k = seen.get(key, 0)
            seen[key] = k + 1
            mid = f"{path}::{func}::{before} -> {after}#{k}"
            out.append(Mutant(mid, path, func, top, lines, before, after, index, change))
    return sorted(out, key=lambda m: (m.lines, m.index))


def mutated_code(source, path, mutant):
    """The code object of ``mutant.top`` in ``source`` with ``mutant`` applied (lines as in the file)."""
    tree = ast.parse(source)
    nodes = list(ast.walk(tree))
    node = nodes[mutant.index]
    parent = next(p for p in nodes if any(c is node for c in ast.iter_child_nodes(p)))
    _apply(node, mutant.change, parent)
    ast.fix_missing_locations(tree)
    return _find_code(compile(tree, path, "exec"), mutant.top)


def _find_code(code, qualname):
    for const in code.co_consts:
        if isinstance(const, type(code)):
            if const.co_qualname == qualname:
                return const
            found = _find_code(const, qualname)
            if found is not None:
                return found
    return None
