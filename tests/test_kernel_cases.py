"""Every ``@njit`` kernel of ``flightsw`` and ``hil_harness`` lists the cases it handles, and a test
names each case it reaches (issue 22, Build 7). Coverage cannot see inside compiled bodies, so the
case lists are how a reader knows what a kernel was checked for.

Convention (numpydoc-style section in the kernel's docstring)::

    Cases
    -----
    saturate-high : a sum above 32767 saturates to 32767 (AV set).
    round-tie : exactly half an LSB rounds towards +inf.

A case id is lowercase letters, digits and hyphens; the description may run over several indented
lines. A test names the cases it reaches with the ``cases`` marker (first argument the kernel's
dotted name, then case ids)::

    @pytest.mark.cases("flightsw.arith.adsp2100.add16", "saturate-high", "round-tie")
    def test_add16_saturates(): ...

The marker may also appear in ``pytest.param(..., marks=...)`` or a module's ``pytestmark``. The
checks below are read from the source with ``ast`` (nothing is imported or compiled).
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("flightsw", "hil_harness")
CASE_ID = re.compile(r"^[a-z0-9][a-z0-9-]*$")
HEADER = re.compile(r"^Cases\s*$")

def _is_kernel_decorator(dec: ast.expr) -> bool:
    node = dec.func if isinstance(dec, ast.Call) else dec
    name = node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")
    return name in ("njit", "callee_kernel")


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def parse_cases(doc: str | None) -> list[str] | None:
    """The case ids of a docstring's ``Cases`` section (None if it has none)."""
    if not doc:
        return None
    lines = [ln.rstrip() for ln in doc.expandtabs().splitlines()]
    for i, ln in enumerate(lines[:-1]):
        if HEADER.match(ln.strip()) and set(lines[i + 1].strip()) == {"-"}:
            break
    else:
        return None
    indent = len(ln) - len(ln.lstrip())
    body = lines[i + 2:]
    out = []
    for j, ln in enumerate(body):
        if not ln.strip():
            continue
        ind = len(ln) - len(ln.lstrip())
        if ind < indent:
            break
        if ind > indent:                          # a description's continuation line
            continue
        nxt = next((b for b in body[j + 1:] if b.strip()), "")
        if set(nxt.strip()) == {"-"}:             # the next section's title
            break
        out.append(ln.strip().partition(" : ")[0].strip())
    return out


def kernels() -> dict[str, tuple[Path, int, list[str] | None]]:
    """{dotted kernel name: (file, line, case ids or None)} of every @njit function."""
    found = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            if "__pycache__" in path.parts:
                continue
            mod = _module_name(path)
            tree = ast.parse(path.read_text(), str(path))
            for node in ast.walk(tree):
                if isinstance(node, ast.FunctionDef) and any(
                        map(_is_kernel_decorator, node.decorator_list)):
                    found[f"{mod}.{node.name}"] = (path, node.lineno,
                                                   parse_cases(ast.get_docstring(node)))
    return found


def named_cases() -> dict[tuple[str, str], list[str]]:
    """{(kernel, case): [test file:line, ...]} of every ``cases`` marker in the tests."""
    named: dict[tuple[str, str], list[str]] = {}
    for path in sorted((ROOT / "tests").rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if not (isinstance(node, ast.Call) and ast.unparse(node.func).endswith("mark.cases")):
                continue
            args = [a.value for a in node.args if isinstance(a, ast.Constant)]
            where = f"{path.relative_to(ROOT)}:{node.lineno}"
            if len(args) != len(node.args) or len(args) < 2 or not all(isinstance(a, str)
                                                                        for a in args):
                raise AssertionError(f"{where}: cases marker needs a kernel name and case ids "
                                     "as string literals")
            for case in args[1:]:
                named.setdefault((args[0], case), []).append(where)
    return named


KERNELS = kernels()
NAMED = named_cases()


def test_the_scan_finds_the_kernels():
    assert len(KERNELS) > 250
    assert "flightsw.ip.threshold.isqrt32" in KERNELS


def test_parse_cases_reads_a_hand_written_section():
    doc = """Add with saturation.

    Parameters
    ----------
    a : int

    Cases
    -----
    saturate-high : above 32767
        clamps to 32767.
    round-tie : half an LSB.

    Notes
    -----
    text
    """
    assert parse_cases(doc) == ["saturate-high", "round-tie"]
    assert parse_cases("no section") is None
    assert parse_cases("Cases\n-----\nBad Name : x\n") == ["Bad Name"]


def test_every_kernel_lists_its_cases():
    missing, bad = [], []
    for name, (path, line, cases) in KERNELS.items():
        where = f"{path.relative_to(ROOT)}:{line} {name}"
        if not cases:
            missing.append(where)
        for c in cases or ():
            if not CASE_ID.match(c):
                bad.append(f"{where}: case id {c!r} (lowercase, digits, hyphens)")
    assert not missing, "kernels without a Cases section:\n" + "\n".join(missing)
    assert not bad, "\n".join(bad)


def test_every_case_is_named_by_a_test():
    unnamed = [f"{name}: {c}" for name, (_, _, cases) in KERNELS.items()
               for c in cases or ()
               if (name, c) not in NAMED]
    assert not unnamed, "cases no test names (add @pytest.mark.cases):\n" + "\n".join(unnamed)


def test_every_marker_names_a_listed_case():
    stale = []
    for (name, case), where in NAMED.items():
        if name not in KERNELS:
            stale.append(f"{where[0]}: no @njit kernel {name}")
        elif case not in (KERNELS[name][2] or ()):
            stale.append(f"{where[0]}: {name} lists no case {case!r}")
    assert not stale, "\n".join(stale)
