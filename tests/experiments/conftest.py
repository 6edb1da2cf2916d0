"""The mutation check of the paper comparisons: each must fail when our number is wrong.

A test that compares a reproduced number with a seed's asks for the ``scaled`` fixture
and passes every reproduced number it checks through it (``ours = scaled(value)``). Each
such test then runs three times:

* ``as-is``: ``scaled`` is the identity, the real check;
* ``x1.5`` and ``x0.5``: ``scaled`` multiplies by 1.5 or 0.5, and the test is a strict
  expected failure that must raise ``AssertionError``. A check that still passes with
  our number half or one and a half times what it is cannot tell a right result from a
  wrong one, and the suite goes red (XPASS, strict).

A check whose claim is one-sided by nature (the seed says "at least five-fold") declares
which mutation can break it: ``@pytest.mark.mutate(only=0.5, reason="...")``. Tests
that are themselves expected failures (the paper's number missed) are not mutated: their
``raises=AssertionError`` already makes them real. ``tests/experiments/test_mutation.py``
fails when a test that uses a seed's ``paper`` numbers neither asks for ``scaled`` nor
stands in its list of exceptions with a reason.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

#: The factors each paper comparison runs under (1.0: the real check).
MUTATIONS = {"as-is": 1.0, "x1.5": 1.5, "x0.5": 0.5}


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "mutate(only, reason): a one-sided paper check; only this mutation factor can break it",
    )


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "scaled" not in metafunc.fixturenames:
        return
    mark = metafunc.definition.get_closest_marker("mutate")
    only = None if mark is None else mark.kwargs["only"]
    if mark is not None and not mark.kwargs.get("reason"):
        raise pytest.UsageError(f"{metafunc.definition.nodeid}: mutate(...) needs a reason")
    params = []
    for name, factor in MUTATIONS.items():
        if factor == 1.0:
            params.append(pytest.param(factor, id=name))
        elif only is None or factor == only:
            why = f"mutation: our number x{factor:g} must fail the paper check"
            xfail = pytest.mark.xfail(raises=AssertionError, strict=True, reason=why)
            params.append(pytest.param(factor, id=name, marks=xfail))
    metafunc.parametrize("scaled", params, indirect=True)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Drop the mutations of a test that is itself an expected failure (see the docstring)."""
    keep, drop = [], []
    for item in items:
        callspec = getattr(item, "callspec", None)
        factor = None if callspec is None else callspec.params.get("scaled")
        if factor is not None and factor != 1.0 and len(list(item.iter_markers("xfail"))) > 1:
            drop.append(item)
        else:
            keep.append(item)
    if drop:
        config.hook.pytest_deselected(items=drop)
        items[:] = keep


@pytest.fixture
def scaled(request: pytest.FixtureRequest) -> Callable[[Any], Any]:
    """Our reproduced number as is, or mutated ×1.5 / ×0.5 (module docstring)."""
    factor = float(request.param)

    def scale(value: Any) -> Any:
        if isinstance(value, dict):
            return {k: scale(v) for k, v in value.items()}
        if isinstance(value, list | tuple):
            return type(value)(scale(v) for v in value)
        if value is None:
            return None
        if isinstance(value, np.ndarray):
            return value * factor
        return float(value) * factor

    scale.factor = factor  # type: ignore[attr-defined]
    return scale
