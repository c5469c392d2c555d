"""Localization: positioning fixes (noise, rate, dropouts), .xyz records, dead reckoning."""
from __future__ import annotations

import io
import math

import numpy as np
import pytest

from robo_comp.errors import ScenarioError
from robo_comp.world.arena import Arena
from robo_comp.world.localization import (
    DeadReckoner, Fix, Localization, PositioningSystem, format_xyz, parse_xyz, parse_xyz_line,
    read_xyz, write_xyz,
)
from robo_comp.world.scenario import Drift, Positioning, parse_scenario


@pytest.mark.parametrize("rate,noise,dropout", [(2.0, 0.3, 0.05), (5.0, 1.0, 0.3), (1.0, 0.0, 0.0)])
def test_fixes_respect_noise_rate_and_dropout(rate: float, noise: float, dropout: float) -> None:
    ps = PositioningSystem(Positioning(rate=rate, noise=noise, dropout=dropout), np.random.default_rng(7))
    n, seconds, dt = 200, 20.0, 0.05
    tags = [f"r{i}" for i in range(n)]
    tx = np.arange(n, dtype=float)
    ty = np.full(n, 3.0)
    fixes = []
    for k in range(1, int(seconds / dt) + 1):
        fixes += ps.poll(k * dt, tags, tx, ty)
    due = ps.sent + ps.dropped
    assert due == pytest.approx(n * rate * seconds, rel=0.05)
    assert ps.dropped / due == pytest.approx(dropout, abs=0.02)
    ex = np.array([f.x - tx[int(f.tag[1:])] for f in fixes])
    ey = np.array([f.y - 3.0 for f in fixes])
    assert abs(ex.mean()) < 0.05 + 0.05 * noise and abs(ey.mean()) < 0.05 + 0.05 * noise
    assert ex.std() == pytest.approx(noise, abs=0.05 * noise + 1e-9)
    assert ey.std() == pytest.approx(noise, abs=0.05 * noise + 1e-9)
    # Per-robot fixes are spaced by the period.
    times = sorted(f.time for f in fixes if f.tag == "r0")
    gaps = np.diff(times)
    assert gaps.min() >= 1.0 / rate - dt - 1e-9


def test_positioning_is_seeded() -> None:
    def run(seed: int) -> list[Fix]:
        ps = PositioningSystem(Positioning(), np.random.default_rng(seed))
        return sum((ps.poll(k * 0.1, ["a", "b"], [1.0, 2.0], [1.0, 2.0]) for k in range(1, 50)), [])
    assert run(1) == run(1) and run(1) != run(2)


def test_xyz_round_trip(tmp_path) -> None:
    fixes = [Fix("r1", 12.4312, 8.1, 0.0, 15.25), Fix("blue-7", -1.0, 0.5, 1.25, 0.0)]
    buf = io.StringIO()
    assert write_xyz(fixes, buf) == 2
    text = "# tag x y z time\n\n" + buf.getvalue()
    assert text.splitlines()[2] == "r1 12.431 8.100 0.000 15.250"
    back = parse_xyz(text)
    assert [f.tag for f in back] == ["r1", "blue-7"]
    assert back[0].x == pytest.approx(12.431) and back[1].z == pytest.approx(1.25)
    p = tmp_path / "run.xyz"
    p.write_text(text)
    assert read_xyz(str(p)) == back
    assert parse_xyz_line("  # only a comment") is None


@pytest.mark.parametrize("line", ["r1 1 2 3", "r1 1 2 3 4 5", "r1 x 2 3 4", "r1 1 2 nan 4", "r1 1 inf 0 4"])
def test_xyz_malformed_lines(line: str) -> None:
    with pytest.raises(ScenarioError, match=r"run\.xyz line 3"):
        parse_xyz("a 1 2 3 4\n\n" + line + "\n", "run.xyz")


def test_xyz_rejects_bad_tags() -> None:
    with pytest.raises(ValueError):
        format_xyz(Fix("two words", 1, 2, 0, 0))


