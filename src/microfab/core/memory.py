"""The C allocator's policy for microfab's processes: keep freed memory for the next array.

A NumPy array above glibc's mmap threshold (128 kB at start, raised dynamically up to
32 MB) is mapped fresh from the kernel and unmapped when freed, and the heap's top is
returned to the kernel whenever more than 128 kB is free there. Optimisation loops that
make and drop the same large temporaries thousands of times (stage 1's IPOPT iterations,
the twins' lifted blocks) then fault every page of every temporary in again: the reference
job (`examples/blackbox_stage_reference.toml`) took 19.7 million minor page faults and
39 s of system time for 221 s of user time (issue 43, measured with ``/usr/bin/time -v``).

`apply_allocator_policy` sets, once per process, through glibc's ``mallopt``:

* ``M_MMAP_THRESHOLD`` = 32 MiB (glibc's largest): arrays below it come from the heap;
* ``M_TRIM_THRESHOLD`` = 256 MiB: freed heap is kept up to that much before it is
  returned (assumed: an eighth of the 2 GB a command may use, `microfab.io.schema`);
* ``M_TOP_PAD`` = 64 MiB: the heap grows in steps of that much.

The same settings go into the environment (``MALLOC_*_``) for the processes microfab
starts. Numbers are unchanged (only where memory comes from); on the reference job the
page faults fell to 11.3 million and the system time to 23 s (10.6 % of user time). On a
C library other than glibc (musl, macOS) nothing is done.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
from typing import Any

__all__ = ["ALLOCATOR_SETTINGS", "apply_allocator_policy"]

_M_TRIM_THRESHOLD = -1  # glibc malloc.h
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3

#: ``mallopt`` parameter, its environment variable and the value set (bytes).
ALLOCATOR_SETTINGS: tuple[tuple[int, str, int], ...] = (
    (_M_MMAP_THRESHOLD, "MALLOC_MMAP_THRESHOLD_", 32 * 2**20),
    (_M_TRIM_THRESHOLD, "MALLOC_TRIM_THRESHOLD_", 256 * 2**20),
    (_M_TOP_PAD, "MALLOC_TOP_PAD_", 64 * 2**20),
)

_applied = False


def _mallopt() -> Any:
    """The C library's ``mallopt`` (glibc), or None where it has none."""
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        libc = ctypes.CDLL(name)
        func = libc.mallopt
    except (OSError, AttributeError):
        return None
    func.argtypes = (ctypes.c_int, ctypes.c_int)
    func.restype = ctypes.c_int
    return func


def apply_allocator_policy() -> bool:
    """Set the allocator policy of this process and its children (module docstring).

    Returns
    -------
    bool
        True when every setting was accepted by ``mallopt`` (now or at an earlier call),
        False where the C library has no ``mallopt`` or refused one.
    """
    global _applied
    if _applied:
        return True
    for _, env, value in ALLOCATOR_SETTINGS:
        os.environ.setdefault(env, str(value))  # a user's own setting wins
    func = _mallopt()
    if func is None:
        return False
    ok = all(func(param, value) == 1 for param, _, value in ALLOCATOR_SETTINGS)
    _applied = ok
    return ok
