"""Printhead plant: 1D lossy squeeze-tube acoustics, drive voltage -> orifice flow.

A MicroFab dispenser (seed 003 part 1, ``../shared/seeds/003_4915b267b12a78d4.txt``,
"Method": 120 µm orifice) is a liquid-filled glass capillary squeezed by a tubular PZT.
The capillary runs from the reservoir connection (``z = 0``) to the tapered orifice
(``z = L``). This module models it as linear one-dimensional acoustics in the channel,
a lumped nozzle and a lumped meniscus, written as one continuous LTI state-space model
whose input is the voltage slope ``dV/dt`` and whose output is the nozzle flow ``q_n``.

Channel (``0 < z < L``, cross-section ``A = π a²``, volume flow ``q`` positive towards
the nozzle, pressure ``p`` relative to the reservoir)::

    (A / (ρ c²)) ∂p/∂t = s(z, t) - ∂q/∂z                  (mass, per unit length)
    (ρ / A) ∂q/∂t      = -∂p/∂z - R' q,   R' = 8 η / (π a⁴) (momentum, per unit length)

``c`` is the effective wave speed of the liquid-filled compliant tube (liquid and wall
compressibility together), ``R'`` the quasi-steady laminar Poiseuille resistance per
unit length (Pa s/m⁴; multiplying the second line by ``A`` gives the equivalent form
``ρ ∂q/∂t = -A ∂p/∂z - (8 π η / A) q``). The source ``s`` [m²/s] is the rate of volume
displaced per unit length by the PZT, spread uniformly over the actuated section
``[z0, z1]`` (``actuator_start_fraction``, ``actuator_end_fraction`` of ``L``)::

    s(z, t) = -(gain / (z1 - z0)) dV/dt       for z0 < z < z1 (0 elsewhere)

with ``gain`` = `Printhead.gain_m3_per_v` > 0. **Sign convention**: a positive voltage
*expands* the tube (``positive_voltage_expands=True``, the default), so a rising edge
draws liquid in and a falling edge squeezes it out. This is the "fill-before-fire"
operation of squeeze-mode dispensers: the rise of the positive dwell pulse of the seed's
bipolar waveform creates an under-pressure wave, which the reservoir end reflects as an
over-pressure wave; the fall, timed one acoustic travel time ``L / c`` later
(Bogy & Talke 1984), squeezes the tube while that wave passes and ejects the main jet
during the echo plateau. With ``positive_voltage_expands=False`` the source changes sign
(positive ``dV/dt`` contracts the tube).

Reservoir end (``z = 0``)::

    p(0, t) = -Z_in q(0, t),    Z_in = r ρ c / A,  r = inlet_impedance_ratio >= 0

``r = 0`` is the ideal pressure-release end ``p = 0``. The default ``r = 0.3`` is an
ASSUMPTION (see `Printhead`): with ``p = 0`` and Poiseuille friction alone the model
rings for milliseconds (decay rates of 110-160 1/s for water), while squeeze-mode
dispensers settle within a few hundred µs.

Nozzle end (``z = L``): the nozzle (radius ``R``, effective length ``l``) is a lumped
inertance and Poiseuille resistance in series with the meniscus compliance::

    (M_n) dq_n/dt = p(L) - R_n q_n - V_m / C_m,    dV_m/dt = q_n
    M_n = ρ l / (π R²),   R_n = 8 η l / (π R⁴),   C_m = π R⁴ / (8 σ)

``V_m`` is the liquid volume pushed out of the orifice plane. The meniscus compliance
comes from a small spherical cap of height ``h`` over the orifice of radius ``R``: its
volume is ``V_m ≈ π R² h / 2`` and its radius of curvature ``R_c ≈ R² / (2 h)`` (both to
first order in ``h / R``), so the Laplace pressure is
``p = 2 σ / R_c = 4 σ h / R² = 8 σ V_m / (π R⁴)``, i.e. ``C_m = π R⁴ / (8 σ)``.
Entrance and exit kinetic (Bernoulli) losses of the nozzle are ignored, and so is the
frequency dependence of the wall friction (the oscillatory boundary layer raises the
losses above the quasi-steady Poiseuille value when the Womersley number is large). The
coupling is one-way: the jet outside the nozzle does not load the acoustics, so once
the ejected volume exceeds a hemisphere (``2 π R³ / 3``) the meniscus term is only a
linear stand-in for the real free surface.

Discretisation: finite volumes on a staggered grid, ``cells`` pressure cells of length
``Δz = L / cells`` with pressures at the cell centres and flows at the faces; face 0
sits on the reservoir end (half-cell inertance and resistance to the boundary), the last
face is the nozzle flow ``q_n`` (its inertance includes the half cell next to the
nozzle). The state is ``[p_0..p_{N-1}, q_0..q_{N-1}, q_n, V_m]`` (Pa, m³/s, m³). Any
drive with a ``voltage(t_s)`` method (`DriveSignal`) can be applied; the trapezoidal
waveforms of :mod:`microfab.trajectory.waveform` are piecewise linear, so their slope is
piecewise constant and the zero-order-hold discretisation is exact when the
sample grid hits the corners (it does for the seed's waveform at the default 50 ns).
The response is the convolution of the input with the ZOH Markov parameters, evaluated
from the eigen-decomposition of the (diagonally balanced) system matrix, or by matrix
exponential and repeated squaring where the eigenvectors are ill-conditioned.

Character of the default model: the meniscus compliance (``≈ 7e-17 m³/Pa`` for water)
is about 14 times that of the liquid in the channel, so acoustically the nozzle end is
nearly *open*: the channel modes sit close to the half-wave series ``n c / (2 L)``
(16.7 kHz, 33 kHz, ...), below which the liquid column swings on the meniscus spring at
about 1.1-1.4 kHz. In the closed-nozzle limit (tiny orifice) they become the
quarter-wave series ``(2 n - 1) c / (4 L)``.
The orifice flow record (`NozzleFlow`) is in :mod:`.printhead_flow` and the ZOH Markov
parameters of the response in :mod:`.printhead_markov`; both are re-exported here.

References
----------
Seed 003 part 1, "Method" and Table 1. D. B. Bogy & F. E. Talke, "Experimental and
theoretical study of wave propagation phenomena in drop-on-demand ink jet devices",
IBM J. Res. Dev. 28 (1984) 314 (optimal dwell = acoustic travel time ``L / c``).
H. Wijshoff, "The dynamics of the piezo inkjet printhead operation", Phys. Rep. 491
(2010) 77 (channel acoustics, nozzle inertance and resistance, meniscus).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import scipy.linalg
import scipy.signal

from microfab.core.threads import single_threaded
from microfab.core.validate import check_int, check_nonnegative, check_positive
from microfab.plants.printhead_flow import NozzleFlow
from microfab.plants.printhead_markov import _MAX_MODAL_CONDITION as _MAX_MODAL_CONDITION
from microfab.plants.printhead_markov import _MODAL_BLOCK as _MODAL_BLOCK
from microfab.plants.printhead_markov import _markov_doubling, _markov_modal

__all__ = [
    "SEED003_DWELL_S",
    "DriveSignal",
    "NozzleFlow",
    "Printhead",
    "calibrate_gain",
    "nozzle_flow",
    "printhead_state_space",
]

#: Dwell time of the seed's bipolar drive, s. It sets the default channel length (Bogy &
#: Talke: the optimal dwell is the acoustic travel time ``L / c``) and is re-exported by
#: :mod:`microfab.trajectory.waveform` as a default of the waveform.
SEED003_DWELL_S = 30e-6  # seed 003 part 1, Table 1

#: Effective wave speed, m/s. Assumption: the compliant glass/PZT wall lowers the speed of
#: sound of water (about 1480 m/s) to roughly 1200 m/s (Korteweg-type correction).
_WAVE_SPEED_M_S = 1200.0


class DriveSignal(Protocol):
    """A drive voltage that can be evaluated at any time (e.g. a trapezoidal waveform).

    :class:`microfab.trajectory.waveform.Waveform` is one; any object with this method
    will do (a sampled record wrapped in ``numpy.interp``, a test stand-in).
    """

    def voltage(self, t_s: np.ndarray | float) -> np.ndarray:
        """Drive voltage in V at the times ``t_s`` (s, any shape); same shape as ``t_s``."""
        ...


@dataclass(frozen=True, kw_only=True)
class Printhead:
    """Geometry and actuator of a squeeze-tube (MicroFab-type) dispenser.

    Attributes
    ----------
    nozzle_radius_m : float
        Orifice radius ``R`` in m, > 0 and smaller than the channel radius (default
        60 µm: the seed's 120 µm orifice, seed 003 part 1, "Method").
    nozzle_length_m : float
        Effective length ``l`` of the tapered orifice for its inertance and resistance in
        m, > 0 (default 100 µm; assumption: the last part of the taper, where the radius
        is close to ``R``, dominates both, and its length is of the order of the orifice
        diameter).
    channel_radius_m : float
        Inner radius ``a`` of the glass capillary in m, > 0 (default 0.25 mm; assumption:
        a 0.5 mm bore, typical of the glass capillaries of MicroFab dispensers).
    wave_speed_m_s : float
        Effective speed of sound ``c`` in the liquid-filled tube in m/s, > 0 (default
        1200 m/s; assumption: water's 1480 m/s lowered by the wall compliance).
    channel_length_m : float
        Acoustic length ``L`` from the reservoir end to the orifice in m, > 0 (default
        ``1200 m/s × 30 µs = 36 mm``: chosen so that the seed's 30 µs dwell, seed 003
        part 1 Table 1, is the Bogy & Talke optimum ``L / c``).
    actuator_start_fraction, actuator_end_fraction : float
        Part of the channel covered by the PZT, as fractions of ``L`` from the reservoir
        end, ``0 <= start < end <= 1`` (defaults 0.2 and 0.8; assumption: the PZT sleeve
        covers the middle of the capillary, leaving the inlet fitting and the tapered
        tip free).
    inlet_impedance_ratio : float
        Acoustic resistance of the reservoir connection in units of the channel's
        characteristic impedance ``ρ c / A``, >= 0; 0 is the ideal pressure-release end
        ``p = 0``. Default 0.3 (assumption): the inlet still reflects with inversion
        (reflection coefficient ``(r - 1) / (r + 1) = -0.54``), as the Bogy & Talke
        operation needs, but lets about 70 % of the incident wave energy leave into the
        supply line, so that the residual ringing dies out within a few hundred µs as it
        does in practice; with ``p = 0`` and Poiseuille friction alone it would not.
    positive_voltage_expands : bool
        Sign convention of the actuator (default True: a positive voltage expands the
        tube, fill-before-fire; see the module docstring).
    gain_m3_per_v : float
        Volume displaced by the PZT per volt in m³/V, > 0. The default 9.67e-15 m³/V is
        the calibrated value rounded to three digits
        (:func:`microfab.process.inkjet.dispenser.default_printhead` recomputes it
        exactly): the gain that gives a 6 m/s peak orifice velocity
        (``REFERENCE_PEAK_VELOCITY_M_S`` there) with the seed's 50 V bipolar waveform and
        water. For comparison, a free thin PZT tube (``d31 ≈
        -270 pm/V``, mean radius 0.5 mm, wall 0.25 mm, 22 mm long) would displace about
        ``2 π r² l |d31| / t ≈ 4e-14 m³/V``; the glass wall and the liquid take part of it.
    cells : int
        Number of finite-volume pressure cells along the channel, >= 4 (default 60: the
        first modes are resolved to better than 0.1 % in frequency).

    Examples
    --------
    >>> head = Printhead()
    >>> round(head.channel_length_m / head.wave_speed_m_s * 1e6, 9)
    30.0
    """

    nozzle_radius_m: float = 60e-6  # seed 003 part 1, "Method": 120 µm orifice
    nozzle_length_m: float = 100e-6  # assumption: effective length of the taper's tip
    channel_radius_m: float = 0.25e-3  # assumption: 0.5 mm bore glass capillary
    wave_speed_m_s: float = _WAVE_SPEED_M_S  # assumption: wall-softened water
    # Bogy & Talke: L = c × dwell, with the dwell of seed 003 part 1, Table 1
    channel_length_m: float = _WAVE_SPEED_M_S * SEED003_DWELL_S
    actuator_start_fraction: float = 0.2  # assumption: PZT sleeve on the middle part
    actuator_end_fraction: float = 0.8  # assumption: PZT sleeve on the middle part
    inlet_impedance_ratio: float = 0.3  # assumption: partly absorbing reservoir connection
    positive_voltage_expands: bool = True  # fill-before-fire convention
    gain_m3_per_v: float = 9.67e-15  # calibrated (process.inkjet.dispenser), rounded
    cells: int = 60

    def __post_init__(self) -> None:
        for name in (
            "nozzle_radius_m",
            "nozzle_length_m",
            "channel_radius_m",
            "channel_length_m",
        ):
            check_positive(name, getattr(self, name), "m")
        check_positive("wave_speed_m_s", self.wave_speed_m_s, "m/s")
        check_positive("gain_m3_per_v", self.gain_m3_per_v, "m³/V")
        check_nonnegative("inlet_impedance_ratio", self.inlet_impedance_ratio, "(dimensionless)")
        if not self.nozzle_radius_m < self.channel_radius_m:
            raise ValueError(
                f"nozzle_radius_m ({self.nozzle_radius_m} m) must be smaller than "
                f"channel_radius_m ({self.channel_radius_m} m)"
            )
        start, end = self.actuator_start_fraction, self.actuator_end_fraction
        if not (math.isfinite(start) and math.isfinite(end) and 0.0 <= start < end <= 1.0):
            raise ValueError(
                "actuator fractions must satisfy 0 <= start < end <= 1 (fractions of "
                f"channel_length_m), got start {start} and end {end} (dimensionless)"
            )
        check_int("cells", self.cells, 4, "(count)")

    @property
    def travel_time_s(self) -> float:
        """One-way acoustic travel time ``L / c`` in s (Bogy & Talke's optimal dwell)."""
        return self.channel_length_m / self.wave_speed_m_s

    @property
    def nozzle_area_m2(self) -> float:
        """Orifice cross-section ``π R²`` in m²."""
        return math.pi * self.nozzle_radius_m**2


def _check_fluid(density_kg_m3: float, viscosity_pa_s: float, surface_tension_n_m: float) -> None:
    check_positive("density_kg_m3", density_kg_m3, "kg/m³")
    check_nonnegative("viscosity_pa_s", viscosity_pa_s, "Pa s")
    check_nonnegative("surface_tension_n_m", surface_tension_n_m, "N/m")


def printhead_state_space(
    printhead: Printhead,
    *,
    density_kg_m3: float,
    viscosity_pa_s: float,
    surface_tension_n_m: float,
    meniscus_input: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Continuous state-space model from ``dV/dt`` to the nozzle flow ``q_n``.

    Parameters
    ----------
    printhead : Printhead
        Geometry, actuator and discretisation.
    density_kg_m3 : float
        Liquid density ``ρ`` in kg/m³, > 0.
    viscosity_pa_s : float
        Dynamic viscosity ``η`` in Pa s, >= 0 (0 gives the lossless limit, apart from the
        inlet resistance).
    surface_tension_n_m : float
        Surface tension ``σ`` in N/m, >= 0 (0 removes the meniscus stiffness).
    meniscus_input : bool, optional
        Replace the lumped meniscus spring ``V_m / C_m`` by a second input, the meniscus
        pressure ``p_m`` in Pa acting on the nozzle flow (for a model of the meniscus
        outside this one, :mod:`microfab.plants.printhead_coupled`); ``surface_tension_n_m``
        is then not used. Default False.

    Returns
    -------
    A : numpy.ndarray
        System matrix, shape (2 N + 2, 2 N + 2), 1/s in consistent SI units, with the
        state ``[p_0..p_{N-1} (Pa), q_0..q_{N-1} (m³/s), q_n (m³/s), V_m (m³)]`` and
        ``N = printhead.cells``.
    B : numpy.ndarray
        Input matrix, shape (2 N + 2, 1); the input is ``dV/dt`` in V/s. With
        ``meniscus_input`` shape (2 N + 2, 2), the second input ``p_m`` in Pa.
    C : numpy.ndarray
        Output matrix, shape (1, 2 N + 2); the output is ``q_n`` in m³/s (positive out of
        the nozzle).
    D : numpy.ndarray
        Feed-through, shape (1, 1) (or (1, 2) with ``meniscus_input``), zero.

    Raises
    ------
    ValueError
        If a fluid property is out of range.

    Examples
    --------
    >>> A, B, C, D = printhead_state_space(
    ...     Printhead(cells=10), density_kg_m3=1000.0, viscosity_pa_s=1e-3,
    ...     surface_tension_n_m=0.072)
    >>> A.shape, B.shape, C.shape, D.shape
    ((22, 22), (22, 1), (1, 22), (1, 1))
    """
    _check_fluid(density_kg_m3, viscosity_pa_s, surface_tension_n_m)
    rho, eta, sigma = density_kg_m3, viscosity_pa_s, surface_tension_n_m
    n = printhead.cells
    length = printhead.channel_length_m
    dz = length / n
    area = math.pi * printhead.channel_radius_m**2
    radius_n = printhead.nozzle_radius_m
    c = printhead.wave_speed_m_s

    cell_compliance = area * dz / (rho * c * c)  # m³/Pa
    face_inertance = rho * dz / area  # kg/m⁴
    friction = 8.0 * eta / (math.pi * printhead.channel_radius_m**4)  # Pa s/m⁴ per m
    inlet_resistance = printhead.inlet_impedance_ratio * rho * c / area  # Pa s/m³
    nozzle_inertance = rho * printhead.nozzle_length_m / (math.pi * radius_n**2)
    nozzle_resistance = 8.0 * eta * printhead.nozzle_length_m / (math.pi * radius_n**4)
    meniscus_stiffness = 8.0 * sigma / (math.pi * radius_n**4)  # 1 / C_m, Pa/m³
    if meniscus_input:
        meniscus_stiffness = 0.0  # the meniscus is modelled outside, through input 2

    nx = 2 * n + 2
    ip = np.arange(n)  # cell pressures
    iq = n + np.arange(n + 1)  # face flows q_0..q_{N-1}, then q_n at index 2N
    iv = 2 * n + 1  # meniscus volume
    a_mat = np.zeros((nx, nx))
    # mass: C_cell dp_i/dt = q_i - q_{i+1} + S_i u
    a_mat[ip, iq[:-1]] = 1.0 / cell_compliance
    a_mat[ip, iq[1:]] = -1.0 / cell_compliance
    # momentum, inner faces j = 1..N-1: M dq_j/dt = p_{j-1} - p_j - R' dz q_j
    j = np.arange(1, n)
    a_mat[iq[j], ip[j - 1]] = 1.0 / face_inertance
    a_mat[iq[j], ip[j]] = -1.0 / face_inertance
    a_mat[iq[j], iq[j]] = -friction * dz / face_inertance
    # reservoir face: (M/2) dq_0/dt = -Z_in q_0 - p_0 - R' dz/2 q_0
    m0 = face_inertance / 2.0
    a_mat[iq[0], ip[0]] = -1.0 / m0
    a_mat[iq[0], iq[0]] = -(inlet_resistance + friction * dz / 2.0) / m0
    # nozzle: (M_n + M/2) dq_n/dt = p_{N-1} - (R_n + R' dz/2) q_n - V_m / C_m
    mt = nozzle_inertance + face_inertance / 2.0
    a_mat[iq[n], ip[n - 1]] = 1.0 / mt
    a_mat[iq[n], iq[n]] = -(nozzle_resistance + friction * dz / 2.0) / mt
    a_mat[iq[n], iv] = -meniscus_stiffness / mt
    a_mat[iv, iq[n]] = 1.0

    # actuator: volume per volt in each cell, from the overlap of cell and PZT section
    z0 = printhead.actuator_start_fraction * length
    z1 = printhead.actuator_end_fraction * length
    left = np.arange(n) * dz
    overlap = np.clip(np.minimum(left + dz, z1) - np.maximum(left, z0), 0.0, None)
    sign = -1.0 if printhead.positive_voltage_expands else 1.0
    b_mat = np.zeros((nx, 2 if meniscus_input else 1))
    b_mat[ip, 0] = sign * printhead.gain_m3_per_v * overlap / (z1 - z0) / cell_compliance
    if meniscus_input:
        b_mat[iq[n], 1] = -1.0 / mt

    c_mat = np.zeros((1, nx))
    c_mat[0, iq[n]] = 1.0
    return a_mat, b_mat, c_mat, np.zeros((1, b_mat.shape[1]))


def _balanced_model(
    printhead: Printhead,
    density_kg_m3: float,
    viscosity_pa_s: float,
    surface_tension_n_m: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, b, c)`` from ``dV/dt`` to the mean orifice velocity, diagonally balanced.

    Pressures (~1e5 Pa), flows (~1e-8 m³/s) and volumes (~1e-13 m³) differ by many orders
    of magnitude; a diagonal similarity brings the entries of ``A`` to similar sizes
    before exponentials and eigenvectors are taken.
    """
    a_mat, b_mat, c_mat, _ = printhead_state_space(
        printhead,
        density_kg_m3=density_kg_m3,
        viscosity_pa_s=viscosity_pa_s,
        surface_tension_n_m=surface_tension_n_m,
    )
    _, (scale, _) = scipy.linalg.matrix_balance(a_mat, permute=False, separate=True)
    a_bal = a_mat / scale[:, None] * scale[None, :]
    b_bal = b_mat[:, 0] / scale
    c_bal = c_mat[0] * scale / printhead.nozzle_area_m2
    return a_bal, b_bal, c_bal


@single_threaded
def nozzle_flow(
    printhead: Printhead,
    drive: DriveSignal,
    *,
    density_kg_m3: float,
    viscosity_pa_s: float,
    surface_tension_n_m: float,
    duration_s: float = 300e-6,
    dt_s: float = 50e-9,
) -> NozzleFlow:
    """Mean orifice velocity produced by a drive voltage, starting from rest.

    Parameters
    ----------
    printhead : Printhead
        Dispenser model.
    drive : DriveSignal
        Drive voltage (e.g. a :class:`microfab.trajectory.waveform.Waveform`), evaluated
        at the sample times; the record starts at ``t = 0`` with the model at rest.
    density_kg_m3 : float
        Liquid density in kg/m³, > 0.
    viscosity_pa_s : float
        Dynamic viscosity in Pa s, >= 0.
    surface_tension_n_m : float
        Surface tension in N/m, >= 0.
    duration_s : float, optional
        Length of the record in s, > 0 (default 300 µs).
    dt_s : float, optional
        Sample spacing in s, > 0 (default 50 ns, which hits every corner of the seed's
        waveform). The record holds the samples ``k dt_s`` up to ``duration_s``.

    Returns
    -------
    NozzleFlow
        Velocity, displacement and the orifice radius.

    Raises
    ------
    ValueError
        If an argument is out of range or the record has fewer than 2 samples.

    Notes
    -----
    The input over ``[t_k, t_{k+1}]`` is the mean slope ``(V(t_{k+1}) - V(t_k)) / dt``,
    which is the exact slope when no corner of the waveform falls inside the step; the
    zero-order-hold model then integrates the continuous model exactly. Corners between
    samples are smeared over one step (the displaced volume is kept exact).

    Examples
    --------
    >>> from microfab.trajectory.waveform import seed003_waveform
    >>> flow = nozzle_flow(Printhead(), seed003_waveform(50.0), density_kg_m3=1000.0,
    ...                    viscosity_pa_s=1e-3, surface_tension_n_m=0.072)
    >>> 1.0 < flow.peak_velocity_m_s < 20.0
    True
    """
    _check_fluid(density_kg_m3, viscosity_pa_s, surface_tension_n_m)
    check_positive("duration_s", duration_s, "s")
    check_positive("dt_s", dt_s, "s")
    n = math.floor(duration_s / dt_s + 1e-9) + 1
    if n < 2:
        raise ValueError(
            f"duration_s ({duration_s} s) must span at least one step of dt_s ({dt_s} s)"
        )
    t = np.arange(n) * dt_s
    u = np.diff(drive.voltage(t)) / dt_s  # mean slope over each step, V/s, shape (n-1,)
    a_bal, b_bal, c_bal = _balanced_model(
        printhead, density_kg_m3, viscosity_pa_s, surface_tension_n_m
    )
    # x_0 = 0 and x_{k+1} = Φ x_k + Γ u_k, so y_k = Σ_{j<k} g_{k-1-j} u_j: a convolution
    # of the input with the Markov parameters g_i = c Φ^i Γ.
    g = _markov_modal(a_bal, b_bal, c_bal, dt_s, n - 1)
    if g is None:
        g = _markov_doubling(a_bal, b_bal, c_bal, dt_s, n - 1)
    velocity = np.zeros(n)
    velocity[1:] = scipy.signal.fftconvolve(g, u)[: n - 1]
    displacement = np.concatenate(([0.0], np.cumsum(0.5 * (velocity[1:] + velocity[:-1]) * dt_s)))
    return NozzleFlow(
        t_s=t,
        velocity_m_s=velocity,
        displacement_m=displacement,
        nozzle_radius_m=printhead.nozzle_radius_m,
    )


def calibrate_gain(
    printhead: Printhead,
    drive: DriveSignal,
    *,
    density_kg_m3: float,
    viscosity_pa_s: float,
    surface_tension_n_m: float,
    target_peak_velocity_m_s: float,
) -> Printhead:
    """Set the actuator gain so that a drive gives a target peak orifice velocity.

    The model is linear in the gain: one run at unit gain (1 m³/V) gives the peak
    velocity per unit gain, and the gain is the ratio of the target to it.

    Parameters
    ----------
    printhead : Printhead
        Dispenser model; everything but ``gain_m3_per_v`` is kept.
    drive : DriveSignal
        Reference drive voltage (e.g. the seed's 50 V bipolar waveform).
    density_kg_m3, viscosity_pa_s, surface_tension_n_m : float
        Reference liquid: kg/m³ (> 0), Pa s (>= 0), N/m (>= 0).
    target_peak_velocity_m_s : float
        Wanted `NozzleFlow.peak_velocity_m_s` in m/s, > 0 (over the default 300 µs
        record of `nozzle_flow`).

    Returns
    -------
    Printhead
        A copy with the calibrated ``gain_m3_per_v``.

    Raises
    ------
    ValueError
        If the target is not positive or the drive produces no outward flow.

    Examples
    --------
    >>> from microfab.trajectory.waveform import seed003_waveform
    >>> head = calibrate_gain(Printhead(), seed003_waveform(50.0), density_kg_m3=1000.0,
    ...                       viscosity_pa_s=1e-3, surface_tension_n_m=0.072,
    ...                       target_peak_velocity_m_s=5.0)
    >>> round(nozzle_flow(head, seed003_waveform(50.0), density_kg_m3=1000.0,
    ...                   viscosity_pa_s=1e-3, surface_tension_n_m=0.072).peak_velocity_m_s, 9)
    5.0
    """
    check_positive("target_peak_velocity_m_s", target_peak_velocity_m_s, "m/s")
    unit = dataclasses.replace(printhead, gain_m3_per_v=1.0)
    peak = nozzle_flow(
        unit,
        drive,
        density_kg_m3=density_kg_m3,
        viscosity_pa_s=viscosity_pa_s,
        surface_tension_n_m=surface_tension_n_m,
    ).peak_velocity_m_s
    if not peak > 0:
        raise ValueError(
            f"the drive gives no outward orifice flow (peak velocity {peak} m/s at unit "
            "gain), so no gain can reach the target"
        )
    return dataclasses.replace(printhead, gain_m3_per_v=target_peak_velocity_m_s / peak)