def test_dead_reckoning_drifts_without_fixes_and_corrects_with_them() -> None:
    drift = Drift(distance=0.05, heading=2.0, heading_per_cell=0.5)
    errors_open, errors_fixed = [], []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        truth = [0.0, 0.0, 0.0]
        dr = DeadReckoner(0, 0, 0, drift, rng, fix_noise=0.1)
        dr_fix = DeadReckoner(0, 0, 0, drift, np.random.default_rng(seed + 100), fix_noise=0.1)
        for leg in range(40):                    # a staircase: 5 cells, turn ±90°
            turn = 0.0 if leg == 0 else (90.0 if leg % 2 else -90.0)
            for r in (dr, dr_fix):
                r.advance(5.0, turn)
            truth[2] += turn
            truth[0] += 5 * math.cos(math.radians(truth[2]))
            truth[1] += 5 * math.sin(math.radians(truth[2]))
            if leg % 2 == 1:                     # a fix every other leg
                dr_fix.correct(Fix("r", truth[0] + rng.normal(0, 0.1), truth[1] + rng.normal(0, 0.1), 0, leg))
        errors_open.append(math.hypot(dr.x - truth[0], dr.y - truth[1]))
        errors_fixed.append(math.hypot(dr_fix.x - truth[0], dr_fix.y - truth[1]))
    assert np.mean(errors_open) > 2.0              # 200 cells blindfolded: drifts by cells
    assert np.mean(errors_fixed) < 1.5 and np.mean(errors_fixed) < np.mean(errors_open) / 3
    # With zero drift, dead reckoning is exact.
    exact = DeadReckoner(1, 1, 0, Drift(0, 0, 0))
    exact.advance(3, 0)
    exact.advance(2, 90)
    assert exact.pose() == pytest.approx((4.0, 3.0, 90.0))


def test_correct_with_gain_and_variance() -> None:
    dr = DeadReckoner(0, 0, 0, Drift(0.1, 0, 0), np.random.default_rng(0), fix_noise=0.5)
    assert dr.sigma == 0.0
    dr.advance(10)
    assert dr.sigma > 0.5
    before = dr.var
    dr.correct(Fix("r", 10.0, 3.0, 0, 1.0))
    assert dr.var < before
    assert 0.0 < dr.y < 3.0                        # blended, not jumped
    dr.correct(Fix("r", 10.0, 3.0, 0, 2.0), gain=1.0)
    assert (dr.x, dr.y) == (10.0, 3.0)


ROOM = '''map = { width = 30, height = 10 }
seed = 4
[positioning]
rate = 2
noise = 0.2
dropout = 0.1
[drift]
distance = 0.05
heading = 3
heading_per_cell = 1
[robot]
drive = "grid4"
'''


def test_localization_tracks_arena_robots() -> None:
    a = Arena(parse_scenario(ROOM, "loc.toml"))
    a.add_robot("r", "red", 1, 1, 0)
    a.add_robot("b", "blue", 1, 8, 0)
    loc = Localization(a)
    assert loc.estimate("r") == (1.0, 1.0, 0.0)
    a.command("r", "forward", 25)
    a.command("b", "forward", 25)
    all_fixes = []
    for _ in range(150):
        a.step(0.1)
        all_fixes += loc.update()
    assert {f.tag for f in all_fixes} == {"r", "b"}
    assert len(all_fixes) == pytest.approx(2 * 2 * 15 * 0.9, rel=0.25)
    for tag in ("r", "b"):
        x, y, _ = loc.estimate(tag)
        p = a.pose(tag)
        assert p.x == 26.0
        assert math.hypot(x - p.x, y - p.y) < 1.0   # estimate close, but not the truth
    assert loc.estimates()["r"] != (a.pose("r").x, a.pose("r").y, a.pose("r").heading)
    a.remove_robot("b")
    loc.update()
    assert set(loc.estimates()) == {"r"}


def test_position_fixes_correct_a_wrong_heading_through_their_track():
    """A robot that believes it faces 30 degrees off drives straight east: the HX5's fixes measure
    positions only, yet the way they move says where the robot faces (issue 33)."""
    from robo_comp.world.arena import Arena
    from robo_comp.world.localization import Localization
    from robo_comp.world.scenario import parse_scenario

    sc = parse_scenario("map = { width = 40, height = 9 }\nseed = 2\n[robot]\ndrive = \"free\"\n", "m.toml")
    arena = Arena(sc, seed=2)
    arena.add_robot("r1", "red", 2.0, 4.0, 0.0)
    loc = Localization(arena)
    loc.update()
    loc.reckoners["r1"].heading = 30.0  # wrong by 30 degrees
    arena.command("r1", "forward", 30.0)
    while arena.is_moving("r1"):
        arena.step(0.1)
        loc.update()
    x, y, h = loc.estimate("r1")
    assert abs((h - 0.0 + 180) % 360 - 180) < 5, h
    assert abs(x - 32.0) < 1.0 and abs(y - 4.0) < 1.0, (x, y)
