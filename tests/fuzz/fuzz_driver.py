"""Run fuzz cases through the ``microfab`` command line and classify what happens.

A `Case` is a command line and the files it needs in an empty working folder. `run_case`
runs it in process with typer's ``CliRunner`` inside a fresh temporary folder, hashes
every file in that folder before and after, and returns an `Outcome`:

``refused``
    exit code 2 and the whole output (stdout and stderr) is one line starting with
    ``error:``, and every file in the folder is byte-identical afterwards;
``accepted``
    exit code 0;
``uncaught``
    a Python exception escaped the command (a traceback);
``messy``
    any other exit: exit code 2 with more than one line or without ``error:``, or
    another exit code;
``dirty``
    a clean refusal that changed, created or deleted a file in the working folder;
``hang``
    the case used more than the per-case CPU time (its process and the processes it
    started), or made no progress (used next to no CPU) for as long (`_watch`);
``clobbered``
    whatever the exit, a file the case names in ``keep`` (an input: measured data, a
    drawing, a job file) was changed or deleted — an output that was also an input.

`run_pool` runs many cases in worker processes, so that a case stuck in compiled code
is killed and reported as a hang without stopping the run.

A hang is measured in CPU time, not wall time, so that a loaded machine does not turn
slow cases into hangs (``make fuzz`` counted 3 hangs at 20 s of wall time on a loaded
2-core machine, none on an idle one): a case that computes gets ``TIMEOUT_S`` CPU seconds
however many other processes share the cores, and a case that waits forever (a deadlock,
a dead worker it waits for) is caught by its lack of progress, which load only makes
slower, never zero.
"""

from __future__ import annotations

import atexit
import contextlib
import functools
import hashlib
import multiprocessing as mp
import os
import shutil
import signal
import stat
import sys
import tempfile
import threading
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    "OUTCOMES",
    "Case",
    "Outcome",
    "format_table",
    "run_case",
    "run_pool",
    "tally",
]

#: Every outcome, in table order; those after ``accepted`` are failures.
OUTCOMES = ("refused", "accepted", "uncaught", "hang", "messy", "dirty", "clobbered")
FAILURES = ("uncaught", "hang", "messy", "dirty", "clobbered")
#: CPU seconds a case may use (its process and every process it started) before it is a
#: hang. Assumed: 20, the old wall-time limit, on which every accepted case of an idle
#: machine stays under 10 s.
TIMEOUT_S = 20.0
#: A case that used less than `STALL_CPU_S` CPU seconds over `TIMEOUT_S` seconds of wall
#: time made no progress: a hang. Assumed: 0.05 s, 0.25 % of a core, while a runnable
#: process on a 2-core machine at a load of 20 still gets about 10 %.
STALL_CPU_S = 0.05
#: Seconds between two looks at a case's CPU time (assumed: cheap, and fine against 20 s).
WATCH_EVERY_S = 0.5


@dataclass(frozen=True)
class Case:
    """One fuzz case: a command line run in an empty folder holding ``files``.

    Attributes
    ----------
    kind : str
        The input kind (table row), e.g. ``"dxf"``.
    argv : tuple of str
        Arguments of ``microfab`` (paths relative to the working folder).
    files : tuple of (str, bytes)
        Files written into the working folder first (relative path, content); outputs
        that already exist (a previous reference, an older state) belong here too, so
        that a refusal is seen to leave them alone.
    setup : tuple of str
        Named fixtures copied into the folder (see `FIXTURES`).
    note : str
        What was done to the input, for reports.
    damage : tuple of (str, str)
        After the fixtures and files: (relative path, how) with ``how`` one of `DAMAGE`
        (a state file cut or emptied, an input replaced by a folder...).
    keep : tuple of str
        Relative paths that must be byte-identical after the command whatever its exit
        (inputs: an accepted command that overwrote one is ``clobbered``).
    together : int
        How many processes of the command run at once on the folder (`fuzz_concurrency`);
        1: one, in process.
    """

    kind: str
    argv: tuple[str, ...]
    files: tuple[tuple[str, bytes], ...] = ()
    setup: tuple[str, ...] = ()
    note: str = ""
    damage: tuple[tuple[str, str], ...] = ()
    keep: tuple[str, ...] = ()
    together: int = 1

    def describe(self) -> str:
        """One line: kind, note and command."""
        return f"[{self.kind}] {self.note} :: microfab {' '.join(self.argv)}"


