import numpy as np
import pytest

from microfab.geometry.segments import CurveSegment, LineSegment
from microfab.geometry.text import SEED002_LETTERS, letters_seed002, text_layer


@pytest.fixture(scope="module")
def letters():
    return letters_seed002(height=0.02)


@pytest.mark.parametrize("ch", SEED002_LETTERS)
def test_seed002_letter_is_one_closed_contour(letters, ch):
    layer = letters[ch]
    assert layer.source == ch
    assert len(layer) == 1
    (c,) = layer
    assert c.closed
    assert c.length > 0
    assert abs(c.signed_area) > 0
    assert c.orientation == "ccw"
    kinds = {type(s) for s in c.segments}
    assert kinds == {LineSegment, CurveSegment}  # straight stems and curved bowls
    assert c.corners().size >= 2  # sharp corners too (seed 002 §II-C)


def test_letters_are_u_r_c_h(letters):
    assert list(letters) == ["u", "r", "c", "h"]
    # an "h" has an ascender: taller than the x-height letters
    heights = {k: v.bbox[3] - v.bbox[1] for k, v in letters.items()}
    assert heights["h"] > 1.3 * heights["u"]


def test_origin_at_lower_left_of_ink_box():
    for s in ("u", "gh", "Ag"):
        x0, y0, _, _ = text_layer(s).bbox
        assert x0 == pytest.approx(0, abs=1e-9)
        assert y0 == pytest.approx(0, abs=1e-9)


def test_o_has_outer_and_hole_oriented():
    layer = text_layer("o")
    assert len(layer) == 2
    assert layer.depth == (0, 1)
    oriented = layer.oriented()
    assert [c.orientation for c in oriented] == ["ccw", "cw"]
    outer, hole = oriented
    assert abs(outer.signed_area) > abs(hole.signed_area)


def test_height_scaling_is_linear():
    a = text_layer("c", height=0.01)[0]
    b = text_layer("c", height=0.03)[0]
    assert b.length == pytest.approx(3 * a.length, rel=1e-12)
    assert b.signed_area == pytest.approx(9 * a.signed_area, rel=1e-12)
    np.testing.assert_allclose(b.segments[3].start, 3 * a.segments[3].start, atol=1e-15)


def test_height_is_font_size():
    # DejaVu Sans: cap height 1493 / 2048 em ("H" stands on the baseline, flat top);
    # matplotlib's outlines come on a grid of 1/6400 em (26.6 fixed point at size 100)
    H = text_layer("H", height=0.01)
    assert H.bbox[3] - H.bbox[1] == pytest.approx(0.01 * 1493 / 2048, abs=0.01 / 6400)


def test_multiple_characters_and_weight():
    normal = text_layer("uh")
    bold = text_layer("uh", weight="bold")
    assert len(normal) == 2
    assert sum(abs(c.signed_area) for c in bold) > sum(abs(c.signed_area) for c in normal)


@pytest.mark.parametrize("text", ["", "   "])
def test_empty_text_raises(text):
    with pytest.raises(ValueError, match="no visible"):
        text_layer(text)


@pytest.mark.parametrize("h", [0.0, -1e-3, float("nan")])
def test_bad_height_raises(h):
    with pytest.raises(ValueError, match="height"):
        text_layer("u", height=h)


def test_unknown_font_raises():
    with pytest.raises(ValueError, match="not found"):
        text_layer("u", font="No Such Font Family 1234")


@pytest.mark.parametrize("text", ["\U0005b1f3", "a\x18", "\u200b", "x\ny"])
def test_characters_without_a_glyph_are_refused(text):
    # a missing glyph was drawn as a placeholder box of dozens of contours (12 of them: 20 s)
    with pytest.raises(ValueError, match=r"U\+[0-9A-F]{4,}.*(not in font|not a printable)"):
        text_layer(text)


def test_accented_letters_of_the_font_are_taken():
    assert len(text_layer("é")) >= 2


@pytest.mark.parametrize("h", [1e152, float("inf")])
def test_huge_height_raises(h):
    with pytest.raises(ValueError, match="text height"):
        text_layer("u", height=h)
