"""Package data (twin parameters, calibrations, default jobs) and their one reader.

`read_text` is how code reads a packaged data file: a file is read once per content (its
inode, modification time and size), so that a twin's loader and the labels of the tables that
compare the twin with a paper (`microfab.machines.provenance`) share one read, and a file
rewritten by a calibration is read again.
"""

from __future__ import annotations

import threading
from importlib import resources
from pathlib import Path

__all__ = ["read_text"]

_CACHE: dict[str, tuple[tuple[int, int, int], str]] = {}
_LOCK = threading.Lock()


def read_text(name: str) -> str:
    """The text (UTF-8) of the packaged data file ``name`` (e.g. ``"lmw_stage.toml"``).

    Raises
    ------
    FileNotFoundError
        No such file in the package.
    """
    res = resources.files(__name__).joinpath(name)
    if not isinstance(res, Path):  # not a plain folder (e.g. a zip): no cache
        return res.read_text(encoding="utf-8")
    st = res.stat()
    stamp = (st.st_ino, st.st_mtime_ns, st.st_size)  # an atomic rewrite is a new inode
    with _LOCK:
        hit = _CACHE.get(name)
        if hit is not None and hit[0] == stamp:
            return hit[1]
    text = res.read_text(encoding="utf-8")
    with _LOCK:
        _CACHE[name] = (stamp, text)
    return text