@dataclass(frozen=True)
class Outcome:
    """What one case did."""

    case: Case
    outcome: str
    exit_code: int | None
    seconds: float
    detail: str = ""
    changed: tuple[str, ...] = field(default=())

    @property
    def failed(self) -> bool:
        """True for an uncaught exception, a hang, a messy or a dirty refusal."""
        return self.outcome in FAILURES


class CaseTimeoutError(BaseException):
    """Raised by the alarm in a case that runs too long (not an `Exception`)."""


# ------------------------------------------------------------------------- fixtures
def _ilc_state(dest: Path) -> None:
    """A learning state after one valid trial (``st/``), as ``ilc step`` leaves it."""
    from fuzz_cases import BASE_TRIAL_FILE, base_trial_csv

    from microfab.machines.files import ilc_step

    tpl = _template_dir() / "ilc_state"
    if not tpl.exists():
        work = Path(tempfile.mkdtemp(prefix="state-", dir=_template_dir()))
        (work / BASE_TRIAL_FILE).write_bytes(base_trial_csv(second=False))
        ilc_step(work / BASE_TRIAL_FILE, work / "st", work / "next.csv")
        (work / "st").rename(tpl)
        shutil.rmtree(work)
    shutil.copytree(tpl, dest / "st")


_TEMPLATES: list[tuple[int, Path]] = []


def _template_dir() -> Path:
    if not _TEMPLATES or _TEMPLATES[0][0] != os.getpid():  # one per (forked) process
        tpl = Path(tempfile.mkdtemp(prefix="microfab-fuzz-tpl-"))
        atexit.register(_remove_templates)
        _TEMPLATES[:] = [(os.getpid(), tpl)]
    return _TEMPLATES[0][1]


def _remove_templates() -> None:
    """Remove this process's fixture templates (a forked worker runs no atexit)."""
    if _TEMPLATES and _TEMPLATES[0][0] == os.getpid():
        shutil.rmtree(_TEMPLATES[0][1], ignore_errors=True)
        _TEMPLATES.clear()


#: Named fixtures a `Case` may ask for in ``setup``.
FIXTURES: dict[str, Callable[[Path], None]] = {"ilc_state": _ilc_state}


