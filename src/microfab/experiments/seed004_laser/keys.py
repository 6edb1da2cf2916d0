"""The ``laser-micromachining`` job keys that the ``microfab laser`` options share (seed 004).

A light module (it imports `microfab.io.job` only), so that the command line declares its
options with these keys without importing the job (which pulls the stage, its twin and
its controllers): ``laser analyze --contour`` sets what ``[drawing] contour`` sets.
"""

from __future__ import annotations

from microfab.io.job import Key

__all__ = ["CONTOUR"]

#: Which closed contour of the drawing, counted from 0 (a drawing with fewer is refused
#: when it is read: the count is the drawing's).
CONTOUR = Key(name="contour", type="int", default=0, low=0, help="which closed contour, from 0")
