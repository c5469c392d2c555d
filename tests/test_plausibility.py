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


def test_poses_that_hop_about_near_the_anchor_are_charged_for_the_driving_between() -> None:
    """Each pose is within the anchor's reach, but 4 cells from the one before in a hundredth of a
    second: the robot would have driven 4 cells each time. The hops use up the budget (7.5 cells at
    2 cells/s) and the rest are refused, saying the hop; jitter within the noise costs nothing."""
    tr = GATE.track(2.0)
    assert GATE.admit(tr, 5.0, 5.0, 0.0, 10.0).ok
    said = [GATE.admit(tr, 5.0 + (2.0 if k % 2 == 0 else -2.0), 5.0, 0.0, 10.0 + 0.01 * k) for k in range(1, 11)]
    # taken: 3 (a hop of 2), 7 (of 4: 1.5 left); then every pose at 3 is refused (the ones at 7 are
    # where the robot was taken last: it stays)
    assert [v.ok for v in said] == [True, True] + [False, True] * 4, said
    assert "a hop of 4.0 cells from the pose taken last (7.00, 5.00) to (3.00, 5.00)" in said[-2].reason
    # a host that reports its noise: jitter of 3 sigma about one place is never charged
    calm = GATE.track(2.0)
    assert GATE.admit(calm, 5.0, 5.0, 0.3, 10.0).ok
    assert all(GATE.admit(calm, 5.0 + (0.8 if k % 2 else -0.8), 5.0, 0.3, 10.0 + 0.01 * k).ok for k in range(1, 500))


def test_a_robot_driving_at_its_top_speed_is_never_refused() -> None:
    tr = GATE.track(2.0)
    assert GATE.admit(tr, 1.0, 2.0, 0.0, 0.0).ok
    for k in range(1, 131):  # 13 s along row 2 at 2 cells/s, reports at 10 Hz, every third one late
        t = 0.1 * k
        late = 0.25 if k % 3 == 0 else 0.0
        assert GATE.admit(tr, 1.0 + 2.0 * t, 2.0, 0.0, t + late).ok, (k, tr)
