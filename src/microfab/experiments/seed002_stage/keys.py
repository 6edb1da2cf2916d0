"""The ``stage-identify`` job keys that ``microfab`` options share (seed 002 part 1).

A command-line option that sets what one of these keys sets declares itself with the key
(``number("--amax", key=A_MAX)``, `microfab.cli._options`), so the job file and the
command line accept the same values in the same unit. This module imports only
`microfab.io.job`: the CLI reads it at start-up, and `job` (which pulls the study, the twin
and the networks) reads its keys from here.

The bounds that other layers declare are restated here as numbers, so that this module
stays light; ``tests/cli/test_option_rules_identify_stage.py`` checks that they agree:

- ``MIN_RUN_S`` = `microfab.identify.stage_runs.MIN_RUN_S`,
- ``MAX_TOTAL_S`` = `microfab.identify.excitation.MAX_TOTAL_S`,
- ``A_MAX_HIGH`` = ``MachineLimits.seed002_stage().acceleration`` (`microfab.core.limits`),
- ``WHITEN`` = ``AnnConfig().whiten`` and ``WHITEN_LOW`` = `microfab.identify.ann.WHITEN_LOW`.

Option / key pairs: ``stage excite --duration`` and ``calibrate xy-stage --duration`` /
``[linear] total_s``; ``stage excite --amax`` / ``[linear] a_max``; ``stage excite --seed``
and ``calibrate xy-stage --runs-seed`` / ``[linear] seed``; ``stage play --seed`` / ``[twin]
seed``; ``stage play --hold`` / ``[twin] hold_s``; ``identify linear --order`` and
``--decimate`` / ``[linear] order`` and ``decimate``; ``identify ann --epochs``,
``--threads``, ``--workers``, ``--epoch-windows``, ``--validation``, ``--seed``,
``--whiten`` / ``[ann] max_epochs``, ``threads``, ``workers``, ``epoch_windows``,
``validation``, ``seed``, ``whiten``.
"""

from __future__ import annotations

from microfab.io.job import Key

__all__ = [
    "ANN_EPOCH_WINDOWS",
    "ANN_MAX_EPOCHS",
    "ANN_SEED",
    "ANN_THREADS",
    "ANN_VALIDATION",
    "ANN_WHITEN",
    "ANN_WORKERS",
    "A_MAX",
    "A_MAX_HIGH",
    "A_MAX_LOW",
    "DECIMATE",
    "EPOCH_WINDOWS",
    "HOLD_S",
    "MAX_EPOCHS",
    "MAX_TOTAL_S",
    "MIN_RUN_S",
    "ORDER",
    "RUNS_SEED",
    "RUNS_TOTAL_S",
    "TWIN_SEED",
    "WHITEN",
    "WHITEN_LOW",
    "check_whiten_key",
]

#: Shortest run the identification reads, s (seed 002 §III-B: the networks read "the most
#: recent 500 ms"; `microfab.identify.stage_runs.MIN_RUN_S`).
MIN_RUN_S = 0.5
#: Most excitation asked for at once, s (`microfab.identify.excitation.MAX_TOTAL_S`,
#: assumed there: one hour of 10 kHz commands, six times the seed's 600 s).
MAX_TOTAL_S = 3600.0
#: Largest acceleration of the stage, m/s² (seed 002 Table I: 40 m/s²).
A_MAX_HIGH = 40.0
#: Training windows per epoch: assumed, so that both networks train within the 15 min of
#: issue 17 on one CPU thread (16 batches of 16 384 per epoch, about 5 s;
#: `microfab.identify.ann.AnnConfig`).
EPOCH_WINDOWS = 262_144
#: The training schedule (issue 34: training <= 5 min on 2 cores): at most 60 epochs.
#: Assumed, from the measurement in ``benchmarks/bench_ann.py``: the validation σ levels
#: off within the first minutes, and issue 17's 200 epochs reached the same σ.
MAX_EPOCHS = 60
#: Most epochs one training may ask for. Assumed: about 5 s an epoch (``EPOCH_WINDOWS``),
#: 10 000 epochs are 14 hours, far past the seed's 200; more is a typo.
_EPOCHS_HIGH = 10_000

_F = "float"

