"""Every expected failure in the suite expects its assertion, and nothing else.

A strict ``xfail`` without ``raises`` "fails as expected" on any exception: a typo, a
missing attribute, an import error. Such a check can never fail (issue 43 found six Table
II cells that raised ``AttributeError`` and counted it as the expected miss). So every
``pytest.mark.xfail`` in ``tests/`` names ``raises=AssertionError`` and ``strict=True``,
and the imperative ``pytest.xfail()`` (which cannot pass) is not used.
"""

from __future__ import annotations

import ast
from pathlib import Path

TESTS = Path(__file__).resolve().parent


def _is_mark_xfail(func: ast.expr) -> bool:
    """``pytest.mark.xfail`` or ``mark.xfail`` (any ``*.mark.xfail`` attribute chain)."""
    return (
        isinstance(func, ast.Attribute)
        and func.attr == "xfail"
        and isinstance(func.value, ast.Attribute)
        and func.value.attr == "mark"
    )


def _is_imperative_xfail(func: ast.expr) -> bool:
    """``pytest.xfail(...)``: marks the test xfailed from inside, whatever happens next."""
    return (
        isinstance(func, ast.Attribute)
        and func.attr == "xfail"
        and isinstance(func.value, ast.Name)
        and func.value.id == "pytest"
    )


def xfail_problems(source: str, name: str) -> list[str]:
    """What is wrong with the expected failures in one test module's ``source``."""
    problems = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and _is_imperative_xfail(node.func):
            problems.append(f"{name}:{node.lineno}: pytest.xfail() cannot fail; assert instead")
            continue
        if not (isinstance(node, ast.Call) and _is_mark_xfail(node.func)):
            continue
        kws = {k.arg: k.value for k in node.keywords}
        raises = kws.get("raises")
        if not (isinstance(raises, ast.Name) and raises.id == "AssertionError"):
            problems.append(f"{name}:{node.lineno}: xfail without raises=AssertionError")
        strict = kws.get("strict")
        if not (isinstance(strict, ast.Constant) and strict.value is True):
            problems.append(f"{name}:{node.lineno}: xfail without strict=True")
    return problems


def _bare_marks(source: str, name: str) -> list[str]:
    """``@pytest.mark.xfail`` used as a decorator without a call (no keywords possible)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            for dec in node.decorator_list:
                if _is_mark_xfail(dec):
                    out.append(f"{name}:{dec.lineno}: bare @xfail without raises=AssertionError")
    return out


def test_every_xfail_in_the_suite_expects_an_assertion_error():
    problems = []
    files = sorted(TESTS.rglob("*.py"))
    assert len(files) > 100  # the whole suite was read, not an empty folder
    for path in files:
        source = path.read_text(encoding="utf-8")
        if "xfail" not in source:
            continue
        name = str(path.relative_to(TESTS.parent))
        if path == Path(__file__).resolve():
            continue  # this module's own examples below are strings
        problems += xfail_problems(source, name) + _bare_marks(source, name)
    assert not problems, "\n".join(problems)


def test_the_check_finds_an_xfail_without_raises():
    bad = (
        "import pytest\n"
        "@pytest.mark.xfail(strict=True, reason='x')\n"
        "def test_a(): pass\n"
        "@pytest.mark.xfail(raises=ValueError, strict=True)\n"
        "def test_b(): pass\n"
        "@pytest.mark.xfail(raises=AssertionError)\n"
        "def test_c(): pass\n"
        "def test_d(): pytest.xfail('no')\n"
        "@pytest.mark.xfail\n"
        "def test_e(): pass\n"
    )
    found = xfail_problems(bad, "m") + _bare_marks(bad, "m")
    assert any(":2: xfail without raises" in p for p in found)
    assert any(":4: xfail without raises" in p for p in found)
    assert any(":6: xfail without strict" in p for p in found)
    assert any(":8: pytest.xfail()" in p for p in found)
    assert any(":9: bare @xfail" in p for p in found)
    good = "import pytest\n@pytest.mark.xfail(raises=AssertionError, strict=True)\ndef t(): 0\n"
    assert xfail_problems(good, "m") == [] and _bare_marks(good, "m") == []
