"""Tables of a laser job's page that only format its summary (`microfab.report.contour`)."""

from __future__ import annotations

from microfab.report.contour import acceleration_table, corner_label, slowdown_table

#: A hexagon's slow-downs at 50 mm/s as `summary.json` carries them (measured, issue 45).
HEXAGON = [
    {"at_mm": 0.0, "speed_mm_s": 0.0, "corners": [1], "corner_at_mm": [0.0], "from_rest": True},
    {"at_mm": 1.0, "speed_mm_s": 0.015, "corners": [2, 3], "corner_at_mm": [1.0, 2.0],
     "from_rest": False},
    {"at_mm": 3.0, "speed_mm_s": 0.083, "corners": [4], "corner_at_mm": [3.0],
     "from_rest": False},
    {"at_mm": 5.0, "speed_mm_s": 0.055, "corners": [5, 6], "corner_at_mm": [4.0, 5.0],
     "from_rest": False},
]  # fmt: skip


def test_the_slowdown_table_names_every_corner_and_says_when_one_covers_two():
    t = slowdown_table(HEXAGON, 0.05, 6)
    first = [r[0] for r in t.rows]
    assert first == [
        "corner 1, start from rest",
        "corners 2+3 (too close to get back to speed)",
        "corner 4",
        "corners 5+6 (too close to get back to speed)",
    ]
    assert t.rows[1][1] == "1.0000, 2.0000"
    assert "not slowed" not in t.note and "6 corner(s)" in t.note
    # a corner the stage took at speed is said, as is a slow-down on a curve
    t = slowdown_table(HEXAGON[:3], 0.05, 6)
    assert "not slowed below 90 %: 5, 6" in t.note
    curve = {"at_mm": 2.0, "speed_mm_s": 1.0, "corners": [], "corner_at_mm": [],
             "from_rest": False}  # fmt: skip
    assert corner_label(curve) == "no corner (a curve)"


def test_the_acceleration_table_states_asked_used_axis_and_forces():
    low = {"asked_m_s2": 5.0, "used_m_s2": 2.083, "axis": "x", "asked_rms_force_n": 4.53,
           "used_rms_force_n": 2.37, "continuous_force_n": 3.0, "plans": 2}  # fmt: skip
    t = acceleration_table(low)
    assert list(t.rows) == [("5", "2.08", "x", "4.53 / 2.37", "3")]
    assert "2 plans" in t.note
