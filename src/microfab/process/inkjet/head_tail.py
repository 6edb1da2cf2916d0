"""Head and tail of a forming drop: what a person comparing frames with the seed's looks at.

Seed 003 part 1 (``../shared/seeds/003_4915b267b12a78d4.txt``, Fig. 3 "Features of a
forming droplet") describes the jet as "a ligament with a front head": a bulbous head
leading a thin tail (the ligament) that is still joined to the nozzle or already free.
Front-pinching needs that shape: the head can only pinch off behind itself if a neck
separates it from a thinner ligament. A jet pushed out as a plug (a fat slug without a
distinct head) can only break at its root. These measures tell the two apart, on the
silhouettes of a simulation (:class:`~microfab.process.inkjet.silhouette.Silhouette`)
and on silhouettes measured from camera frames alike:

* **head**: walking back from the leading tip of the body that carries it, the head ends
  where the radius first falls below ``neck_fraction`` (default 0.7) of the largest
  radius met so far; its radius is that largest radius.
* **neck**: walking back from the end of the head, the first local minimum of the radius
  (confirmed where the radius rises 15 % above the least seen so far,
  ``NECK_TOLERANCE``, or the body ends); on a flat stretch, the point nearest the head
  within that 15 % (on a uniform tail, where the head ends). A second neck nearer the
  nozzle belongs to the tail.
* **tail**: from the neck back to the body's tail end (the nozzle exit for a body still
  attached, its free tail tip otherwise); its length and its mean radius.
* **distinct head**: a neck thinner than ``neck_fraction`` of the head radius with a tail
  behind it at least as long as the head's radius. A plug has no neck (tail length 0); a
  slug necked only at its root has a tail shorter than that: neither has a distinct head.
* **ligament thinning rate** (:func:`thinning_rate`): over the frames before a breakup,
  the least-squares slope of the tail's thinnest radius against time, as a speed (m/s)
  and as an exponential rate (1/s).

The 0.7 threshold is an assumption (the seed gives no numeric definition): a head that
is less than 1/0.7 ≈ 1.4 times as wide as the ligament behind it is not seen as a head in
the seed's frames.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.process.inkjet.silhouette import Silhouette

__all__ = ["NECK_FRACTION", "HeadTail", "Thinning", "head_and_tail", "thinning_rate"]

#: Radius ratio below which the jet behind the head counts as a neck (assumption, above).
NECK_FRACTION = 0.7
#: A local minimum of the radius counts once the radius rises this fraction above it, and
#: the neck is the point nearest the head within it (assumption: measured radii carry
#: about a tenth of a pixel of noise, 5 % of a 4 µm ligament at 2 µm/pixel).
NECK_TOLERANCE = 0.15


@dataclass(frozen=True, kw_only=True)
class HeadTail:
    """Head and tail of the leading body of one silhouette.

    Attributes
    ----------
    time_s : float
        Time of the silhouette, s.
    tip_z_m : float
        Leading tip, m downstream of the nozzle exit.
    head_radius_m : float
        Largest radius of the head, m.
    head_length_m : float
        Tip to the end of the head, m.
    neck_z_m, neck_radius_m : float
        Position (m) and radius (m) of the neck behind the head.
    tail_length_m : float
        Neck to the tail end of the body, m (0 without a distinct head).
    tail_mean_radius_m : float
        Volume-equivalent mean radius of the tail, m (0 without a tail).
    tail_min_radius_m : float
        Thinnest radius of the tail (the neck included), m; the nozzle end and free tips
        (radius 0) are left out.
    attached : bool
        Whether the body carrying the head is still joined to the nozzle.
    distinct_head : bool
        Whether a neck thinner than ``NECK_FRACTION`` of the head radius separates the head
        from a tail at least as long as the head's radius.
    """

    time_s: float
    tip_z_m: float
    head_radius_m: float
    head_length_m: float
    neck_z_m: float
    neck_radius_m: float
    tail_length_m: float
    tail_mean_radius_m: float
    tail_min_radius_m: float
    attached: bool
    distinct_head: bool

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready values, units in the keys."""
        return {
            "time_s": self.time_s,
            "tip_z_m": self.tip_z_m,
            "head_radius_m": self.head_radius_m,
            "head_length_m": self.head_length_m,
            "neck_z_m": self.neck_z_m,
            "neck_radius_m": self.neck_radius_m,
            "tail_length_m": self.tail_length_m,
            "tail_mean_radius_m": self.tail_mean_radius_m,
            "tail_min_radius_m": self.tail_min_radius_m,
            "attached": self.attached,
            "distinct_head": self.distinct_head,
        }


def _check_fraction(neck_fraction: float) -> float:
    if not 0.0 < neck_fraction < 1.0:
        raise ValueError(f"neck_fraction must lie in (0, 1), got {neck_fraction}")
    return float(neck_fraction)


def _min_positive(r: np.ndarray) -> float:
    """Thinnest radius, free tips (radius 0) left out; 0 if nothing is left."""
    pos = r[r > 0.0]
    return float(pos.min()) if pos.size else 0.0


