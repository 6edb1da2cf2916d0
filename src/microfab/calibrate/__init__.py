"""One calibration core: a twin fitted to all of its paper's numbers at once (issue 45).

`problem` declares the targets (fit or check), the free parameters and the model;
`solve.calibrate` runs the global search, polish, sensitivity and conflict sweep through
one memo (resumable from a file); `report` holds the results as data.
"""

from microfab.calibrate.problem import CalibrationProblem, FreeParameter, Target
from microfab.calibrate.report import CalibrationResult, Conflict, ParameterRow, TargetRow
from microfab.calibrate.solve import Progress, calibrate

__all__ = [
    "CalibrationProblem",
    "CalibrationResult",
    "Conflict",
    "FreeParameter",
    "ParameterRow",
    "Progress",
    "Target",
    "TargetRow",
    "calibrate",
]
