"""Learning on machines it never saw: a seeded family of stabilised loops (none of them
the twin), five paths, the ILC in process (`learn`) and through files (`ilc_step`).

Every loop and path must either converge (RMS error at least 10x lower within 12 trials,
on every axis) or be refused on the first call with a one-line `ConvergenceError`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import control
from microfab.control.base import LTIController
from microfab.control.ilc import ConvergenceError, FrequencyILC
from microfab.geometry.text import text_layer
from microfab.io.trace import read_columns, write_columns
from microfab.machines.files import ilc_step
from microfab.machines.galvo.machine import GALVO_LIMITS
from microfab.machines.learning import learn
from microfab.machines.simulated import EncoderNoise, SimulatedMachine
from microfab.plants.base import LTIPlant
from microfab.plants.lti import DiscreteLTI, discretize, with_input_delay
from microfab.trajectory.periodic import square_scan

FS = 200_000.0  # assumed: resolves modes up to 40 kHz
DT = 1 / FS
FEATURES_PER_S = 200  # N = 1000 samples per period
N = round(FS / FEATURES_PER_S)
AXES = ("x", "y")
NOISE_RMS = 0.4e-3  # V, the encoder noise of the reported defect
ITERATIONS = 12
N_LOOPS = 8
NMP_LOOP = 3  # this loop's plant has a right-half-plane zero


@dataclass(frozen=True)
class AxisLoop:
    plant: DiscreteLTI
    controller: DiscreteLTI
    about: str


def _axis_loop(rng: np.random.Generator, nmp: bool) -> AxisLoop:
    """A plant drawn from the family and a lead controller placing the crossover; drawn
    again until the discrete closed loop (true gain and delay included) is stable."""
    s = control.tf("s")
    while True:
        fp = float(np.exp(rng.uniform(np.log(20.0), np.log(200.0))))  # rigid-body pole
        fc = float(np.exp(rng.uniform(np.log(500.0), np.log(3000.0))))  # crossover
        wp, wc = 2 * np.pi * fp, 2 * np.pi * fc
        plant = wp / (s * (s + wp))
        modes = [
            (rng.uniform(5e3, 40e3), rng.uniform(0.01, 0.05)) for _ in range(rng.integers(1, 4))
        ]
        for fm, zeta in modes:
            wm = 2 * np.pi * fm
            plant = plant * wm**2 / (s**2 + 2 * zeta * wm * s + wm**2)
        fz = float(rng.uniform(3.0, 6.0) * fc)
        if nmp:
            plant = plant * (1 - s / (2 * np.pi * fz))
        lead = (1 + s / (wc / 3)) / (1 + s / (3 * wc))  # about 53 degrees at wc
        k = 1.0 / abs(control.evalfr(plant * lead, 1j * wc))  # on the nominal plant
        gain_error = float(rng.uniform(0.7, 1.3))
        delay = int(rng.integers(1, 4))
        p = with_input_delay(discretize(gain_error * plant, DT), delay)
        c = discretize(k * lead, DT, "tustin")
        loop = control.feedback(
            control.ss(p.A, p.B, p.C, p.D, DT) * control.ss(c.A, c.B, c.C, c.D, DT), 1
        )
        if np.max(np.abs(loop.poles())) < 1.0 - 1e-7:
            about = (
                f"pole {fp:.0f} Hz, crossover {fc:.0f} Hz, modes "
                + ", ".join(f"{f / 1e3:.1f} kHz/{z:.3f}" for f, z in modes)
                + f", gain x{gain_error:.2f}, delay {delay}"
                + (f", RHP zero {fz:.0f} Hz" if nmp else "")
            )
            return AxisLoop(plant=p, controller=c, about=about)


def make_machine(index: int) -> tuple[SimulatedMachine, str]:
    """Loop ``index`` of the family: two axes drawn independently, encoder noise on."""
    rng = np.random.default_rng(1000 + index)
    loops = [_axis_loop(rng, nmp=index == NMP_LOOP) for _ in AXES]
    machine = SimulatedMachine(
        [LTIPlant(a.plant) for a in loops],
        [LTIController(a.controller) for a in loops],
        EncoderNoise(rms=(NOISE_RMS,) * len(AXES), seed=index),
        axes=AXES,
        limits=GALVO_LIMITS,
    )
    return machine, "; ".join(f"{a}: {lp.about}" for a, lp in zip(AXES, loops, strict=True))


def _at_constant_speed(points: np.ndarray) -> np.ndarray:
    closed = np.vstack([points, points[:1]])
    s = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))))
    q = np.arange(N) / N * s[-1]
    return np.column_stack([np.interp(q, s, closed[:, a]) for a in range(2)])


def _letter() -> np.ndarray:
    outline = text_layer("S", height=1.0).contours[0]
    p = outline.point(np.arange(N) / N * outline.length)
    p = p - p.mean(axis=0)
    return 0.8 * p / np.abs(p).max()


PATHS = {
    "offset square": lambda: square_scan(FEATURES_PER_S, (0.6, 0.6), FS) + np.array([0.3, -0.2]),
    "triangle": lambda: _at_constant_speed(np.array([[-1.0, -1.0], [1.0, -1.0], [0.0, 1.0]])),
    "circle": lambda: (
        0.8
        * np.column_stack(
            [np.cos(2 * np.pi * np.arange(N) / N), np.sin(2 * np.pi * np.arange(N) / N)]
        )
    ),
    "lissajous": lambda: (
        0.8
        * np.column_stack(
            [
                np.sin(3 * 2 * np.pi * np.arange(N) / N),
                np.sin(2 * 2 * np.pi * np.arange(N) / N + 0.5),
            ]
        )
    ),
    "letter S": _letter,
}


@pytest.fixture(scope="module")
def machines() -> list[tuple[SimulatedMachine, str]]:
    return [make_machine(i) for i in range(N_LOOPS)]


def _judge(rms: np.ndarray, about: str, path: str) -> None:
    rms = np.asarray(rms)
    assert rms.shape == (ITERATIONS, len(AXES))
    assert np.all(rms[-1] <= rms[0] / 10), f"{path} on {about}: RMS {rms[0]} -> {rms[-1]}"


def test_the_family_is_what_it_says(machines) -> None:
    assert len(machines) >= 8
    abouts = [a for _, a in machines]
    assert sum("RHP zero" in a for a in abouts) >= 1
    assert len(set(abouts)) == len(abouts)


@pytest.mark.parametrize("path", list(PATHS))
@pytest.mark.parametrize("index", range(N_LOOPS))
def test_learns_in_process(machines, index: int, path: str) -> None:
    machine, about = machines[index]
    ref = PATHS[path]()
    ilc = FrequencyILC(ref, DT, AXES)
    try:
        learn(machine, ilc, iterations=ITERATIONS)
    except ConvergenceError as exc:  # a refusal is allowed on the first call only
        assert ilc.iteration == 0 and "\n" not in str(exc)
        return
    _judge(ilc.rms_history, about, path)
    assert ilc.events == [], ilc.events


@pytest.mark.parametrize("path", list(PATHS))
@pytest.mark.parametrize("index", range(N_LOOPS))
def test_learns_through_files(machines, index: int, path: str, tmp_path: Path) -> None:
    machine, about = machines[index]
    ref = PATHS[path]()
    u = ref.copy()
    rms = []
    for i in range(ITERATIONS):
        meas = machine.run(u)
        cols = {"time": np.arange(N) * DT}
        for a, name in enumerate(AXES):
            cols[f"reference_{name}"] = ref[:, a]
            cols[f"input_{name}"] = u[:, a]
            cols[f"output_{name}"] = meas.output[:, a]
        trial = tmp_path / f"trial{i}.csv"
        write_columns(trial, cols)
        try:
            rep = ilc_step(trial, tmp_path / "state", tmp_path / "next.csv")
        except ConvergenceError as exc:
            assert i == 0 and "\n" not in str(exc)
            return
        rms.append([rep.rms[a] for a in AXES])
        nxt = read_columns(tmp_path / "next.csv")
        u = np.column_stack([nxt[f"input_{a}"] for a in AXES])
    _judge(np.array(rms), about, path)