# ------------------------------------------------------------------------- one case
def _hashes(root: Path) -> dict[str, str]:
    out = {}
    for dirpath, _dirs, files in os.walk(root):
        for f in files:
            p = Path(dirpath) / f
            st = p.lstat()
            if p.is_symlink():  # a loop, or a link a case planted: its target, not opened
                out[str(p.relative_to(root))] = "link:" + os.readlink(p)
            elif not stat.S_ISREG(st.st_mode):  # a FIFO: opening it would block
                out[str(p.relative_to(root))] = f"special:{stat.S_IFMT(st.st_mode)}"
            else:
                out[str(p.relative_to(root))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def cpu_seconds(pid: int | None = None) -> float:
    """CPU seconds (user and system) of a process and of every process it started.

    Live descendants are read one by one (a sweep's workers); those that ended count
    through their parent's children's times once it waited for them.
    """
    import psutil

    proc = psutil.Process(pid)
    t = proc.cpu_times()
    total = t.user + t.system + t.children_user + t.children_system
    for child in proc.children(recursive=True):
        with contextlib.suppress(psutil.Error):
            c = child.cpu_times()
            total += c.user + c.system
    return total


class _Progress:
    """A case's CPU time against `TIMEOUT_S` and `STALL_CPU_S` (module docstring)."""

    def __init__(self, pid: int | None, cpu_s: float, stall_s: float) -> None:
        self.pid, self.cpu_s, self.stall_s = pid, cpu_s, stall_s
        self.start = self.last = cpu_seconds(pid)
        self.since = time.monotonic()

    def hang(self) -> str | None:
        """Why the case is a hang now (``"over N s of CPU"``, ``"no progress ..."``), or None."""
        now, cpu = time.monotonic(), cpu_seconds(self.pid)
        if cpu - self.start > self.cpu_s:
            return f"over {self.cpu_s:g} s of CPU"
        if cpu - self.last >= STALL_CPU_S:
            self.last, self.since = cpu, now
        elif now - self.since > self.stall_s:
            return f"no progress: under {STALL_CPU_S:g} s of CPU in {self.stall_s:g} s"
        return None


@contextlib.contextmanager
def _alarm(seconds: float) -> Iterator[None]:
    """Raise `CaseTimeoutError` in this thread once the block hangs (`_Progress`).

    A watcher thread looks every `WATCH_EVERY_S` and sends SIGALRM to this thread, whose
    handler raises; compiled code that never returns to Python is left to `run_pool`.
    """
    why: list[str] = []
    stop = threading.Event()
    main = threading.get_ident()

    def on_alarm(signum: int, frame: Any) -> None:
        if why and not stop.is_set():
            raise CaseTimeoutError(why[0])

    def watch() -> None:
        progress = _Progress(None, seconds, seconds)
        while not stop.wait(WATCH_EVERY_S):
            reason = progress.hang()
            if reason is not None:
                why.append(reason)
                signal.pthread_kill(main, signal.SIGALRM)
                return

    old = signal.signal(signal.SIGALRM, on_alarm)
    watcher = threading.Thread(target=watch, name="fuzz-watch", daemon=True)
    watcher.start()
    try:
        yield
    finally:
        stop.set()
        watcher.join()
        signal.signal(signal.SIGALRM, old)


@contextlib.contextmanager
def _in_folder(path: Path) -> Iterator[None]:
    old = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


def _damage(path: Path, how: str) -> None:
    """Damage one file (or every file under a folder) of the working folder."""
    if how in ("fifo", "loop"):  # a special file where the input or output was
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif path.exists() or path.is_symlink():
            path.unlink()
        path.parent.mkdir(parents=True, exist_ok=True)
        if how == "fifo":
            os.mkfifo(path)
        else:
            path.symlink_to(path.name)
        return
    if path.is_dir() and how not in ("remove", "file"):
        for f in sorted(q for q in path.rglob("*") if q.is_file()):
            _damage(f, how)
        return
    data = path.read_bytes() if path.is_file() else b""
    if how == "empty":
        path.write_bytes(b"")
    elif how == "half":
        path.write_bytes(data[: len(data) // 2])
    elif how == "junk":
        path.write_bytes(bytes(range(256)) * 4)
    elif how == "remove":
        shutil.rmtree(path) if path.is_dir() else path.unlink(missing_ok=True)
    elif how == "folder":  # a folder where a file was
        path.unlink(missing_ok=True)
        path.mkdir(parents=True, exist_ok=True)
    elif how == "file":  # a file where a folder (or file) was
        shutil.rmtree(path) if path.is_dir() else path.unlink(missing_ok=True)
        path.write_bytes(b"not a folder\n")
    else:
        raise ValueError(f"unknown damage {how!r}; known: {', '.join(DAMAGE)}")


#: The ways `Case.damage` can damage an input.
DAMAGE = ("empty", "half", "junk", "remove", "folder", "file", "fifo", "loop")


def _prepare(case: Case, work: Path) -> None:
    for name in case.setup:
        FIXTURES[name](work)
    for rel, content in case.files:
        p = work / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(content)
    for rel, how in case.damage:
        _damage(work / rel, how)


def _kept(case: Case, work: Path, before: dict[str, str]) -> tuple[str, ...]:
    """The ``keep`` files that are no longer as they were."""
    after = _hashes(work)
    lost = []
    for rel in case.keep:
        names = [k for k in before if k == rel or k.startswith(rel.rstrip("/") + "/")]
        lost += [k for k in names if after.get(k) != before[k]]
    return tuple(sorted(lost))


def classify(exit_code: int | None, output: str, exception: BaseException | None) -> str:
    """``refused``, ``accepted``, ``uncaught`` or ``messy`` for one finished command."""
    if exception is not None and not isinstance(exception, SystemExit):
        return "uncaught"
    if exit_code == 0:
        return "accepted"
    lines = [ln for ln in output.splitlines() if ln.strip()]
    if exit_code == 2 and len(lines) == 1 and lines[0].startswith("error:"):
        return "refused"
    return "messy"


@functools.cache
def _command() -> Any:
    """The ``microfab`` click command, built once (typer rebuilds it on every invoke)."""
    import typer.main

    from microfab.cli import app

    return typer.main.get_command(app)


def invoke(argv: Sequence[str]) -> tuple[int, str, BaseException | None]:
    """Run ``microfab argv`` in process as typer's CliRunner does.

    Returns
    -------
    exit_code : int
    output : str
        stdout and stderr, interleaved as a terminal shows them.
    exception : BaseException or None
        An exception that escaped the command (not ``SystemExit``).
    """
    from typer.testing import CliRunner

    exc: BaseException | None = None
    with CliRunner().isolation(env={"COLUMNS": "100"}) as streams:
        try:
            _command().main(args=list(argv), prog_name="microfab")
            code = 0
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
        except Exception as e:
            exc, code = e, 1
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            output = streams[2].getvalue().decode("utf-8", "replace")
    return code, output, exc


def run_case(case: Case, timeout_s: float = TIMEOUT_S) -> Outcome:
    """Run one case in process in a fresh temporary folder and classify it."""
    with tempfile.TemporaryDirectory(prefix="microfab-fuzz-") as tmp:
        work = Path(tmp)
        _prepare(case, work)
        before = _hashes(work)
        if case.together > 1:
            from fuzz_concurrency import run_together

            return run_together(case, work, before)
        t0 = time.perf_counter()
        try:
            with _in_folder(work), _alarm(timeout_s):
                code, output, exc = invoke(case.argv)
        except CaseTimeoutError as exc:
            return Outcome(case, "hang", None, time.perf_counter() - t0, str(exc))
        seconds = time.perf_counter() - t0
        outcome = classify(code, output, exc)
        if outcome == "uncaught":
            assert exc is not None
            tb = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
            last = f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:300]
            return Outcome(case, outcome, code, seconds, f"{last}\n{tb}")
        changed: tuple[str, ...] = ()
        lost = _kept(case, work, before) if case.keep else ()
        if lost:
            detail = " | ".join(ln for ln in output.splitlines() if ln.strip())[:500]
            return Outcome(case, "clobbered", code, seconds, detail, lost)
        if outcome == "refused":
            after = _hashes(work)
            changed = tuple(
                sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k))
            )
            if changed:
                outcome = "dirty"
        detail = " | ".join(ln for ln in output.splitlines() if ln.strip())[:500]
        return Outcome(case, outcome, code, seconds, detail, changed)


