"""A continuous transfer function model: coefficients, poles, gain, bandwidth, JSON.

`TFModel` is ``G(s) = (b_m s^m + ... + b_0) / (s^n + a_{n-1} s^{n-1} + ... + a_0)``
(``m <= n``, denominator monic, ``s`` in rad/s), e.g. seed 003 part 2 §1's galvo axis
``1.242e11 / (s^3 + 9517 s^2 + 5.773e7 s + 1.272e11)``. It gives what a fit is judged by
and what a shaper is built from: poles and zeros, the static gain ``G(0)``, the natural
frequency ``|p| / 2 pi`` of each real pole and of each complex pair with its damping
``-Re(p) / |p|``, the -3 dB bandwidth (the first frequency where ``|G|`` falls to
``|G(0)| / sqrt(2)``), a python-control ``TransferFunction``, and a JSON-ready dict.

Its frequency response can be taken as sampled data would show it (``sampling``):

* ``"none"``: ``G(j w)``, the continuous model;
* ``"delay"``: ``G(j w) exp(-j w T / 2)``, the half-sample delay of a zero-order hold;
* ``"zoh"``: the ZOH discretisation of ``G`` at ``T`` evaluated at ``z = exp(j w T)``:
  exactly what a system sampled every ``T`` with a held input shows.

Numerics use a scaled variable ``s' = s / w_s`` (``w_s`` the geometric mean of the pole
magnitudes, `TFModel.scale_rad_s`), in which the seed's coefficients are all of order one;
`TFModel.scaled` and `TFModel.from_scaled` convert, and `response_scaled` evaluates a model
given in that form (the fit's inner loop).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Annotated, Any, Literal, NamedTuple

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.signal
from pydantic import AfterValidator, BaseModel, ConfigDict, Field

import control
from microfab.core.arrays import readonly
from microfab.core.validate import check_positive
from microfab.io.filekinds import FILE_KINDS
from microfab.plants.lti import freqresp_ss

__all__ = [
    "SAMPLINGS",
    "PoleMode",
    "Sampling",
    "TFModel",
    "TFModelDoc",
    "read_tf_model",
    "response_scaled",
]

Sampling = Literal["zoh", "delay", "none"]
SAMPLINGS: tuple[str, ...] = ("zoh", "delay", "none")
FORMAT = "microfab.identify.TFModel"
VERSION = 1
_REAL_TOL = 1e-9  # |Im p| <= _REAL_TOL |p|: the pole is real
_DICT_KEYS = frozenset({"format", "version", "num", "den", "unit", "derived", "fit"})


class PoleMode(NamedTuple):
    """A complex pole pair as natural frequency and damping.

    Attributes
    ----------
    frequency_hz : float
        Natural frequency ``|p| / (2 pi)``, Hz.
    damping : float
        Damping ratio ``-Re(p) / |p|``.
    """

    frequency_hz: float
    damping: float


def check_sampling(sampling: str, dt: float | None) -> float | None:
    """Check a sampling mode and its sample time; return ``dt`` as a float (or None).

    Raises
    ------
    ValueError
        An unknown mode, or "zoh" / "delay" without a positive ``dt``.
    """
    if sampling not in SAMPLINGS:
        raise ValueError(f"sampling must be one of {', '.join(SAMPLINGS)}, got {sampling!r}")
    if sampling == "none":
        return None if dt is None else check_positive("dt", dt, "s")
    if dt is None:
        raise ValueError(
            f"sampling={sampling!r} needs the sample time dt in s (or use sampling='none')"
        )
    return check_positive("dt", dt, "s")


def response_scaled(
    b: np.ndarray, a: np.ndarray, w: np.ndarray, sampling: str, period: float | None
) -> np.ndarray:
    """Frequency response of a model given in the scaled variable ``s' = s / w_s``.

    Parameters
    ----------
    b, a : numpy.ndarray
        Numerator and monic denominator in ``s'``, highest power first,
        ``len(b) <= len(a)``.
    w : numpy.ndarray
        Scaled angular frequencies ``2 pi f / w_s``, shape (n,).
    sampling : {"zoh", "delay", "none"}
        How the model is compared with sampled data (module docstring).
    period : float or None
        Scaled sample time ``w_s dt`` (unused for "none").

    Returns
    -------
    numpy.ndarray
        Complex response, shape (n,).
    """
    s = 1j * w
    if sampling == "zoh" and len(a) > 1:
        A, B, C, D = scipy.signal.tf2ss(b, a)
        nx = A.shape[0]
        aug = np.zeros((nx + 1, nx + 1))
        aug[:nx, :nx] = A
        aug[:nx, nx:] = B
        phi = scipy.linalg.expm(aug * period)
        z = np.exp(s * period)
        return freqresp_ss(phi[:nx, :nx], phi[:nx, nx:], C, D, z)[:, 0, 0]
    h = np.polyval(b, s) / np.polyval(a, s)
    if sampling == "delay":
        h = h * np.exp(-0.5 * s * period)
    return h


@dataclass(frozen=True, eq=False)
class TFModel:
    """A continuous single-input single-output transfer function ``num(s) / den(s)``.

    Parameters
    ----------
    num : array_like
        Numerator coefficients, highest power of ``s`` (rad/s) first; leading zeros are
        dropped.
    den : array_like
        Denominator coefficients, highest power first, leading one non-zero; stored
        divided by it (monic), the numerator with it.
    unit : str
        Unit of the gain, output / input (e.g. "bit/bit"), for labels.

    Raises
    ------
    ValueError
        Empty, non-1-D or non-finite coefficients, a zero leading denominator
        coefficient, or more zeros than poles (an improper model).

    Examples
    --------
    >>> m = TFModel(num=[1.242e11], den=[1, 9517, 5.773e7, 1.272e11])  # seed 003 §1
    >>> round(m.static_gain, 4), [round(f, 1) for f in m.real_poles_hz]
    (0.9764, [550.5])
    """

    num: np.ndarray
    den: np.ndarray
    unit: str = field(default="")

    def __post_init__(self) -> None:
        num = np.atleast_1d(np.asarray(self.num, dtype=float))
        den = np.atleast_1d(np.asarray(self.den, dtype=float))
        for name, c in (("num", num), ("den", den)):
            if c.ndim != 1 or c.size == 0:
                raise ValueError(f"{name} must be a non-empty 1-D sequence, got shape {c.shape}")
            if not np.all(np.isfinite(c)):
                raise ValueError(f"{name} holds NaN/inf: {c.tolist()}")
        if den[0] == 0.0:
            raise ValueError(f"den's leading coefficient must be non-zero, got {den.tolist()}")
        nz = np.nonzero(num)[0]
        num = num[nz[0] :] if nz.size else np.zeros(1)
        if num.size > den.size:
            raise ValueError(
                f"the model must be proper (no more zeros than poles), got "
                f"{num.size - 1} zeros and {den.size - 1} poles"
            )
        object.__setattr__(self, "num", readonly(num / den[0]))
        object.__setattr__(self, "den", readonly(den / den[0]))

    # --------------------------------------------------------------- structure
    @property
    def n_poles(self) -> int:
        """Number of poles (degree of the denominator)."""
        return self.den.size - 1

    @property
    def n_zeros(self) -> int:
        """Number of finite zeros (degree of the numerator)."""
        return self.num.size - 1

    @property
    def poles(self) -> np.ndarray:
        """Poles, rad/s, shape (n_poles,), by increasing magnitude."""
        p = np.roots(self.den)
        return p[np.lexsort((p.imag, np.abs(p)))]

    @property
    def zeros(self) -> np.ndarray:
        """Finite zeros, rad/s, shape (n_zeros,), by increasing magnitude."""
        z = np.roots(self.num) if self.num.size > 1 else np.zeros(0, complex)
        return z[np.lexsort((z.imag, np.abs(z)))]

    @property
    def is_stable(self) -> bool:
        """Whether every pole lies in the open left half plane."""
        return bool(np.all(self.poles.real < 0))

    @property
    def static_gain(self) -> float:
        """``G(0) = b_0 / a_0``; ``inf`` for a model with a pole at the origin."""
        if self.den[-1] == 0.0:
            return math.inf
        return float(self.num[-1] / self.den[-1])

    @property
    def real_poles_hz(self) -> tuple[float, ...]:
        """``|p| / (2 pi)`` of each real pole, Hz, increasing."""
        p = self.poles
        real = np.abs(p.imag) <= _REAL_TOL * np.abs(p)
        return tuple(float(v) for v in np.sort(np.abs(p[real])) / (2 * np.pi))

    @property
    def complex_modes(self) -> tuple[PoleMode, ...]:
        """Natural frequency (Hz) and damping of each complex pole pair, by frequency."""
        p = self.poles
        upper = p[p.imag > _REAL_TOL * np.abs(p)]
        modes = [PoleMode(float(abs(q) / (2 * np.pi)), float(-q.real / abs(q))) for q in upper]
        return tuple(sorted(modes))

    @property
    def scale_rad_s(self) -> float:
        """Characteristic frequency, rad/s: geometric mean of the non-zero pole magnitudes.

        ``|a_0|^(1/n)`` when no pole is at the origin; 1 for a model without non-zero poles.
        """
        mags = np.abs(self.poles)
        mags = mags[mags > 0]
        if mags.size == 0:
            return 1.0
        return float(np.exp(np.mean(np.log(mags))))

    # ---------------------------------------------------------------- scaling
    def scaled(self, scale_rad_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients in ``s' = s / scale_rad_s``, denominator monic.

        Returns
        -------
        (numpy.ndarray, numpy.ndarray)
            ``b'``, ``a'`` with ``G(s) = b'(s') / a'(s')``.
        """
        ws = check_positive("scale_rad_s", scale_rad_s, "rad/s")
        n, m = self.n_poles, self.n_zeros
        a = self.den * ws ** -np.arange(n + 1, dtype=float)
        b = self.num * ws ** (np.arange(m, -1, -1, dtype=float) - n)
        return b, a

    @classmethod
    def from_scaled(
        cls, b: np.ndarray, a: np.ndarray, scale_rad_s: float, *, unit: str = ""
    ) -> TFModel:
        """The model whose coefficients in ``s' = s / scale_rad_s`` are ``b``, ``a``."""
        ws = check_positive("scale_rad_s", scale_rad_s, "rad/s")
        lead = float(np.asarray(a, dtype=float)[0])
        a = np.asarray(a, dtype=float) / lead
        b = np.atleast_1d(np.asarray(b, dtype=float)) / lead
        n, m = a.size - 1, b.size - 1
        den = a * ws ** np.arange(n + 1, dtype=float)
        num = b * ws ** (n - np.arange(m, -1, -1, dtype=float))
        return cls(num=num, den=den, unit=unit)

    # --------------------------------------------------------------- response
    def frequency_response(
        self, freq_hz: np.ndarray, *, sampling: Sampling = "none", dt: float | None = None
    ) -> np.ndarray:
        """Complex response at ``freq_hz``, continuous or as sampled data shows it.

        Parameters
        ----------
        freq_hz : numpy.ndarray
            Frequencies, Hz, shape (n,).
        sampling : {"none", "delay", "zoh"}
            Continuous ``G(j w)``, with the half-sample delay, or ZOH-discretised at
            ``dt`` (module docstring).
        dt : float, optional
            Sample time, s; needed for "delay" and "zoh".

        Returns
        -------
        numpy.ndarray
            Complex response, shape (n,).
        """
        dt = check_sampling(sampling, dt)
        ws = self.scale_rad_s
        b, a = self.scaled(ws)
        w = 2 * np.pi * np.atleast_1d(np.asarray(freq_hz, dtype=float)) / ws
        return response_scaled(b, a, w, sampling, None if dt is None else dt * ws)

    def bandwidth_hz(self) -> float:
        """-3 dB bandwidth: first frequency where ``|G| = |G(0)| / sqrt(2)``, Hz.

        Half power, 20 log10(1/sqrt 2) = -3.0103 dB below the static gain (python-control's
        ``bandwidth`` takes -3.0 dB exactly, 0.2 % lower for the seed's model).

        Raises
        ------
        ValueError
            An unstable model, one without a finite non-zero static gain, or one whose
            gain never falls 3 dB.
        """
        if not self.is_stable:
            raise ValueError("the bandwidth of an unstable model is not defined")
        g0 = self.static_gain
        if not math.isfinite(g0) or g0 == 0.0:
            raise ValueError(f"the model's static gain is {g0}: no -3 dB bandwidth relative to it")
        level = abs(g0) / math.sqrt(2.0)
        roots = np.concatenate([self.poles, self.zeros])
        mags = np.abs(roots[np.abs(roots) > 0]) / (2 * np.pi)
        f = np.geomspace(mags.min() * 1e-4, mags.max() * 1e4, 1601)
        excess = np.abs(self.frequency_response(f)) - level
        below = np.nonzero(excess < 0)[0]
        if below.size == 0:
            raise ValueError("the model's gain never falls 3 dB below its static gain")
        i = below[0]
        if i == 0:
            raise ValueError("the model's gain is 3 dB down at the lowest frequency examined")

        def gap(x: float) -> float:
            return float(np.abs(self.frequency_response(np.array([x]))[0]) - level)

        return float(scipy.optimize.brentq(gap, f[i - 1], f[i], xtol=1e-12, rtol=1e-13))

    # ------------------------------------------------------------- conversion
    def to_control(self) -> control.TransferFunction:
        """The model as a python-control continuous ``TransferFunction``."""
        return control.tf(self.num.tolist(), self.den.tolist())

    @classmethod
    def from_control(cls, tf: control.TransferFunction, *, unit: str = "") -> TFModel:
        """A `TFModel` from a continuous SISO python-control ``TransferFunction``."""
        if not (tf.ninputs == 1 and tf.noutputs == 1):
            raise ValueError(f"need a SISO transfer function, got {tf.noutputs}x{tf.ninputs}")
        if tf.isdtime(strict=True):
            raise ValueError("need a continuous-time transfer function, got a discrete one")
        return cls(num=np.ravel(tf.num[0][0]), den=np.ravel(tf.den[0][0]), unit=unit)

    def formula(self, digits: int = 4) -> str:
        """``num / den`` in ``s`` with ``digits`` significant digits (the seed's style)."""

        def poly(c: np.ndarray) -> str:
            n = c.size - 1
            terms = []
            for i, v in enumerate(c):
                if v == 0.0:
                    continue
                p = n - i
                coef = f"{v:.{digits}g}"
                if p > 0 and coef == "1":
                    coef = ""
                var = "" if p == 0 else ("s" if p == 1 else f"s^{p}")
                terms.append(f"{coef} {var}".strip() if coef and var else coef + var)
            return " + ".join(terms).replace("+ -", "- ") or "0"

        return f"({poly(self.num)}) / ({poly(self.den)})"

    def derived(self) -> dict[str, Any]:
        """Poles, zeros, gain, modes and bandwidth as JSON-ready numbers."""
        try:
            bw: float | None = self.bandwidth_hz()
        except ValueError:
            bw = None
        g0 = self.static_gain
        return {
            "poles": [[float(p.real), float(p.imag)] for p in self.poles],
            "zeros": [[float(z.real), float(z.imag)] for z in self.zeros],
            "static_gain": g0 if math.isfinite(g0) else None,
            "real_poles_hz": list(self.real_poles_hz),
            "complex_modes": [m._asdict() for m in self.complex_modes],
            "bandwidth_hz": bw,
            "stable": self.is_stable,
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict: format, version, ``num``, ``den``, unit and the derived numbers.

        The ``derived`` block is for readers; `from_dict` recomputes it from the
        coefficients and does not read it.
        """
        return {
            "format": FORMAT,
            "version": VERSION,
            "num": self.num.tolist(),
            "den": self.den.tolist(),
            "unit": self.unit,
            "derived": self.derived(),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TFModel:
        """Read `to_dict`'s output (also a `microfab.identify.fit.FitResult.to_dict`).

        Raises
        ------
        ValueError
            Not a dict, an unknown key, another format or version, missing or
            non-numeric ``num`` / ``den``, or an invalid model.
        """
        if not isinstance(d, dict):
            raise ValueError(f"a model must be a JSON object, got {type(d).__name__}")
        unknown = sorted(set(d) - _DICT_KEYS)
        if unknown:
            raise ValueError(
                f"unknown key {unknown[0]!r} in the model (known: {', '.join(sorted(_DICT_KEYS))})"
            )
        if d.get("format", FORMAT) != FORMAT:
            raise ValueError(f"format must be {FORMAT!r}, got {d['format']!r}")
        if d.get("version", VERSION) != VERSION:
            raise ValueError(f"version must be {VERSION}, got {d['version']!r}")
        for key in ("num", "den"):
            if key not in d:
                raise ValueError(f"the model has no {key!r} (coefficients, highest power first)")
            v = d[key]
            if not isinstance(v, list) or not all(
                isinstance(c, int | float) and not isinstance(c, bool) for c in v
            ):
                raise ValueError(f"{key!r} must be a list of numbers, got {v!r}")
        unit = d.get("unit", "")
        if not isinstance(unit, str):
            raise ValueError(f"unit must be a string, got {unit!r}")
        return cls(num=np.array(d["num"], float), den=np.array(d["den"], float), unit=unit)


# --------------------------------------------------------------------------- the file
#: What `microfab.io.schema.read_json` calls a model file.
MODEL_KIND = FILE_KINDS["tf-model"].what
#: Most coefficients of a numerator or denominator read from a file. Assumed: the fits
#: of microfab are of order 12 or less; 64 leaves room and refuses a list of samples
#: given where coefficients belong.
MAX_COEFFS = 64


def _known_unit(unit: str) -> str:
    from microfab.io.schema import parse_unit

    parse_unit(unit)  # an unknown unit is refused (a SchemaError, a ValueError)
    return unit


class TFModelDoc(BaseModel):
    """The JSON form of a `TFModel` (`TFModel.to_dict`; also `FitResult.to_dict`)."""

    model_config = ConfigDict(strict=True, extra="forbid", allow_inf_nan=False)

    format: Literal["microfab.identify.TFModel"] = FORMAT
    version: Literal[1] = VERSION
    num: list[float] = Field(min_length=1, max_length=MAX_COEFFS)
    den: list[float] = Field(min_length=1, max_length=MAX_COEFFS)
    unit: Annotated[str, AfterValidator(_known_unit)] = ""
    derived: dict[str, Any] | None = None
    fit: dict[str, Any] | None = None


def read_tf_model(path: str | os.PathLike[str]) -> TFModel:
    """A transfer-function model file (`TFModel.to_dict` as JSON), through `TFModelDoc`.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        (`microfab.io.schema.SchemaError`) Not JSON, a file of another kind (named), a
        field of the wrong type, length or value, an unknown unit; or a model `TFModel`
        refuses (improper, a zero leading coefficient). The line names the file.
    """
    from microfab.io.schema import read_json, validated

    where = str(path)
    doc = validated(TFModelDoc, read_json(path, MODEL_KIND), where)
    try:
        return TFModel(num=np.array(doc.num), den=np.array(doc.den), unit=doc.unit)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
