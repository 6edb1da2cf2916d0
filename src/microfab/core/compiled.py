"""`Compiled`: the one base class of components that run in the compiled per-sample loop.

A closed-loop component (plant, controller, observer) is an explicit state machine. Any
such component runs in the Python loop of `microfab.sim.loop`; one that also derives from
`Compiled` runs in the numba loop as well. It then carries

* ``params``: its parameters as one flat ``float64`` array, and
* numba kernels (``@numba.njit`` functions), named by the class variable ``kernel_names``
  of its role (`microfab.plants.base.CompiledPlant`,
  `microfab.control.base.CompiledController`, `microfab.control.base.CompiledObserver`),
  which work in place on flat ``float64`` state arrays and allocate nothing.

A class that derives from `Compiled` but lacks one of its kernels is refused when it is
instantiated (`TypeError` naming the class and the kernel), rather than being silently
sent down the slow path.

This module also holds the packed layout of a state-space model shared by the LTI kernels
of the plant and control layers: ``[nx, nu, ny, A.ravel(), B.ravel(), C.ravel(),
D.ravel()]``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar, Self

import numpy as np
from numba import njit

__all__ = ["Compiled", "is_kernel", "lti_dims", "pack_lti"]


def is_kernel(obj: object) -> bool:
    """Whether ``obj`` is a numba-compiled function (a ``@numba.njit`` dispatcher)."""
    from numba.core.dispatcher import Dispatcher

    return isinstance(obj, Dispatcher)


class Compiled(ABC):
    """Base of every component that supplies numba kernels for the compiled loop.

    Subclasses name the kernels of their role in ``kernel_names`` and define each as a
    class attribute holding a ``@numba.njit`` function; instances set ``params``.

    Attributes
    ----------
    kernel_names : tuple of str
        Names of the kernel attributes the role requires (class variable).
    params : numpy.ndarray
        Flat ``float64`` parameter array passed to every kernel, shape (n_params,).

    Raises
    ------
    TypeError
        On instantiation, when a kernel named in ``kernel_names`` is missing or is not a
        numba-compiled function.
    """

    kernel_names: ClassVar[tuple[str, ...]] = ()
    params: np.ndarray

    def __new__(cls, *args: Any, **kwargs: Any) -> Self:
        """Refuse a class that lacks one of the kernels its role names."""
        missing = [n for n in cls.kernel_names if not is_kernel(getattr(cls, n, None))]
        if missing:
            raise TypeError(
                f"{cls.__name__} derives from Compiled but does not define the numba "
                f"kernel(s) {', '.join(repr(n) for n in missing)} (class attributes holding "
                "@numba.njit functions); define them, or drop the Compiled base so that "
                "the component runs in the Python loop"
            )
        return super().__new__(cls)

    @abstractmethod
    def init(self) -> np.ndarray:
        """Initial state: a flat ``float64`` array (kernel scratch space included)."""

    def kernels(self) -> tuple[Any, ...]:
        """The kernels in the order of ``kernel_names`` (the numba dispatchers themselves).

        Read from the class: a numba dispatcher read through an instance is bound as a
        method, which the compiled loop cannot take.
        """
        return tuple(getattr(type(self), n) for n in self.kernel_names)

    def packed_params(self) -> np.ndarray:
        """``params`` checked: flat, C-contiguous, finite ``float64``.

        Raises
        ------
        TypeError
            When ``params`` is missing or not a 1-D ``float64`` array.
        ValueError
            When it holds NaN or inf.
        """
        p = getattr(self, "params", None)
        if not isinstance(p, np.ndarray) or p.dtype != np.float64 or p.ndim != 1:
            raise TypeError(
                f"{type(self).__name__}.params must be a 1-D float64 array, got "
                f"{type(p).__name__}"
                + (f" of dtype {p.dtype} and shape {p.shape}" if isinstance(p, np.ndarray) else "")
            )
        memo = getattr(self, "__dict__", {})
        if memo.get("_checked_params") is p and not p.flags.writeable:
            return p  # checked before, and read-only since
        if not np.isfinite(p).all():
            raise ValueError(f"{type(self).__name__}.params holds NaN or inf")
        p = np.ascontiguousarray(p)
        if not p.flags.writeable and p.flags.owndata:
            # Read-only and owning its data: it changes only if made writeable again
            # (tested above), so check it once (the compiled loop asks at every call).
            memo["_checked_params"] = p
        return p


def pack_lti(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> np.ndarray:
    """Pack state-space matrices into the flat parameter layout of the LTI kernels.

    Parameters
    ----------
    A, B, C, D : numpy.ndarray
        Shapes (nx, nx), (nx, nu), (ny, nx), (ny, nu).

    Returns
    -------
    numpy.ndarray
        ``[nx, nu, ny, A.ravel(), B.ravel(), C.ravel(), D.ravel()]``, ``float64``.
    """
    nx, nu = B.shape
    ny = C.shape[0]
    return np.concatenate(
        [np.array([nx, nu, ny], dtype=float), A.ravel(), B.ravel(), C.ravel(), D.ravel()]
    ).astype(np.float64)


@njit(cache=True, inline="always")
def lti_dims(p: np.ndarray) -> tuple[int, int, int, int, int, int, int]:
    """``(nx, nu, ny, iA, iB, iC, iD)``: sizes and offsets of a packed LTI model."""
    nx = int(p[0])
    nu = int(p[1])
    ny = int(p[2])
    ia = 3
    ib = ia + nx * nx
    ic = ib + nx * nu
    idd = ic + ny * nx
    return nx, nu, ny, ia, ib, ic, idd
