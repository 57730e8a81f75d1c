"""The named-state measures of issue 40, counted on the source with ``ast``; run
``python tests/code_measures.py`` from the repository root to print them.

* ``slot_constants``: module-level integer constants in ``flightsw/tp`` whose names carry a slot
  prefix (``S_ C_ G_ V_ E_ K_ F_ D_ X_ O_ W_ GP_ IMG_ ATT_``).
* ``slot_subscripts``: subscripts in ``flightsw/tp`` whose index names an upper-case constant with
  an underscore (``G[rs, G_MISS]``, ``S[S_NRULE + k]``, ``L.C_MODE``).
* ``literal_positions``: integer literals used as positions into ``pack``, ``info``, ``prm``,
  ``ctl``, ``geo``, ``ops``, ``head``, ``raw``, ``wk`` in ``flightsw/ip``.
* ``wide_functions``: functions in ``flightsw`` taking 10 or more parameters (``self`` counted).
"""
from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SLOT_PREFIX = re.compile(r"^(S|C|G|V|E|K|F|D|X|O|W|GP|IMG|ATT)_[A-Z0-9_]+$")
CONSTANT_NAME = re.compile(r"^[A-Z][A-Z0-9]*_[A-Z0-9_]+$")
PACKS = {"pack", "info", "prm", "ctl", "geo", "ops", "head", "raw", "wk"}
WIDE = 10


def _files(sub: str) -> list[Path]:
    return [p for p in sorted((ROOT / sub).rglob("*.py")) if "__pycache__" not in p.parts]


def _trees(sub: str):
    for p in _files(sub):
        yield p, ast.parse(p.read_text(), str(p))


def _int_value(node) -> bool:
    if isinstance(node, ast.Constant):
        return isinstance(node.value, int) and not isinstance(node.value, bool)
    if isinstance(node, (ast.Tuple, ast.List)):
        return bool(node.elts) and all(_int_value(e) for e in node.elts)
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "range":
        return True
    if isinstance(node, ast.BinOp):
        return _int_value(node.left) or _int_value(node.right) or isinstance(node.left, ast.Name)
    return isinstance(node, ast.Name) and CONSTANT_NAME.match(node.id) is not None


def slot_constants(sub: str = "flightsw/tp") -> list[str]:
    """Module-level names with a slot prefix bound to integers -> ``path:name`` list."""
    out = []
    for p, tree in _trees(sub):
        for node in tree.body:
            if not isinstance(node, (ast.Assign, ast.AnnAssign)):
                continue
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if node.value is None or not _int_value(node.value):
                continue
            for t in targets:
                for n in ([t] if isinstance(t, ast.Name) else getattr(t, "elts", [])):
                    if isinstance(n, ast.Name) and SLOT_PREFIX.match(n.id):
                        out.append(f"{p.relative_to(ROOT)}:{n.id}")
    return out


def _names_constant(node) -> bool:
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name) and CONSTANT_NAME.match(sub.id):
            return True
        if isinstance(sub, ast.Attribute) and CONSTANT_NAME.match(sub.attr):
            return True
    return False


def slot_subscripts(sub: str = "flightsw/tp") -> list[str]:
    """Subscripts whose index names an upper-case constant -> ``path:line`` list."""
    out = []
    for p, tree in _trees(sub):
        for node in ast.walk(tree):
            if isinstance(node, ast.Subscript) and _names_constant(node.slice):
                out.append(f"{p.relative_to(ROOT)}:{node.lineno}")
    return out


def _literal_index(node) -> bool:
    parts = node.elts if isinstance(node, ast.Tuple) else [node]
    for s in parts:
        if isinstance(s, ast.Slice):
            if any(isinstance(b, ast.Constant) and isinstance(b.value, int) and b.value != 0
                   for b in (s.lower, s.upper)):
                return True
        elif isinstance(s, ast.Constant) and isinstance(s.value, int):
            return True
    return False


def literal_positions(sub: str = "flightsw/ip") -> list[str]:
    """Integer-literal positions into the IP's positional packs -> ``path:line`` list."""
    out = []
    for p, tree in _trees(sub):
        for node in ast.walk(tree):
            if (isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name)
                    and node.value.id in PACKS and _literal_index(node.slice)):
                out.append(f"{p.relative_to(ROOT)}:{node.lineno}")
    return out


def n_params(fn) -> int:
    """Parameters of a function node (``self``, ``*args`` and ``**kw`` counted)."""
    a = fn.args
    return (len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + (a.vararg is not None)
            + (a.kwarg is not None))


def wide_functions(sub: str = "flightsw") -> list[str]:
    """Functions with ``WIDE`` or more parameters -> ``path:name(n)`` list."""
    out = []
    for p, tree in _trees(sub):
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and n_params(node) >= WIDE:
                out.append(f"{p.relative_to(ROOT)}:{node.name}({n_params(node)})")
    return out


MEASURES = {"slot_constants": slot_constants, "slot_subscripts": slot_subscripts,
            "literal_positions": literal_positions, "wide_functions": wide_functions}

if __name__ == "__main__":
    verbose = "-v" in sys.argv
    for name, fn in MEASURES.items():
        found = fn()
        print(f"{name}: {len(found)}")
        if verbose:
            for f in found:
                print("   ", f)
