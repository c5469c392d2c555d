"""Generated scenarios: deterministic, always solvable, harder with the knob, shown like any other."""
from __future__ import annotations

import os
import statistics
import subprocess
import sys

import numpy as np
import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

from robo_comp.errors import FieldError  # noqa: E402
from robo_comp.world.arena import Arena  # noqa: E402
from robo_comp.world.generate import generate_scenario, reachable  # noqa: E402
from robo_comp.world.scenario import load_scenario, parse_scenario  # noqa: E402


def build(seed: int, difficulty: float, **kw):
    return parse_scenario(generate_scenario(seed, difficulty=difficulty, **kw), f"generated:{seed}")


def test_the_same_seed_gives_the_same_file_and_another_seed_another():
    assert generate_scenario(4, difficulty=0.3) == generate_scenario(4, difficulty=0.3)
    assert generate_scenario(4, difficulty=0.3) != generate_scenario(5, difficulty=0.3)
    assert generate_scenario(4, difficulty=0.3) != generate_scenario(4, difficulty=0.7)


@pytest.mark.parametrize("difficulty", [0.0, 0.5, 1.0])
def test_every_victim_and_start_is_reachable_from_every_start(difficulty):
    for seed in range(1, 31):
        sc = build(seed, difficulty, teams=2 + seed % 3)
        arena = Arena(sc, seed=0)
        for team in sc.teams:
            assert len(arena.free_start_cells(team.name)) >= team.robots, (seed, team.name)
        for team in sc.teams:
            seen = reachable(sc.walls, sc.start_cells(team.name)[:1])
            assert all(seen[y, x] for t in sc.teams for x, y in sc.start_cells(t.name)), (seed, difficulty)
            assert all(seen[v.y, v.x] for v in sc.victims), (seed, difficulty)
        assert len(sc.victims) >= 4


def test_difficulty_makes_it_harder_on_average():
    def measure(d):
        walls, victims, rubble, far = [], [], [], []
        for seed in range(1, 16):
            sc = build(seed, d)
            walls.append(int(sc.walls.sum()))
            victims.append(len(sc.victims))
            rubble.append(sum(z.rect.w * z.rect.h for z in sc.zones))
            start = sc.teams[0].start
            far.append(np.mean([abs(v.x - start.x) + abs(v.y - start.y) for v in sc.victims]))
        return [statistics.mean(v) for v in (walls, victims, rubble, far)]

    easy, hard = measure(0.1), measure(0.9)
    assert all(h > e for e, h in zip(easy, hard)), (easy, hard)


def test_bad_knobs_are_refused_with_a_sentence():
    with pytest.raises(FieldError, match="between 0 and 1"):
        generate_scenario(1, difficulty=1.5)
    with pytest.raises(FieldError, match="24x16"):
        generate_scenario(1, width=10, height=10)
    with pytest.raises(FieldError, match="1 to 4 teams"):
        generate_scenario(1, teams=7)


def test_the_command_writes_a_file_that_loads(tmp_path):
    cmd = [sys.executable, "-m", "robo_comp.cli", "scenario", "generate", "--seed", "9", "--difficulty", "0.7"]
    r = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "generated-9.toml" in r.stdout and "victims" in r.stdout
    sc = load_scenario(tmp_path / "generated-9.toml")
    assert sc.name == "Generated #9 (difficulty 0.70)" and sc.walls.shape == (48, 64)
    bad = subprocess.run(cmd[:-1] + ["3"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "between 0 and 1" in bad.stderr and "Traceback" not in bad.stderr


def test_a_league_match_on_a_generated_map_shows_on_the_wall(tmp_path):
    """The match's log carries the generated arena; the wall draws it from the log."""
    import pygame

    from robo_comp.league import reference
    from robo_comp.league.engine import play_match
    from robo_comp.view.model import MatchView
    from robo_comp.wall.replay import ReplaySource

    spec = {"id": 1, "scenario": "generated:2:0.5", "seed": 1, "seconds": 30, "robots": 2, "log": str(tmp_path / "g.log"),
            "entrants": [{"team": "a", "version": "1", "files": {"p.py": reference.source("frontier")}},
                         {"team": "b", "version": "1", "files": {"p.py": reference.source("sitter")}}]}
    play_match(spec)
    clock = [0.0]
    src = ReplaySource(tmp_path / "g.log", speed=100.0, clock=lambda: clock[0])
    model = MatchView()
    src.attach(model)
    clock[0] = 1.0
    src.advance(model)
    assert model.arena is not None and (model.arena.width, model.arena.height) == (64, 48)
    assert (model.arena.walls == load_walls(tmp_path / "g.log")).all()
    assert sorted(model.robots) == [101, 102, 103, 104]
    pygame.display.init()
    from robo_comp.wall.render import Renderer
    from robo_comp.wall.view import TileSpec, ViewState

    surf = pygame.Surface((640, 480), 0, 32)
    Renderer(model, TileSpec(width=640, height=480), ViewState()).draw(surf, None, None)
    colours = {tuple(c) for c in pygame.surfarray.array3d(surf).reshape(-1, 3)[::97]}
    assert len(colours) > 4  # walls, floor, rubble, robots of two teams drawn


def load_walls(log):
    from robo_comp.protocol.arena import unpack_walls
    from robo_comp.protocol.logfile import read_recording

    _, started = read_recording(log)
    return unpack_walls(started["arena"])
