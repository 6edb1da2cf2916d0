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


def test_the_paper_model_table_sets_the_twin_prediction_beside_it_per_speed() -> None:
    from microfab.report.contour_fig7 import fig7_paper_table

    paper = [{"speed_mm_s": v, "without_nm": w, "with_nm": c, "ratio": w / c,
              "change_nm": w - c, "reference_nm": 0.0045}
             for v, w, c in ((0.5, 0.0052, 0.0051), (20.0, 232.0, 39.8))]  # fmt: skip
    res = [{"speed_mm_s": 20.0, "refused": "3 N"}]
    twin = [_row("circle:radius=1e-4", 0.5, True, False, 306.0, 63.0)]
    t = fig7_paper_table(paper, res, twin)
    assert t.columns[:5] == ("speed [mm/s]", "paper's model (eqs. 2-15)",
                             "with Table I's 10 nm encoder", "calibrated twin (prediction)",
                             "reference's own [nm]")  # fmt: skip
    assert t.rows[0][:5] == ("0.5", "0.0052 / 0.0051 (1.02x)", "", "306 / 63 (4.9x)", "0.0045")
    assert t.rows[1][2] == "refused (Table I)" and t.rows[1][3] == ""
    assert "F_l = 0" in t.note and "prediction" in t.note
