"""`BackgroundWriter`: write checkpoints on a worker thread while the caller computes.

A resumable job saves its state every chunk, atomically and durably (`microfab.io.atomic`:
write, ``fsync``, rename, ``fsync`` of the folder). That costs milliseconds a file, as
much as simulating a chunk on a fast loop. Handing each save to one worker thread lets the
two overlap: the compiled loops release the GIL, and ``fsync`` and zlib's CRC do too.

Guarantees (what "nothing is lost" needs):

* saves run one at a time, in the order submitted, each atomic as before;
* `close` (or leaving the ``with`` block, also on an exception or ``KeyboardInterrupt``)
  waits for every submitted save, so an interrupted job finds on disk everything it had
  submitted, and resumes after it;
* the first error of a save is raised in the caller, at the next `submit` or at `close`;
  the saves after it are not run (a later checkpoint must not exist without an earlier
  one);
* at most ``max_pending`` saves wait at once: `submit` blocks beyond that, so memory stays
  bounded when the disk is slower than the loop.

The arrays handed to a save must not be changed by the caller afterwards (give copies
or arrays the caller no longer writes).
"""

from __future__ import annotations

import collections
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from types import TracebackType
from typing import Any, Self

from microfab.core.validate import check_int

__all__ = ["BackgroundWriter"]


class BackgroundWriter:
    """Runs save functions on one worker thread, in order (module notes).

    Parameters
    ----------
    max_pending : int
        Saves that may wait at once (>= 1); `submit` blocks beyond it.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from microfab.io.atomic import atomic_write_text
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> with BackgroundWriter() as writer:
    ...     for i in range(3):
    ...         writer.submit(atomic_write_text, folder / f"{i}.txt", str(i))
    >>> sorted(p.read_text() for p in folder.iterdir())
    ['0', '1', '2']
    """

    def __init__(self, max_pending: int = 4) -> None:
        self.max_pending = check_int("max_pending", max_pending, 1, "saves")
        self._pool: ThreadPoolExecutor | None = ThreadPoolExecutor(
            max_workers=1, thread_name_prefix="microfab-writer"
        )
        self._pending: collections.deque[Future[None]] = collections.deque()
        self._failed: BaseException | None = None  # first failure, seen by the caller
        self._stopped = False  # set by the worker when a save fails

    def _reap(self, keep: int) -> None:
        """Wait until at most ``keep`` saves are pending; raise the first failure."""
        while self._pending and (len(self._pending) > keep or self._pending[0].done()):
            fut = self._pending.popleft()
            exc = fut.exception()
            if exc is not None and self._failed is None:
                self._failed = exc
        if self._failed is not None:
            raise self._failed

    def submit(self, fn: Callable[..., None], /, *args: Any, **kwargs: Any) -> None:
        """Queue ``fn(*args, **kwargs)`` after the saves already queued.

        Raises
        ------
        RuntimeError
            After `close`.
        Exception
            The error of an earlier save (this one is then not queued).
        """
        if self._pool is None:
            raise RuntimeError("this BackgroundWriter is closed; make a new one")
        self._reap(self.max_pending - 1)

        def run() -> None:
            if self._stopped:  # skip the saves after a failed one
                return
            try:
                fn(*args, **kwargs)
            except BaseException:
                self._stopped = True
                raise

        self._pending.append(self._pool.submit(run))

    def close(self) -> None:
        """Wait for every queued save, stop the thread; raise the first save error."""
        if self._pool is None:
            return
        try:
            self._reap(0)
        finally:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc is None:
            self.close()
            return
        try:
            self.close()  # the saves queued before the error still land
        except Exception as save_error:  # the body's error wins; keep the other in the note
            exc.add_note(f"a background save failed as well: {save_error!r}")