# ------------------------------------------------------------------------- many cases
def _worker(conn: Any, timeout_s: float) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        while True:
            case = conn.recv()
            if case is None:
                return
            try:
                out = run_case(case, timeout_s)
            except Exception as exc:  # the driver itself failed: report it as uncaught
                out = Outcome(case, "uncaught", None, 0.0, f"driver: {exc!r}")
            conn.send(out)
    finally:
        _remove_templates()


@dataclass
class _Slot:
    proc: Any
    conn: Any
    case: Case | None = None
    started: float = 0.0


def run_pool(
    cases: Sequence[Case],
    *,
    workers: int = 2,
    timeout_s: float = TIMEOUT_S,
    on_result: Callable[[Outcome], None] | None = None,
) -> list[Outcome]:
    """Run cases in ``workers`` processes; a case that hangs (`_Progress`) is a hang.

    A worker whose case does not return although it hangs by ``timeout_s`` plus a grace
    period (stuck in compiled code, where the in-process alarm cannot reach) is killed
    and replaced; its CPU time is read from here.
    """
    ctx = mp.get_context("fork")
    grace = 10.0
    watch: dict[int, tuple[_Progress, float]] = {}  # slot: its case's progress, next look

    def start() -> _Slot:
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=_worker, args=(child, timeout_s), daemon=True)
        proc.start()
        child.close()
        return _Slot(proc, parent)

    todo = list(reversed(cases))
    slots = [start() for _ in range(max(1, min(workers, len(cases))))]
    results: list[Outcome] = []

    def done(out: Outcome) -> None:
        results.append(out)
        if on_result is not None:
            on_result(out)

    try:
        while todo or any(s.case is not None for s in slots):
            for i, s in enumerate(slots):
                if s.case is None and todo:
                    s.case, s.started = todo.pop(), time.monotonic()
                    s.conn.send(s.case)
                    # a `together` case runs its command `together` times at once, once
                    # more alone after, and once alone to learn what it leaves: each run
                    # gets the budget of one case
                    runs = 1 if s.case.together <= 1 else s.case.together + 2
                    budget = timeout_s * runs + grace
                    watch[i] = (_Progress(s.proc.pid, budget, budget),
                                s.started + WATCH_EVERY_S)  # fmt: skip
                if s.case is None:
                    continue
                if s.conn.poll(0.005):
                    try:
                        out = s.conn.recv()
                    except EOFError:  # the worker died (e.g. killed for memory)
                        out = Outcome(s.case, "uncaught", None, 0.0, "worker process died")
                        s.proc.join(1)
                        slots[i] = start()
                    else:
                        s.case = None
                    done(out)
                    continue
                why = None
                progress, due = watch[i]
                if s.proc.is_alive() and time.monotonic() >= due:
                    with contextlib.suppress(Exception):  # the worker just ended: next round
                        why = progress.hang()
                    watch[i] = (progress, time.monotonic() + WATCH_EVERY_S)
                if not s.proc.is_alive() or why is not None:
                    alive = s.proc.is_alive()
                    s.proc.kill()
                    s.proc.join(5)
                    detail = f"{why} (killed)" if alive else "worker died"
                    kind = "hang" if alive else "uncaught"
                    done(Outcome(s.case, kind, None, time.monotonic() - s.started, detail))
                    slots[i] = start()
    finally:
        for s in slots:
            with contextlib.suppress(OSError, BrokenPipeError):
                s.conn.send(None)
        for s in slots:
            s.proc.join(5)
            if s.proc.is_alive():
                s.proc.kill()
    return results