# --- [linear]: the random runs and the linear model ---------------------------------------
#: Total length of the excitation runs, s. Low: one run the identification reads
#: (``MIN_RUN_S``); high: ``MAX_TOTAL_S`` (the excitation refuses more).
RUNS_TOTAL_S = Key(
    name="total_s",
    type=_F,
    default=600.0,
    low=MIN_RUN_S,
    high=MAX_TOTAL_S,
    unit="s",
    help="random-run data (seed §III-C.1: 6e6 samples, 600 s)",
)
#: Largest acceleration of the runs, m/s²: at most Table I's 40; at least 1e-3 (assumed:
#: over the shortest run, 0.5 s, 1e-3 m/s² moves about a t²/8 = 30 µm, 15 times the 2 µm
#: output noise of seed 002 eq. 3; below it a run is noise, and make fuzz found 1e-308
#: accepted by the open bound at 0).
A_MAX_LOW = 1e-3
A_MAX = Key(
    name="a_max",
    type=_F,
    default=5.0,
    low=A_MAX_LOW,
    high=A_MAX_HIGH,
    unit="m/s²",
    help="largest acceleration of the runs (seed §III-D: 5)",
)
#: States of the linear model (seed 002 §III-A: 4); 30 assumed: the order check scans 2-8.
ORDER = Key(name="order", type="int", default=4, low=1, high=30, help="states (seed: 4)")
#: Decimation before the linear fit; 100 assumed, a loose bound (10 kHz runs to 100 Hz):
#: the runs' own rate sets the real one, checked with them (at least 400 Hz after it).
DECIMATE = Key(
    name="decimate",
    type="int",
    default=10,
    low=1,
    high=100,
    help="decimation before the fit (10: to 1 kHz)",
)
#: Seed of the random runs.
RUNS_SEED = Key(name="seed", type="int", default=0, low=0, help="seed of the random runs")

# --- [twin]: how runs are played -------------------------------------------------------------
#: Noise seed of the twin (run k uses seed + k).
TWIN_SEED = Key(name="seed", type="int", default=0, low=0, help="noise seed (run k uses seed + k)")
#: Hold after each run, s: 10 s assumed (the twin settles within 0.5 s, `TwinSettings`).
HOLD_S = Key(
    name="hold_s",
    type=_F,
    default=0.5,
    low=0.0,
    high=10.0,
    unit="s",
    help="hold after each command so the stage settles (assumed 0.5 s)",
)

# --- [ann]: the per-axis networks (seed 002 eq. 7) ---------------------------------------
#: Share of whole runs kept for validation: more than 0 (the early stopping needs some),
#: at most 0.9 (assumed: training on fewer than a tenth of the runs is not a fit).
ANN_VALIDATION = Key(
    name="validation",
    type=_F,
    default=0.2,
    low=0.0,
    high=0.9,
    low_open=True,
    help="share of whole runs kept for validation (seed: 20 %)",
)
ANN_MAX_EPOCHS = Key(
    name="max_epochs",
    type="int",
    default=MAX_EPOCHS,
    low=1,
    high=_EPOCHS_HIGH,
    help="most epochs per axis (early stopping decides first)",
)
ANN_EPOCH_WINDOWS = Key(
    name="epoch_windows",
    type="int",
    default=EPOCH_WINDOWS,
    low=0,
    help="training windows per epoch (0: all)",
)
#: CPU threads of PyTorch: 256 assumed (more than any one machine's cores).
ANN_THREADS = Key(
    name="threads",
    type="int",
    default=1,
    low=1,
    high=256,
    help="CPU threads per worker (1: best on 2 cores)",
)
#: Axes trained at once: one process per axis, and there are two axes.
ANN_WORKERS = Key(
    name="workers",
    type="int",
    default=2,
    low=1,
    high=2,
    help="axes trained at once, one process each (2: half the time on 2 cores)",
)
ANN_SEED = Key(
    name="seed", type="int", default=0, low=0, help="seed of the runs, the split and the training"
)
#: Shrinkage of the whitened inputs, relative to the mean eigenvalue (`microfab.identify.
#: ann.AnnConfig.whiten`, assumed there and measured in `microfab.identify.ann_whiten`).
WHITEN = 1e-3
#: Least shrinkage (`microfab.identify.ann.WHITEN_LOW`, assumed there).
WHITEN_LOW = 1e-6
#: 0 turns the whitening off (the training before it); a value between 0 and
#: ``WHITEN_LOW`` is refused (`check_whiten_key`).
ANN_WHITEN = Key(
    name="whiten",
    type=_F,
    default=WHITEN,
    low=0.0,
    high=1.0,
    help="shrinkage of the whitened inputs, a share of their mean eigenvalue (0: not whitened)",
)


def check_whiten_key(value: float, name: str) -> float | None:
    """``value`` of `ANN_WHITEN` as the training takes it: None for 0 (off), else itself.

    Raises
    ------
    ValueError
        ``value`` between 0 and ``WHITEN_LOW``, or outside [0, 1]; the message names
        ``name`` (the option or the key).
    """
    if value == 0.0:
        return None
    if not WHITEN_LOW <= value <= 1.0:
        raise ValueError(
            f"{name} must be 0 (not whitened) or lie in [{WHITEN_LOW:g}, 1] of the mean "
            f"eigenvalue, got {value:g}"
        )
    return value
