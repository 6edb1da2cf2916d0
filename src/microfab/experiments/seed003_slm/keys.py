"""The ``slm-shaping`` job keys that ``microfab slm`` and ``microfab shaper`` options share.

A job-file key and a command-line option that set the same quantity in the same unit are
declared once, here (`microfab.io.job.Key`: type, unit, range), and used by both the job
schema (`microfab.experiments.seed003_slm.job.SCHEMA`) and the options
(``number("--mark-speed", key=MARK_SPEED)``, `microfab.cli._options`), so that their
ranges cannot drift apart. This module stays light (no twin, no Dask, no SciPy): the
command line imports it when it starts.

The scanner's bounds are its declared limits (`microfab.core.limits.MachineLimits
.seed003_slm`, equal to ``data/galvo_slm.toml``); the others are assumed, each with its
reason beside it. Values the packaged data or another module declare are repeated here
(importing them would slow the command's start) and compared with them by
``tests/cli/test_option_rules_slm_shaper.py``.
"""

from __future__ import annotations

from microfab.io.job import Key
from microfab.process.slm.timing import SPEED_RANGE_M_S

__all__ = [
    "BIT_M",
    "FIELD_BIT",
    "HATCH_ANGLE",
    "HATCH_ROTATION",
    "HATCH_SPACING",
    "JUMP_DELAY",
    "JUMP_SPEED",
    "LASER_OFF_DELAY",
    "LASER_ON_DELAY",
    "LAYER_THICKNESS",
    "MARK_DELAY",
    "MARK_SPEED",
    "MAX_DELAY_US",
    "MAX_LAYERS",
    "MAX_SKY_TICKS",
    "OUTLINE_RADIUS",
    "POLE_HZ",
    "POLYGON_DELAY",
    "SHAPER_ORDER",
    "TWIN_SEED",
    "WORKERS",
]

_F = "float"

#: One bit of the scanner field at the work plane, m (assumed 1.5 µm, as
#: ``data/galvo_slm.toml`` and `microfab.process.slm.timing.RTCSettings`).
BIT_M = 1.5e-6
#: Half the field, bit (32768, assumed, as ``data/galvo_slm.toml`` ``field_bit``).
FIELD_BIT = 32768
#: Half the field, m: ±49.152 mm (the scanner's declared workspace, core/limits.py).
_FIELD_M = FIELD_BIT * BIT_M
#: Fastest mark or jump at the work plane, m/s: the scanner's declared velocity limit
#: (10 m/s, ``MachineLimits.seed003_slm``, assumed there: twice the assumed 5 m/s jump
#: speed; the build refuses a faster vector).
_MAX_SPEED_M_S = 10.0
#: Longest fixed RTC delay, µs. Assumed 10 ms: ten times the longest usual jump delay
#: (seed 003 part 2, "Results and discussion": "typically 750 µs to 1ms"); a longer wait
#: is a unit slip (ms typed for µs), and each tick of it is simulated.
MAX_DELAY_US = 10_000.0
#: Longest sky-writing run-in or run-out, ticks (assumed 1000 = 10 ms: ten times the
#: twin's settling after a jump, ~0.9 ms; longer serves nothing and is simulated tick by
#: tick).
MAX_SKY_TICKS = 1000
#: Most layers of a build: 1 m (`microfab.process.slm.source.MAX_HEIGHT_M`, the tallest
#: SLM build volume, assumed) of 10 µm layers, the thinnest usual SLM layer (assumed).
MAX_LAYERS = 100_000

