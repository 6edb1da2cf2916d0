"""Published numbers of seed 000 (Yoo et al., ILC for laser-scanning micro 3D printing).

Every value cites its table or section in ``../shared/seeds/000_f8fa17eaefc5dca4.txt``.
Table 1 and the rates, the galvo twin's calibration target, live with the calibration
(`microfab.machines.galvo.calibration`) and are re-exported here.
"""

from __future__ import annotations

# RATES (seed 000 §4) and TABLE1_MV (seed 000 Table 1) are the galvo twin's calibration
# target and live with it.
from microfab.machines.galvo.calibration import RATES, TABLE1_MV

__all__ = [
    "MARGINS",
    "MAX_VELOCITY_ERROR_400",
    "RATES",
    "SIDE_MM",
    "TABLE1_MV",
    "TABLE2_MM_S",
    "TARGET_SPEED_MM_S",
]

SIDE_MM = 0.6  # seed 000 §4: 0.6 x 0.6 mm square
TARGET_SPEED_MM_S = {100: 240.0, 200: 480.0, 400: 960.0}  # seed 000 §4.2

# seed 000 Table 2: beam velocity mean (std) and (max, min) in mm/s. The table's header
# says "(Max., Min.)" but lists the smaller value first; we store them by meaning.
TABLE2_MM_S: dict[int, dict[str, float]] = {
    100: {
        "fb_mean": 245,
        "fb_std": 27,
        "fb_min": 158,
        "fb_max": 351,
        "ilc_mean": 239,
        "ilc_std": 12,
        "ilc_min": 156,
        "ilc_max": 280,
    },
    200: {
        "fb_mean": 502,
        "fb_std": 75,
        "fb_min": 311,
        "fb_max": 697,
        "ilc_mean": 477,
        "ilc_std": 26,
        "ilc_min": 344,
        "ilc_max": 535,
    },
    400: {
        "fb_mean": 1061,
        "fb_std": 202,
        "fb_min": 623,
        "fb_max": 1401,
        "ilc_mean": 947,
        "ilc_std": 91,
        "ilc_min": 640,
        "ilc_max": 1101,
    },
}

# seed 000 §3.1: measured gain and phase margins.
MARGINS = {"x": {"gm_db": 68.5, "pm_deg": 53.0}, "y": {"gm_db": 69.6, "pm_deg": 51.0}}

# seed 000 §4.2: max velocity error w.r.t. target at 400 features/s, FB -> ILC.
MAX_VELOCITY_ERROR_400 = {"fb": 0.458, "ilc": 0.146}
