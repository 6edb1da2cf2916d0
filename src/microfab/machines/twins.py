"""A twin built once per distinct configuration: the cache every machine module uses.

A twin is immutable configuration (its state lives in the simulator's arrays), so one
object serves every run, study and report of a process that asks for the same data file
and settings. `TwinCache` joins a loader ``load(path) -> params`` and a factory
``build(params, **settings) -> twin``: the key is
the data file (resolved path, modification time and size, so a calibration that rewrites
the file is read again) and the settings; the file is parsed once per version and the twin
built once per distinct settings.

Example::

    stage = TwinCache(load_params, build_stage, "lmw_stage.toml")
    a = stage(ideal=False)          # parsed and built
    b = stage(ideal=False)          # the same object
    c = stage(ideal=True)           # another configuration: built, not parsed, again
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Hashable
from importlib import resources
from pathlib import Path
from typing import Any, Generic, TypeVar

__all__ = ["TwinCache", "data_path"]

P = TypeVar("P")
T = TypeVar("T")


def data_path(name: str) -> Path:
    """The packaged data file ``microfab/data/<name>``."""
    return Path(str(resources.files("microfab.data").joinpath(name)))


def _file_key(path: str | os.PathLike[str]) -> tuple[str, int, int]:
    p = Path(path).resolve()
    try:
        st = p.stat()
    except OSError:  # the factory says what is wrong with it
        return (str(p), -1, -1)
    return (str(p), st.st_mtime_ns, st.st_size)


def _hashable(value: Any) -> Hashable:
    if isinstance(value, dict):
        return tuple(sorted((k, _hashable(v)) for k, v in value.items()))
    if isinstance(value, list | tuple):
        return tuple(_hashable(v) for v in value)
    hash(value)  # a TypeError names what cannot key the cache
    return value


class TwinCache(Generic[P, T]):
    """Parse a data file once per version, build a twin once per distinct settings.

    Parameters
    ----------
    load : callable
        ``load(path) -> params``: the data file's validated parameters (``path`` ``None``:
        the packaged default).
    build : callable
        ``build(params, **settings) -> twin``.
    default_file : str
        The packaged data file's name, under ``microfab/data`` (its content keys the cache
        when no ``path`` is given).

    Notes
    -----
    Settings are keys: give them all explicitly (the machine modules' functions do), so
    that a default left out and the same value given name one configuration.
    """

    def __init__(
        self, load: Callable[[Any], P], build: Callable[..., T], default_file: str
    ) -> None:
        self._load = load
        self._build = build
        self.default_file = default_file
        self._params: dict[Hashable, P] = {}
        self._twins: dict[Hashable, T] = {}
        self._lock = threading.Lock()
        #: Data files parsed and twins built by this cache (a test counts them).
        self.parses = 0
        self.builds = 0

    def params(self, path: str | os.PathLike[str] | None = None) -> P:
        """The parameters of ``path`` (default: the packaged file), parsed once per version."""
        key = (_file_key(data_path(self.default_file) if path is None else path), path is None)
        with self._lock:
            return self._params_locked(key, path)

    def _params_locked(self, key: Hashable, path: str | os.PathLike[str] | None) -> P:
        if key not in self._params:
            self._params[key] = self._load(path)
            self.parses += 1
        return self._params[key]

    def __call__(self, path: str | os.PathLike[str] | None = None, **settings: Any) -> T:
        """The twin of ``path`` (default: the packaged file) and ``settings``.

        Raises
        ------
        Whatever the loader or the factory raises for a bad file or setting (nothing is
        cached then).
        """
        fkey = (_file_key(data_path(self.default_file) if path is None else path), path is None)
        key = (fkey, _hashable(settings))
        with self._lock:
            twin = self._twins.get(key)
            if twin is None:
                twin = self._build(self._params_locked(fkey, path), **settings)
                self._twins[key] = twin
                self.builds += 1
            return twin

    def clear(self) -> None:
        """Forget every parse and twin (the next request reads and builds again)."""
        with self._lock:
            self._params.clear()
            self._twins.clear()