#: Mark and jump speeds, m/s: from 0.1 mm/s (`microfab.process.slm.timing.SPEED_RANGE_M_S`,
#: assumed there: slower is a unit slip) to the scanner's velocity limit.
MARK_SPEED = Key(
    name="mark_speed_m_s", type=_F, default=0.6, low=SPEED_RANGE_M_S[0],
    high=_MAX_SPEED_M_S, unit="m/s", help="mark speed (assumed 0.6 m/s)",
)  # fmt: skip
JUMP_SPEED = Key(
    name="jump_speed_m_s", type=_F, default=5.0, low=SPEED_RANGE_M_S[0],
    high=_MAX_SPEED_M_S, unit="m/s", help="jump speed (assumed 5 m/s)",
)  # fmt: skip
JUMP_DELAY = Key(
    name="jump_delay_us", type=_F, default=750.0, low=0.0, high=MAX_DELAY_US, unit="µs",
    help="fixed jump delay without the shaper (seed §4: 750 µs)",
)  # fmt: skip
MARK_DELAY = Key(
    name="mark_delay_us", type=_F, default=500.0, low=0.0, high=MAX_DELAY_US, unit="µs",
    help="mark delay (assumed, see process/slm/timing.py)",
)  # fmt: skip
POLYGON_DELAY = Key(
    name="polygon_delay_us", type=_F, default=50.0, low=0.0, high=MAX_DELAY_US, unit="µs",
    help="polygon delay (assumed)",
)  # fmt: skip
LASER_ON_DELAY = Key(
    name="laser_on_delay_us", type=_F, default=100.0, low=0.0, high=MAX_DELAY_US, unit="µs",
    help="laser on delay (assumed)",
)  # fmt: skip
LASER_OFF_DELAY = Key(
    name="laser_off_delay_us", type=_F, default=450.0, low=0.0, high=MAX_DELAY_US, unit="µs",
    help="laser off delay (assumed)",
)  # fmt: skip
#: Hatch spacing: at least one bit of the scanner (a finer hatch is not addressable), at
#: most 1 mm (assumed: SLM hatches are about a melt-pool width, 50-200 µm; beyond ten times
#: the 100 µm default the tracks leave powder unmelted between them, or the unit slipped).
HATCH_SPACING = Key(
    name="hatch_spacing_um", type=_F, default=100.0, low=BIT_M * 1e6, high=1000.0, unit="µm",
    help="hatch spacing (assumed 100 µm)",
)  # fmt: skip
#: Hatch direction, deg: an angle modulo 180° (θ and θ + 180° give the same lines), so
#: [-180, 180] holds every direction, written counter-clockwise (135°) or clockwise (-45°)
#: as a user likes; beyond it the angle has turned once more, a typo.
HATCH_ANGLE = Key(
    name="hatch_angle_deg", type=_F, default=0.0, low=-180.0, high=180.0, unit="deg",
    help="hatch direction",
)  # fmt: skip
#: Hatch turn from one layer to the next, deg: layer i is hatched at i·r modulo 360°
#: (`microfab.process.slm.build.build_layers`), so r and r ± 360° are the same build and
#: [-180, 180] holds every strategy once.
HATCH_ROTATION = Key(
    name="hatch_rotation_deg", type=_F, default=67.0, low=-180.0, high=180.0, unit="deg",
    help="hatch rotation from layer to layer (assumed 67°)",
)  # fmt: skip
#: Layer thickness, µm: 1 µm to 1 mm (as `microfab.process.slm.build.LAYER_RANGE_M`,
#: assumed: seed 003 part 2 §1 "typically 20 to 40 µm"; outside, the unit slipped).
LAYER_THICKNESS = Key(
    name="layer_um", type=_F, default=30.0, low=1.0, high=1000.0, unit="µm",
    help="layer thickness (assumed 30 µm)",
)  # fmt: skip
#: Radius of the lattice disc, mm: inside the scanner's field (±49.152 mm, declared).
OUTLINE_RADIUS = Key(
    name="outline_radius_mm", type=_F, default=8.0, low=0.0, high=_FIELD_M * 1e3, unit="mm",
    low_open=True, help="disc outline of the lattice part",
)  # fmt: skip
#: Local Dask workers (assumed at most 512: more processes than one machine has cores).
WORKERS = Key(
    name="workers", type="int", default=2, low=1, high=512,
    help="Dask worker processes of the local cluster (1: in this process)",
)  # fmt: skip
#: The inverse shaper's added poles, Hz: more than 0, at most 5 MHz (the Nyquist frequency
#: of the shortest command sample time, 0.1 µs; the design refuses poles at or above the
#: Nyquist frequency of the sample time in use, 50 kHz on the RTC's 10 µs tick).
POLE_HZ = Key(
    name="pole_hz", type=_F, default=4000.0, low=0.0, high=5e6, unit="Hz", low_open=True,
    help="added poles (seed §2: 2π·4000 rad/s by its coefficients)",
)  # fmt: skip
#: Number of added poles: 1 to 16 (`microfab.control.shaping.MAX_ADDED_POLES`, assumed
#: there: four times the seed's four; the coefficients of (s/p + 1)^n lose the gain).
SHAPER_ORDER = Key(
    name="order", type="int", default=4, low=1, high=16,
    help="number of added poles (seed §2: four)",
)  # fmt: skip
#: Noise seed of the twin (the chirp identification's measurement noise).
TWIN_SEED = Key(name="seed", type="int", default=0, low=0, help="noise seed")
