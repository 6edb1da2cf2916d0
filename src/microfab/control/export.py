"""Trained seed 001 controllers exported for a real-time target: one versioned file.

`export_controller` writes the RBF networks (seed 001 eqs. 2-5: trained weights, centres,
widths, the input scaling, λ, Γ, σ, the sample time and the velocity estimator) and the
plug-in RC's memory (seed 001 §3.3, Fig. 6) to one file; `load_exported` reads it back,
refusing another format or a newer version. The file is written atomically.

Layout (both formats; ``A`` axes (2), ``l`` nodes per axis, ``N`` samples per period):

======================  ==========  ===========================================
name                    shape       meaning
======================  ==========  ===========================================
``format``              string      `EXPORT_FORMAT`
``version``             int         `EXPORT_VERSION`
``meta``                string      JSON: format, version, user ``meta``, ``rbf``
                                    scalars (``lam`` 1/s, ``sigma``, ``dt`` s,
                                    ``estimator_layout``), ``rc`` (its `RCConfig`
                                    and sample counter) or null
``rbf_weights``         (A, l)      Ŵ, V
``rbf_centres``         (A, l, 6)   c_j, scaled units
``rbf_widths``          (A, l)      b_j, scaled units
``rbf_offset``          (A, 6)      z̃ = (z − offset) / scale, units of z
``rbf_scale``           (A, 6)      (mm, mm/s, mm, mm/s, mm/s, mm/s²)
``rbf_gamma``           (l,)        Γ diagonal, V/mm (absent: no adaptation)
``rbf_estimator``       (11,)       velocity filter, Tustin: A (2x2 row-major),
                                    B (2), C (2), D, g (2) (absent: none)
``rc_memory``           (N, A)      correction applied over the last period, mm
``rc_error``            (N, A)      its measured error r − y, mm
``rc_error_current``    (N, A)      error of the current period so far, mm
``rc_inner``            (m,)        inner controller state (may be empty)
======================  ==========  ===========================================

On the target, per axis ``a`` (other axis ``b``) and sample: ``z = (x_a, v_a, x_b, v_b,
s, ν)`` with ``s = λ(x_a − r_a) + (v_a − ṙ_a)`` and ``ν = λ(v_a − ṙ_a) − r̈_a``, the
velocities from the estimator; ``h_j = exp(−‖z̃ − c_j‖² / (2 b_j²))``; ``u_a = Σ Ŵ_j h_j``
(`RBFExport.command`); adaptation ``Ŵ ← exp(−Γσ dt) Ŵ − Γ dt h s`` (`microfab.control.rbf`).
The RC's next correction is `RCMemory.next_correction` (`microfab.control.repetitive`).
A ``.npz`` is NumPy's zip of ``.npy`` arrays; a ``.h5`` / ``.hdf5`` holds the arrays as
root datasets and ``format``, ``version``, ``meta`` as root attributes.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from microfab.control.rbf import N_Z, RBFAdaptive
from microfab.control.rc_memory import RCMemory
from microfab.control.repetitive import RCConfig
from microfab.control.velocity import N_ESTIMATOR_PARAMS
from microfab.io.atomic import atomic_path, atomic_save_npz
from microfab.io.schema import MAX_VALUES, SchemaError, check_count, check_npz

__all__ = [
    "EXPORT_FORMAT",
    "EXPORT_VERSION",
    "ExportedController",
    "RBFExport",
    "export_controller",
    "load_exported",
]

EXPORT_FORMAT = "microfab-controller-export"
#: Version of the layout (module docstring); `load_exported` refuses a newer one.
EXPORT_VERSION = 1
_SUFFIXES = {".npz": "npz", ".h5": "h5", ".hdf5": "h5"}
_RC_ARRAYS = ("memory", "error", "error_current", "inner")


def _h5py() -> Any:
    try:
        import h5py
    except ImportError as exc:  # pragma: no cover - h5py is installed with microfab[hdf5]
        raise ValueError("HDF5 export needs h5py: pip install 'microfab[hdf5]'") from exc
    return h5py


def _arr(name: str, value: Any, ndim: int) -> np.ndarray:
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers, got {value!r}") from None
    if a.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimension(s), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} holds NaN or inf; give finite values")
    return a


def _positive(name: str, value: float | None, unit: str) -> float | None:
    if value is None:
        return None
    v = float(value)
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be positive and finite, got {value} {unit}".rstrip())
    return v


@dataclass(frozen=True, kw_only=True, eq=False)
class RBFExport:
    """The RBF networks of every axis as plain arrays (module docstring for the layout).

    Parameters
    ----------
    weights : numpy.ndarray
        Ŵ per axis, V, shape (A, l).
    centres : numpy.ndarray
        c_j in scaled units, shape (A, l, 6).
    widths : numpy.ndarray
        b_j in scaled units, shape (A, l), > 0.
    lam : float
        λ of ``s = λe + ė``, 1/s, > 0.
    dt : float
        Sample time, s, > 0.
    offset, scale : numpy.ndarray, optional
        Input scaling per axis, shape (A, 6) (default 0 and 1: the centres are in the
        units of ``z``); scale > 0.
    gamma : numpy.ndarray, optional
        Γ diagonal, V/mm, shape (l,), > 0 (None: the target does not adapt).
    sigma : float, optional
        Leakage σ of eq. 5, > 0 (None with ``gamma``).
    estimator : numpy.ndarray, optional
        Velocity filter parameters, shape (11,) (None: the target brings its own).
    """

    weights: np.ndarray
    centres: np.ndarray
    widths: np.ndarray
    lam: float
    dt: float
    offset: np.ndarray | None = None
    scale: np.ndarray | None = None
    gamma: np.ndarray | None = None
    sigma: float | None = None
    estimator: np.ndarray | None = field(default=None)

    def __post_init__(self) -> None:
        w = _arr("weights", self.weights, 2)
        na, nl = w.shape
        if na < 1 or nl < 1:
            raise ValueError(f"weights must be shaped (axes >= 1, nodes >= 1), got {w.shape}")
        c = _arr("centres", self.centres, 3)
        if c.shape != (na, nl, N_Z):
            raise ValueError(
                f"centres must be shaped (axes, nodes, {N_Z}) = {(na, nl, N_Z)} like the "
                f"weights, got {c.shape}; fix their dimension"
            )
        b = _arr("widths", self.widths, 2)
        if b.shape != (na, nl) or np.any(b <= 0):
            raise ValueError(f"widths must be positive and shaped {(na, nl)}, got {b.shape}")
        off = np.zeros((na, N_Z)) if self.offset is None else _arr("offset", self.offset, 2)
        sc = np.ones((na, N_Z)) if self.scale is None else _arr("scale", self.scale, 2)
        for name, a in (("offset", off), ("scale", sc)):
            if a.shape != (na, N_Z):
                raise ValueError(f"{name} must be shaped {(na, N_Z)}, got {a.shape}")
        if np.any(sc <= 0):
            raise ValueError("scale must be positive in every component")
        _positive("lam (λ)", self.lam, "1/s")
        _positive("dt", self.dt, "s")
        g = None if self.gamma is None else _arr("gamma (Γ)", self.gamma, 1)
        if g is not None and (g.shape != (nl,) or np.any(g <= 0)):
            raise ValueError(f"gamma (Γ) must be positive and shaped ({nl},), got {g.shape}")
        if (g is None) != (self.sigma is None):
            raise ValueError("give gamma (Γ) and sigma (σ) together, or neither")
        _positive("sigma (σ)", self.sigma, "")
        est = None if self.estimator is None else _arr("estimator", self.estimator, 1)
        if est is not None and est.shape != (N_ESTIMATOR_PARAMS,):
            raise ValueError(
                f"estimator must hold {N_ESTIMATOR_PARAMS} parameters, got {est.shape}"
            )
        for name, a in (
            ("weights", w),
            ("centres", c),
            ("widths", b),
            ("offset", off),
            ("scale", sc),
            ("gamma", g),
            ("estimator", est),
        ):
            object.__setattr__(self, name, a)
        object.__setattr__(self, "lam", float(self.lam))
        object.__setattr__(self, "dt", float(self.dt))
        if self.sigma is not None:
            object.__setattr__(self, "sigma", float(self.sigma))

    @property
    def n_axes(self) -> int:
        """Axes ``A``."""
        return int(self.weights.shape[0])

    @property
    def n_nodes(self) -> int:
        """Nodes per axis ``l``."""
        return int(self.weights.shape[1])

    @classmethod
    def from_controller(cls, rbf: RBFAdaptive, state: np.ndarray | None = None) -> RBFExport:
        """The arrays of a controller, with the trained weights of ``state`` (default Ŵ(0)).

        Parameters
        ----------
        rbf : RBFAdaptive
            The controller.
        state : numpy.ndarray, optional
            A controller state (e.g. the final state of a run) whose Ŵ is exported.
        """
        if not isinstance(rbf, RBFAdaptive):
            raise TypeError(f"rbf must be an RBFAdaptive, got {type(rbf).__name__}")
        x = rbf.init() if state is None else np.asarray(state, dtype=np.float64)
        if x.shape != rbf.init().shape:
            raise ValueError(
                f"state must be the controller's ({rbf.init().size} values), got {x.shape}"
            )
        nets = rbf.networks
        return cls(
            weights=rbf.weights(x),
            centres=np.stack([n.centres for n in nets]),
            widths=np.stack([n.widths for n in nets]),
            offset=np.stack([n.offset for n in nets]),
            scale=np.stack([n.scale for n in nets]),
            lam=rbf.config.lam,
            dt=rbf.dt,
            gamma=rbf.config.gamma_diagonal(),
            sigma=rbf.config.sigma,
            estimator=rbf.config.estimator.discrete(rbf.dt),
        )

    def hidden(self, axis: int, z: np.ndarray) -> np.ndarray:
        """``h(z)`` of one axis for unscaled inputs ``z``, shape (..., 6) -> (..., l)."""
        zs = (np.asarray(z, dtype=float) - self.offset[axis]) / self.scale[axis]
        d2 = ((zs[..., None, :] - self.centres[axis]) ** 2).sum(axis=-1)
        return np.exp(-d2 / (2.0 * self.widths[axis] ** 2))

    def command(self, z: np.ndarray) -> np.ndarray:
        """``u_a = Ŵ_aᵀ h(z_a)`` of every axis, V, for inputs ``z`` shaped (A, 6)."""
        za = np.asarray(z, dtype=float)
        if za.shape != (self.n_axes, N_Z):
            raise ValueError(f"z must be shaped {(self.n_axes, N_Z)}, got {za.shape}")
        return np.array([self.weights[a] @ self.hidden(a, za[a]) for a in range(self.n_axes)])


@dataclass(frozen=True, kw_only=True, eq=False)
class ExportedController:
    """What `load_exported` read.

    Attributes
    ----------
    rbf : RBFExport or None
        The RBF networks, if exported.
    rc : RCMemory or None
        The RC memory, if exported.
    meta : dict
        The user's metadata.
    version : int
        The file's layout version.
    """

    rbf: RBFExport | None
    rc: RCMemory | None
    meta: dict[str, Any]
    version: int


def export_controller(
    path: str | Path,
    *,
    rbf: RBFAdaptive | RBFExport | None = None,
    rbf_state: np.ndarray | None = None,
    rc: RCMemory | None = None,
    meta: Mapping[str, Any] | None = None,
) -> Path:
    """Write trained networks and RC memory to one versioned file, atomically.

    Parameters
    ----------
    path : str or Path
        Target, ``.npz`` or ``.h5`` / ``.hdf5``.
    rbf : RBFAdaptive or RBFExport, optional
        The RBF controller (with ``rbf_state`` for its trained weights) or its arrays.
    rbf_state : numpy.ndarray, optional
        Controller state whose weights are exported (with an `RBFAdaptive` only).
    rc : RCMemory, optional
        The RC memory (`PluginRC.memory_of`, `RCMemory.load`).
    meta : mapping, optional
        JSON-ready metadata (machine, date, job...).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        Nothing to export, an unknown suffix, metadata that is not JSON, or bad arrays;
        nothing is written then.
    """
    p = Path(path)
    fmt = _SUFFIXES.get(p.suffix.lower())
    if fmt is None:
        raise ValueError(f"export file {p} must end in {', '.join(_SUFFIXES)} (the format)")
    if rbf is None and rc is None:
        raise ValueError("nothing to export: give rbf, rc or both")
    if isinstance(rbf, RBFAdaptive):
        rbf = RBFExport.from_controller(rbf, rbf_state)
    elif rbf_state is not None:
        raise ValueError("rbf_state goes with an RBFAdaptive; an RBFExport carries its weights")
    if rbf is not None and not isinstance(rbf, RBFExport):
        raise TypeError(f"rbf must be an RBFAdaptive or RBFExport, got {type(rbf).__name__}")
    if rc is not None and not isinstance(rc, RCMemory):
        raise TypeError(f"rc must be an RCMemory, got {type(rc).__name__}")
    head: dict[str, Any] = {"format": EXPORT_FORMAT, "version": EXPORT_VERSION}
    head["meta"] = dict(meta or {})
    arrays: dict[str, np.ndarray] = {}
    head["rbf"] = None
    if rbf is not None:
        head["rbf"] = {
            "lam": rbf.lam,
            "sigma": rbf.sigma,
            "dt": rbf.dt,
            "estimator_layout": "A(2x2 row-major), B(2), C(2), D, g(2); Tustin",
        }
        for name in ("weights", "centres", "widths", "offset", "scale", "gamma", "estimator"):
            value = getattr(rbf, name)
            if value is not None:
                arrays[f"rbf_{name}"] = value
    head["rc"] = None
    if rc is not None:
        head["rc"] = {"config": rc.config.to_json(), "samples": rc.samples}
        arrays |= {f"rc_{k}": getattr(rc, k) for k in _RC_ARRAYS}
    try:
        text = json.dumps(head, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"meta must be JSON-ready (no NaN): {exc}") from exc
    if fmt == "npz":
        atomic_save_npz(
            p,
            format=np.array(EXPORT_FORMAT),
            version=np.array(EXPORT_VERSION),
            meta=np.array(text),
            **arrays,
        )
    else:
        h5py = _h5py()
        with atomic_path(p) as tmp, h5py.File(tmp, "w", track_order=True) as f:
            f.attrs["format"] = EXPORT_FORMAT
            f.attrs["version"] = EXPORT_VERSION
            f.attrs["meta"] = text
            for name, value in arrays.items():
                f.create_dataset(name, data=value)
    return p


def _read(p: Path, fmt: str) -> tuple[Any, Any, str, dict[str, np.ndarray]]:
    if fmt == "npz":
        check_npz(p)  # the members' sizes from their headers, before any is read
        with np.load(p, allow_pickle=False) as z:
            arrays = {k: np.array(z[k]) for k in z.files}
        fmt_v = arrays.pop("format", None)
        ver_v = arrays.pop("version", None)
        meta_v = arrays.pop("meta", None)
        return (
            None if fmt_v is None else str(fmt_v),
            None if ver_v is None else ver_v.item(),
            "" if meta_v is None else str(meta_v),
            arrays,
        )
    h5py = _h5py()
    if not h5py.is_hdf5(p):
        raise ValueError("not an HDF5 file")
    with h5py.File(p, "r") as f:
        attrs = dict(f.attrs)
        sets = {k: v for k, v in f.items() if isinstance(v, h5py.Dataset)}
        total = 0
        for k, v in sets.items():  # declared sizes, before any dataset is read
            total += check_count(str(p), f"values in dataset {k!r}", int(np.prod(v.shape)))
            if v.dtype.hasobject or v.dtype.kind not in "biuf":
                raise SchemaError(f"{p}: dataset {k!r} holds {v.dtype}, not numbers")
        check_count(str(p), "values in all datasets", total, MAX_VALUES)
        arrays = {k: np.array(v[()]) for k, v in sets.items()}

    def text(v: Any) -> str | None:
        return None if v is None else v.decode() if isinstance(v, bytes) else str(v)

    ver = attrs.get("version")
    version = None if ver is None else np.asarray(ver).item()
    return text(attrs.get("format")), version, text(attrs.get("meta")) or "", arrays


def _no_constant(name: str) -> None:
    raise ValueError(f"{name} is not a JSON number")


def load_exported(path: str | Path) -> ExportedController:
    """Read a file written by `export_controller`, checking its format and version.

    Raises
    ------
    FileNotFoundError
        No file at ``path``.
    ValueError
        Unreadable; not a controller export; a newer or unknown version (upgrade
        microfab); or inconsistent contents.
    """
    p = Path(path)
    fmt = _SUFFIXES.get(p.suffix.lower())
    if fmt is None:
        raise ValueError(f"export file {p} must end in {', '.join(_SUFFIXES)}")
    if not p.is_file():
        raise FileNotFoundError(f"no controller export at {p}")
    try:
        kind, version, text, arrays = _read(p, fmt)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise ValueError(f"cannot read controller export {p}: {exc}") from exc
    if kind != EXPORT_FORMAT:
        raise ValueError(f"{p} is not a microfab controller export (format {EXPORT_FORMAT!r})")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ValueError(
            f"{p} has an unknown export version {version!r}; expected 1 to {EXPORT_VERSION}"
        )
    if version > EXPORT_VERSION:
        raise ValueError(
            f"{p} was written as export version {version}, newer than this microfab reads "
            f"({EXPORT_VERSION}): upgrade microfab"
        )
    try:
        head = json.loads(text, parse_constant=_no_constant)
        if not isinstance(head, dict):
            raise TypeError(f"its meta is a JSON {type(head).__name__}, not an object")
        rbf = None
        if head["rbf"] is not None:
            r = head["rbf"]
            rbf = RBFExport(
                weights=arrays["rbf_weights"],
                centres=arrays["rbf_centres"],
                widths=arrays["rbf_widths"],
                offset=arrays["rbf_offset"],
                scale=arrays["rbf_scale"],
                gamma=arrays.get("rbf_gamma"),
                sigma=r["sigma"],
                estimator=arrays.get("rbf_estimator"),
                lam=r["lam"],
                dt=r["dt"],
            )
        rc = None
        if head["rc"] is not None:
            rc = RCMemory(
                config=RCConfig.from_json(head["rc"]["config"]),
                samples=int(head["rc"]["samples"]),
                **{k: arrays[f"rc_{k}"] for k in _RC_ARRAYS},
            )
        meta = dict(head["meta"])
    except (KeyError, TypeError, ValueError, json.JSONDecodeError) as exc:
        raise ValueError(f"controller export {p} is inconsistent: {exc}") from exc
    return ExportedController(rbf=rbf, rc=rc, meta=meta, version=version)
