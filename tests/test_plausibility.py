"""The pose gate's shortcut (``Track.box``, what the core's ``reports`` loop tests a row against)
is never more generous than the rule it stands for, ``PoseGate.admit``."""
from __future__ import annotations

import copy

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from robo_comp.match.plausibility import WINDOW, PoseGate

WALLS = np.zeros((20, 30), dtype=bool)
WALLS[8:12, 10:20] = True  # a block in the middle
WALLS[:, 0] = True  # and a wall along one edge
GATE = PoseGate(WALLS, speed=2.0)

coord = st.floats(min_value=-0.4, max_value=19.4, allow_nan=False)
unit = st.floats(min_value=0.0, max_value=1.0, allow_nan=False)


@settings(max_examples=400, deadline=None)
@given(ax=st.floats(min_value=1.0, max_value=28.0), ay=coord, sigma=st.floats(min_value=0.0, max_value=3.0),
       speed=st.floats(min_value=0.1, max_value=2.0), fx=unit, fy=unit, dt=st.floats(min_value=0.0, max_value=0.999),
       psigma=st.floats(min_value=0.0, max_value=3.0), spent=unit)
def test_a_pose_inside_the_box_is_one_admit_takes(ax: float, ay: float, sigma: float, speed: float, fx: float,
                                                  fy: float, dt: float, psigma: float, spent: float) -> None:
    tr = GATE.track(speed)
    if not GATE.admit(tr, ax, ay, sigma, 100.0).ok:
        return  # not a place a robot can be: no anchor, no box
    # an anchor with some of its budget spent (as after a drive)
    GATE.anchor(tr, ax, ay, sigma, tr.budget * (1.0 - spent), 100.0)
    until, x_lo, x_hi, y_lo, y_hi = tr.box
    assume(x_lo <= x_hi)  # by a wall the box is empty: every pose asks admit
    assert until == 100.0 + WINDOW
    x, y, now = x_lo + fx * (x_hi - x_lo), y_lo + fy * (y_hi - y_lo), 100.0 + dt
    assert now < until and x_lo <= x <= x_hi and y_lo <= y <= y_hi  # the hot path takes it ...
    assert GATE.admit(copy.copy(tr), x, y, psigma, now).ok  # ... and so does the rule itself


def test_a_robot_not_placed_has_an_empty_box_and_an_expired_box_asks_again() -> None:
    tr = GATE.track(2.0)
    until, x_lo, x_hi, y_lo, y_hi = tr.box
    assert not (x_lo <= 5.0 <= x_hi and y_lo <= 5.0 <= y_hi)
    assert GATE.admit(tr, 5.0, 5.0, 0.0, 50.0).ok
    until, x_lo, x_hi, y_lo, y_hi = tr.box
    assert x_lo < 5.0 < x_hi and y_lo < 5.0 < y_hi and until == 50.0 + WINDOW
    # next to a wall the box shrinks to the clearance: never a way through the wall
    GATE.admit(tr2 := GATE.track(2.0), 9.0, 10.0, 0.0, 50.0)
    assert tr2.box[2] < 9.5