# ------------------------------------------------------------------------- the table
def tally(results: Sequence[Outcome]) -> dict[str, Counter[str]]:
    """Counts of each outcome per kind, and in ``"total"``."""
    table: dict[str, Counter[str]] = {}
    for r in results:
        table.setdefault(r.case.kind, Counter())[r.outcome] += 1
    total: Counter[str] = Counter()
    for c in table.values():
        total.update(c)
    table["total"] = total
    return table


def format_table(results: Sequence[Outcome]) -> str:
    """The fuzz table: per kind and total, cases and each outcome."""
    heads = (
        "kind",
        "cases",
        "clean refusals",
        "accepted",
        "uncaught",
        f"hangs >{TIMEOUT_S:g} s CPU",
        "messy refusals",
        "refusals that changed files",
        "inputs overwritten",
    )
    keys = ("refused", "accepted", "uncaught", "hang", "messy", "dirty", "clobbered")
    rows = [
        (kind, str(sum(c.values())), *(str(c[k]) for k in keys))
        for kind, c in tally(results).items()
    ]
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(heads)]
    fmt = lambda r: "  ".join(  # noqa: E731
        v.ljust(w) if i == 0 else v.rjust(w) for i, (v, w) in enumerate(zip(r, widths, strict=True))
    )
    sep = "  ".join("-" * w for w in widths)
    return "\n".join([fmt(heads), sep, *(fmt(r) for r in rows[:-1]), sep, fmt(rows[-1])])
