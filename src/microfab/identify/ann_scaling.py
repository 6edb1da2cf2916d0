"""The scaling of the seed 002 networks' inputs and target (`microfab.identify.ann_data`).

`Scaling` holds an offset (mean) and a scale (standard deviation) for every encoded input
column and for the encoded target, fitted on the training windows and stored with the
model (see the module docstring of `microfab.identify.ann_data`, "Scaling"). A data
class apart from the windowing that fits it (`~microfab.identify.ann_data.WindowSet`),
which re-exports it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.core.validate import check_positive

__all__ = ["Scaling"]


@dataclass(frozen=True)
class Scaling:
    """Offset and scale of every network input column and of the target.

    ``scaled = (value - offset) / scale``. Fitted on the training windows (`fit`).

    Parameters
    ----------
    in_offset, in_scale : numpy.ndarray
        Shape (n_inputs,), m.
    out_offset, out_scale : float
        Of the encoded target, m.
    """

    in_offset: np.ndarray
    in_scale: np.ndarray
    out_offset: float
    out_scale: float

    def __post_init__(self) -> None:
        off = np.asarray(self.in_offset, dtype=np.float64)
        sc = np.asarray(self.in_scale, dtype=np.float64)
        if off.ndim != 1 or off.shape != sc.shape:
            raise ValueError(
                f"in_offset and in_scale must be 1-D of one length, got {off.shape}, {sc.shape}"
            )
        if not (np.all(np.isfinite(off)) and np.all(np.isfinite(sc)) and np.all(sc > 0)):
            raise ValueError("in_offset must be finite and in_scale finite and positive")
        check_positive("out_scale", self.out_scale, "m")
        object.__setattr__(self, "in_offset", off)
        object.__setattr__(self, "in_scale", sc)
        object.__setattr__(self, "out_offset", float(self.out_offset))
        object.__setattr__(self, "out_scale", float(self.out_scale))

    @property
    def n_inputs(self) -> int:
        """Number of input columns."""
        return int(self.in_offset.shape[0])

    @classmethod
    def fit(cls, inputs: np.ndarray, target: np.ndarray) -> Scaling:
        """Mean and standard deviation per column (a constant column keeps scale 1)."""
        return cls._from_moments(
            inputs.shape[0], inputs.mean(axis=0), inputs.var(axis=0), target.mean(), target.var()
        )

    @classmethod
    def _from_moments(
        cls, n: int, mean: np.ndarray, var: np.ndarray, t_mean: float, t_var: float
    ) -> Scaling:
        if n < 2:
            raise ValueError(f"scaling needs at least 2 training windows, got {n}")

        def scale(v: np.ndarray, m: np.ndarray) -> np.ndarray:
            s = np.sqrt(np.maximum(v, 0.0))
            tiny = 1e-12 * np.maximum(np.abs(m), 1.0)
            return np.where(s > tiny, s, 1.0)

        return cls(mean, scale(var, mean), float(t_mean), float(scale(np.array(t_var), t_mean)))

    def scale_inputs(self, inputs: np.ndarray) -> np.ndarray:
        """Scaled inputs as float32, shape as given."""
        return ((inputs - self.in_offset) / self.in_scale).astype(np.float32)

    def scale_target(self, target: np.ndarray) -> np.ndarray:
        """Scaled encoded target as float32."""
        return ((np.asarray(target) - self.out_offset) / self.out_scale).astype(np.float32)

    def unscale_target(self, scaled: np.ndarray) -> np.ndarray:
        """Encoded target (m, float64) from the network's scaled output."""
        return np.asarray(scaled, dtype=np.float64) * self.out_scale + self.out_offset

    def as_dict(self) -> dict[str, Any]:
        """JSON form."""
        return {
            "in_offset": self.in_offset.tolist(),
            "in_scale": self.in_scale.tolist(),
            "out_offset": self.out_offset,
            "out_scale": self.out_scale,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Scaling:
        """Inverse of `as_dict`."""
        return cls(
            np.array(d["in_offset"], dtype=np.float64),
            np.array(d["in_scale"], dtype=np.float64),
            float(d["out_offset"]),
            float(d["out_scale"]),
        )
