"""Two processes of one command on one folder at once, for every command that writes.

A ``together`` case is a recipe of `fuzz_workspace.RECIPES` run as two real ``microfab``
processes released at the same instant in one workspace (each imports the command line
first and waits, so that they reach the folder within milliseconds). What must hold:

- each process exits 0 or is refused on one ``error:`` line (the folder is held by the
  other, or what the other wrote is refused as stale); none prints a traceback, none
  hangs;
- nothing is left half-written: no temporary file of an atomic write remains (``.name.*``
  beside an output), and no lock is left held;
- what they leave is usable: the same command run once more afterwards, alone, ends
  accepted or cleanly refused (a learning state that two steps wrote at once and that no
  longer loads would end in a traceback or a messy refusal);
- an input of the command is byte-identical afterwards (``keep``).

`run_together` runs one case; `fuzz_driver.run_case` hands it any case with
``together > 1``. ``make fuzz`` runs every case (one per writing command);
``test_fuzz.py`` checks that every writing command has one and runs two of them.
"""

from __future__ import annotations

import functools
import os
import subprocess
import sys
import time
from pathlib import Path

from fuzz_driver import Case, Outcome
from fuzz_workspace import RECIPES
from hypothesis import strategies as st

__all__ = ["TOGETHER_KINDS", "run_together", "together_cases"]

#: A ``microfab`` process that waits for one line on stdin before it runs its command.
STARTER = """
import sys
from microfab.cli import app
print("ready", flush=True)
sys.stdin.readline()
sys.argv[0] = "microfab"
app()
"""
#: How many run at once (two: the issue's "two processes on one folder"; four learning
#: steps at once are in tests/cli/test_concurrency.py).
COPIES = 2
#: Seconds both may take together (assumed: a cold start takes about 7 s on a loaded
#: 2-core machine and every recipe runs in a few seconds alone; 120 s is a hang).
TOGETHER_TIMEOUT_S = 120.0


@functools.cache
def together_cases() -> tuple[Case, ...]:
    """One case per command whose recipe writes something."""
    out = []
    for name, recipe in RECIPES.items():
        if not recipe.outputs:
            continue
        keep = tuple(i for i in recipe.inputs if i not in recipe.outputs)
        out.append(
            Case(
                kind="together",
                argv=recipe.argv,
                setup=("workspace",),
                keep=keep,
                note=f"{name}: {COPIES} at once on {', '.join(recipe.outputs)}",
                together=COPIES,
            )
        )
    return tuple(out)


def _start(argv: tuple[str, ...], cwd: Path) -> subprocess.Popen[str]:
    env = {**os.environ, "COLUMNS": "200", "MICROFAB_THREADS": "1"}
    return subprocess.Popen(
        [sys.executable, "-c", STARTER, *argv],
        cwd=cwd,
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _hidden(work: Path) -> set[str]:
    """Hidden files under ``work`` (where atomic writes keep their temporary files)."""
    return {
        str((Path(d) / f).relative_to(work))
        for d, _dirs, files in os.walk(work)
        for f in files
        if f.startswith(".")
    }


@functools.cache
def _hidden_after_one(argv: tuple[str, ...]) -> frozenset[str]:
    """The hidden files one run alone leaves (locks, run records): those are expected."""
    import tempfile

    from fuzz_driver import _prepare, invoke

    with tempfile.TemporaryDirectory(prefix="microfab-fuzz-one-") as tmp:
        work = Path(tmp)
        _prepare(Case(kind="together", argv=argv, setup=("workspace",)), work)
        old = os.getcwd()
        os.chdir(work)
        try:
            invoke(argv)
        finally:
            os.chdir(old)
        return frozenset(_hidden(work))


def _leftovers(case: Case, work: Path, before: set[str]) -> list[str]:
    """Hidden files the processes left that one run alone does not: temporary files of
    atomic writes that were never renamed into place."""
    expected = _hidden_after_one(case.argv)
    return sorted(_hidden(work) - before - expected)


def run_together(case: Case, work: Path, kept: dict[str, str]) -> Outcome:
    """Run ``case.together`` copies of ``case.argv`` at once in ``work``; classify.

    Parameters
    ----------
    case : Case
        A ``together`` case.
    work : pathlib.Path
        The prepared working folder.
    kept : dict
        Hashes of the folder's files before (`fuzz_driver._hashes`).
    """
    from fuzz_driver import _hashes, classify, invoke

    before = set(kept)
    t0 = time.perf_counter()
    procs = [_start(case.argv, work) for _ in range(case.together)]
    results: list[tuple[int | None, str]] = []
    try:
        for p in procs:
            assert p.stdout is not None
            if p.stdout.readline().strip() != "ready":
                _o, e = p.communicate(timeout=TOGETHER_TIMEOUT_S)
                return Outcome(case, "uncaught", p.returncode, 0.0, f"did not start: {e[-500:]}")
        for p in procs:
            assert p.stdin is not None
            p.stdin.write("go\n")
            p.stdin.flush()
        for p in procs:
            o, e = p.communicate(timeout=TOGETHER_TIMEOUT_S)
            results.append((p.returncode, o + e))
    except subprocess.TimeoutExpired:
        return Outcome(
            case,
            "hang",
            None,
            time.perf_counter() - t0,
            f"{case.together} at once ran past {TOGETHER_TIMEOUT_S:g} s",
        )
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
    seconds = time.perf_counter() - t0
    outcomes = []
    for code, text in results:
        if "Traceback (most recent call last)" in text:
            return Outcome(case, "uncaught", code, seconds, text[-1500:])
        outcomes.append(classify(code, text, None))
    if "messy" in outcomes:
        text = next(t for (c, t), o in zip(results, outcomes, strict=True) if o == "messy")
        return Outcome(case, "messy", None, seconds, text[-800:])
    after = _hashes(work)
    lost = tuple(
        sorted(
            k
            for k in case.keep
            for f in before
            if (f == k or f.startswith(k.rstrip("/") + "/")) and after.get(f) != kept[f]
        )
    )
    if lost:
        return Outcome(case, "clobbered", None, seconds, "an input changed", lost)
    left = _leftovers(case, work, before)
    if left:
        return Outcome(
            case, "dirty", None, seconds, "left half-written: " + ", ".join(left), tuple(left)
        )
    # what they left must be usable: the command once more, alone
    old = os.getcwd()
    os.chdir(work)
    try:
        code, output, exc = invoke(case.argv)
    finally:
        os.chdir(old)
    again = classify(code, output, exc)
    if again not in ("accepted", "refused"):
        why = output if exc is None else f"{type(exc).__name__}: {exc}"
        return Outcome(
            case,
            again,
            code,
            seconds,
            f"the command alone after {case.together} at once: {why[-800:]}",
        )
    summary = "accepted" if "accepted" in outcomes else "refused"
    return Outcome(
        case,
        summary,
        0,
        seconds,
        "; ".join(f"{o} ({c})" for (c, _t), o in zip(results, outcomes, strict=True)),
    )


def _strategy() -> st.SearchStrategy[Case]:
    return st.sampled_from(together_cases())


#: The kind of this module, with its share of ``make fuzz`` (about one case a command).
TOGETHER_KINDS = {"together": (_strategy, 0.003)}