def head_and_tail(
    silhouette: Silhouette, *, neck_fraction: float = NECK_FRACTION
) -> HeadTail | None:
    """Measure the head and the tail of the body that leads (module docstring).

    Parameters
    ----------
    silhouette : Silhouette
        Bodies at one instant (simulated, or measured from a frame).
    neck_fraction : float, optional
        Radius ratio that ends the head and bounds the neck (0 < f < 1).

    Returns
    -------
    HeadTail or None
        None if there is no liquid out of the nozzle.

    Examples
    --------
    >>> import numpy as np
    >>> z = np.linspace(0.0, 400e-6, 401)
    >>> r = np.where(z > 340e-6, np.sqrt(np.clip(30e-6**2 - (z - 370e-6)**2, 0, None)), 8e-6)
    >>> r[0] = 60e-6
    >>> ht = head_and_tail(Silhouette(time_s=0.0, bodies=((z, r),), nozzle_radius_m=60e-6))
    >>> ht.distinct_head, round(ht.head_radius_m * 1e6), round(ht.tail_length_m * 1e6)
    (True, 30, 341)
    """
    f = _check_fraction(neck_fraction)
    bodies = [b for b in silhouette.bodies if float(np.max(b[1])) > 0.0]
    if not bodies:
        return None
    z, r = max(bodies, key=lambda b: float(b[0][-1]))
    attached = bool(z[0] <= 1e-12 and r[0] > 0.0)
    # walk back from the tip: the head ends where r < f · (largest radius so far)
    rb = r[::-1]
    run_max = np.maximum.accumulate(rb)
    below = np.flatnonzero((rb < f * run_max) & (run_max > 0.0))
    if below.size == 0:
        # a plug: no neck anywhere behind the widest point
        return HeadTail(
            time_s=silhouette.time_s,
            tip_z_m=float(z[-1]),
            head_radius_m=float(r[1:].max() if attached else r.max()),
            head_length_m=float(z[-1] - z[0]),
            neck_z_m=float(z[0]),
            neck_radius_m=float(r[0]),
            tail_length_m=0.0,
            tail_mean_radius_m=0.0,
            tail_min_radius_m=_min_positive(r[1:-1]),
            attached=attached,
            distinct_head=False,
        )
    k_end = r.size - 1 - int(below[0])  # first index (from the nozzle side) out of the head
    head_r = float(run_max[below[0]])
    # the neck: walking back from the head's end, the first local minimum of the radius
    # (confirmed once the radius rises NECK_TOLERANCE above the least seen so far, or the
    # body ends); on a flat stretch, the point nearest the head within that tolerance
    behind = r[: k_end + 1][::-1]  # from the head's end back towards the tail end
    pos = np.where(behind > 0.0, behind, np.inf)  # a free tail tip is not a neck
    least = np.minimum.accumulate(pos)
    rises = np.flatnonzero(pos > (1.0 + NECK_TOLERANCE) * least)
    stop = int(rises[0]) if rises.size else pos.size
    seg = pos[:stop]
    if np.isfinite(seg).any():
        near = np.flatnonzero(seg <= (1.0 + NECK_TOLERANCE) * float(seg.min()))
        k_neck = k_end - int(near[0])
    else:
        k_neck = k_end
    tail_z, tail_r = z[: k_neck + 1], r[: k_neck + 1]
    tail_len = float(z[k_neck] - z[0])
    if tail_len > 0.0 and tail_z.size >= 2:
        vol = float(np.sum(0.5 * (tail_r[1:] ** 2 + tail_r[:-1] ** 2) * np.diff(tail_z)))
        mean_r = math.sqrt(vol / tail_len)
    else:
        mean_r = 0.0
    return HeadTail(
        time_s=silhouette.time_s,
        tip_z_m=float(z[-1]),
        head_radius_m=head_r,
        distinct_head=tail_len >= head_r,
        head_length_m=float(z[-1] - z[k_end]),
        neck_z_m=float(z[k_neck]),
        neck_radius_m=float(r[k_neck]),
        tail_length_m=tail_len,
        tail_mean_radius_m=mean_r,
        tail_min_radius_m=_min_positive(tail_r[1:]),
        attached=attached,
    )


@dataclass(frozen=True, kw_only=True)
class Thinning:
    """Thinning of the ligament before a breakup.

    Attributes
    ----------
    speed_m_s : float
        ``-d r_min / dt``, m/s (positive while thinning).
    rate_per_s : float
        ``-d ln r_min / dt``, 1/s.
    frames : int
        Silhouettes used.
    """

    speed_m_s: float
    rate_per_s: float
    frames: int


def thinning_rate(
    silhouettes: Sequence[Silhouette],
    before_s: float,
    *,
    window_s: float = 40e-6,
    neck_fraction: float = NECK_FRACTION,
) -> Thinning | None:
    """Least-squares thinning of the thinnest ligament radius before ``before_s``.

    The ligament's radius in each silhouette is the tail's thinnest radius
    (:func:`head_and_tail`); for a plug, the thinnest radius of the leading body. Frames
    from ``before_s - window_s`` up to (not including) ``before_s`` are used.

    Parameters
    ----------
    silhouettes : sequence of Silhouette
        In time order.
    before_s : float
        End of the window (typically the breakup time), s.
    window_s : float, optional
        Length of the window, s (> 0).
    neck_fraction : float, optional
        As in :func:`head_and_tail`.

    Returns
    -------
    Thinning or None
        None with fewer than two usable frames.
    """
    if not window_s > 0.0:
        raise ValueError(f"window_s must be > 0 s, got {window_s}")
    t, rmin = [], []
    for s in silhouettes:
        if not before_s - window_s <= s.time_s < before_s:
            continue
        ht = head_and_tail(s, neck_fraction=neck_fraction)
        if ht is None or ht.tail_min_radius_m <= 0.0:
            continue
        t.append(s.time_s)
        rmin.append(ht.tail_min_radius_m)
    if len(t) < 2:
        return None
    tt, rr = np.asarray(t), np.asarray(rmin)
    speed = -float(np.polyfit(tt, rr, 1)[0])
    rate = -float(np.polyfit(tt, np.log(rr), 1)[0])
    return Thinning(speed_m_s=speed, rate_per_s=rate, frames=len(t))
