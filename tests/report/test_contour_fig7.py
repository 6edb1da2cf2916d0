"""The Fig. 7 speed study drawn: one panel per drawing, without / with per variant."""

from __future__ import annotations

from microfab.report.contour_fig7 import fig7_speed_figure


def _row(drawing: str, v: float, fr: bool, ff: bool, without: float, with_: float) -> dict:
    return {"drawing": drawing, "speed_mm_s": v, "friction": fr, "friction_ff": ff,
            "without_nm": without, "with_nm": with_, "gain": without / with_}  # fmt: skip


def test_one_panel_per_drawing_two_lines_per_variant_refused_left_out() -> None:
    rows = [_row("circle", v, True, False, 100 * v, 30 * v) for v in (1.0, 10.0)]
    rows += [_row("circle", v, False, False, 5 * v, 4 * v) for v in (1.0, 10.0)]
    rows += [_row("ellipse", 1.0, True, False, 90.0, 20.0)]
    rows += [{"drawing": "ellipse", "speed_mm_s": 20.0, "friction": True,
              "friction_ff": False, "refused": "3 N"}]  # fmt: skip
    fig = fig7_speed_figure(rows)
    circle, ellipse = fig.axes
    assert circle.get_title() == "circle" and len(circle.lines) == 4
    assert [tuple(ln.get_xdata()) for ln in ellipse.lines] == [(1.0,), (1.0,)]
    solid = [ln for ln in circle.lines if ln.get_linestyle() == "-"]
    assert [tuple(ln.get_ydata()) for ln in solid] == [(30.0, 300.0), (4.0, 40.0)]
