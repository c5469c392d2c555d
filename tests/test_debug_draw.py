"""Debug drawing from team code (robot.draw_dot/draw_line/draw_text), end to end.

On the bench (the league's engine): the real sandbox collects the shapes, the frame is recorded
as ``debug.draw`` for the team, the bounds hold and drawing costs no call budget. Live: a real
core, a real robot host running uploaded code, the web gateway and headless Chromium: the
team's view draws it (screenshot), the toggles switch it per team and per robot, the public
view never receives it. Replays: the team sees it; everyone only when the match's
``debug_replay`` says so. The wall (pygame, SDL dummy) draws it and its keys switch it.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

from robo_comp.protocol import drawing  # noqa: E402
from robo_comp.protocol.topics import PRIVATE_TOPICS, public_event, replay_public_event  # noqa: E402

PLAY_ARGS = ('[{"name": "width", "type": "int"}, {"name": "height", "type": "int"}, '
             '{"name": "index", "type": "int"}, {"name": "count", "type": "int"}]')
#: A league entrant that draws where it is, a line and its step, then turns; it tries to draw
#: past the bound once per step and logs how many shapes were kept.
DRAWER = f'''
MANIFEST = {{"name": "drawer", "version": "1.0", "kind": "extension", "description": "draws",
    "tasks": {{"play": {{"description": "draw and turn", "args": {PLAY_ARGS}}}}}}}

def play(robot, width, height, index, count):
    for k in range(1000):
        x, y, h = robot.position()
        kept = 0
        for i in range(20):
            if robot.draw_dot(x + i * 0.1, y, "red"):
                kept += 1
        if k == 0:
            robot.log("kept " + str(kept))
        robot.turn(90)
'''
#: The same for a live robot host: a task the team gives.
DOODLE = '''
MANIFEST = {"name": "doodle", "version": "1.0", "kind": "extension", "description": "draws",
    "tasks": {"doodle": {"description": "draw where it is and turn", "args": []}}}

def doodle(robot):
    for k in range(400):
        x, y, h = robot.position()
        robot.draw_dot(x, y, "red")
        robot.draw_line(x, y, x + 4, y + 2, "cyan")
        robot.draw_text(x + 1, y - 1, "goal " + str(k % 10), "yellow")
        robot.turn(45)
'''


def test_shapes_are_checked_and_bounded():
    assert drawing.dot(1, 2.345, "red") == ["d", 1.0, 2.35, "#ff3b30"]
    assert drawing.text(0, 0, "x" * 100)[3] == "x" * drawing.MAX_TEXT
    with pytest.raises(ValueError, match="colour must be one of"):
        drawing.line(0, 0, 1, 1, "chartreuse")
    with pytest.raises(ValueError, match="x must be a number of cells"):
        drawing.dot(float("nan"), 0)
    # what a hostile sandbox sends is cleaned, never trusted: bad shapes dropped, the rest bounded
    junk: Any = [["d", 1, 1, "#00ff00"], ["d", "1", 1, "red"], ["x", 1, 1, "red"], "dot", ["l", 1, 2, 3, "red"],
                 ["t", 1, 1, {"no": 1}, "red"], ["d", 1e9, 1, "red"]] + [["d", 2, 2, "red"]] * 40
    kept = drawing.clean_frame(junk)
    assert kept[0] == ["d", 1.0, 1.0, "#00ff00"] and ["t", 1.0, 1.0, "", "#ff3b30"] in kept
    assert len(kept) == drawing.MAX_SHAPES and drawing.clean_frame({"not": "a list"}) == []


def test_the_one_table_keeps_debug_drawing_off_public_feeds():
    data = {"team": "red", "tags": [101], "frames": [[["d", 1.0, 1.0, "#ff3b30"]]]}
    assert "debug.draw" in PRIVATE_TOPICS and public_event("debug.draw", data) is None
    assert replay_public_event("debug.draw", data, "team") is None
    assert replay_public_event("debug.draw", data, "everyone") == data


def _drawer_match(tmp: Path, debug_replay: str = "team", seconds: float = 8.0) -> dict[str, Any]:
    from robo_comp.league.engine import play_match

    ref = Path(__file__).resolve().parent.parent / "robo_comp" / "league" / "reference" / "sitter.py"
    return play_match({"id": 1, "scenario": "demo_room", "seed": 3, "seconds": seconds, "robots": 2,
                       "debug_replay": debug_replay,
                       "entrants": [{"team": "red", "version": "1", "files": {"drawer.py": DRAWER}},
                                    {"team": "blue", "version": "1", "files": {"sitter.py": ref.read_text()}}],
                       "log": str(tmp / "events.log")})


def test_the_bench_records_frames_at_the_bound_and_charges_nothing(tmp_path):
    from robo_comp.protocol.logfile import read_log

    _drawer_match(tmp_path)
    records = list(read_log(tmp_path / "events.log"))
    draws = [r for r in records if r.topic == "debug.draw"]
    assert draws and all(r.team == "red" for r in draws)
    assert all(len(f) == drawing.MAX_SHAPES for r in draws for f in r.data["frames"])
    times = [r.t for r in draws]
    assert all(b - a >= drawing.TICK - 1e-9 for a, b in zip(times, times[1:]))  # one recording a tick at most
    logs = [r.data["text"] for r in records if r.topic == "robot.log"]
    assert f"kept {drawing.MAX_SHAPES}\n" in logs  # a draw past the bound returns False
    started = next(r for r in records if r.topic == "core.started")
    assert started.data["debug_replay"] == "team"


def test_replays_show_it_to_the_team_and_to_everyone_only_when_the_match_says(tmp_path):
    from robo_comp.web.replay import Recording

    for choice in ("team", "everyone"):
        folder = tmp_path / choice
        folder.mkdir()
        _drawer_match(folder, choice, seconds=4.0)
        rec = Recording(folder / "events.log")
        assert rec.debug_replay == choice
        team = rec.build("red")
        assert any('"debug.draw"' in f for f in team.frags)
        assert not any('"debug.draw"' in f for f in rec.build("blue").frags)
        public = rec.build("public")
        assert any('"debug.draw"' in f for f in public.frags) == (choice == "everyone")


def test_the_wall_draws_it_and_its_keys_switch_it():
    import pygame

    from robo_comp.view.model import MatchView
    from robo_comp.wall.render import Renderer
    from robo_comp.wall.view import Layout, MapGeometry, TileSpec, ViewState
    from test_wall_render import interaction, snapshot

    pygame.display.init()
    pygame.font.init()
    m = MatchView(clock=lambda: 0.0)
    m.load_snapshot(snapshot())
    m.apply("debug.draw", {"team": "red", "tags": [101], "frames": [[["d", 8.0, 8.0, "#00ff00"],
                                                                      ["l", 2.0, 10.0, 12.0, 10.0, "#ff00ff"]]]})
    tile, view = TileSpec(width=1000, height=640), ViewState()
    geom = MapGeometry.of(Layout.of(tile.canvas), 30, 20, view)
    dot = geom.cell_centre(8.0, 8.0)
    mid = geom.cell_centre(7.0, 10.0)

    def shown() -> tuple[Any, Any]:
        surf = pygame.Surface(tile.size, 0, 32)
        Renderer(m, tile, view).draw(surf, None)
        return tuple(surf.get_at(dot))[:3], tuple(surf.get_at(mid))[:3]

    assert shown() == ((0, 255, 0), (255, 0, 255))
    act, _ = interaction(m, view, tile)
    act.key("d", 0.0)  # no robot selected: all of it off
    assert shown()[0] != (0, 255, 0)
    act.key("d", 0.0)
    act.selected = 101
    act.key("D", 0.0)  # the selected robot's team off
    assert view.debug_off_teams == ["red"] and shown()[1] != (255, 0, 255)
    act.key("D", 0.0)
    act.key("d", 0.0)  # the selected robot off
    assert view.debug_off_robots == [101] and shown()[0] != (0, 255, 0)
    m.apply("debug.draw", {"team": "red", "tags": [101], "frames": [[]]})  # an empty frame clears it
    assert m.debug == {}


# ---------------------------------------------------------------------- live, in Chromium
pytest.importorskip("starlette", reason="the web extra is not installed (pip install -e '.[web]')")

from conftest import wait_for, wait_robots  # noqa: E402
from robo_comp.testing import start_match  # noqa: E402
from robo_comp.web.server import view_key  # noqa: E402
from test_web import browser, open_page, start_web, stop  # noqa: E402,F401
from test_web_story import shot  # noqa: E402

DEBUG_STATE = """() => ({
  frames: robo.model.debug.size, shown: robo.renderer.debugShown || 0,
  panel: !document.getElementById('debug-panel').classList.contains('hidden'),
  rows: [...document.querySelectorAll('#debug-list label')].map(l => l.innerText.trim()),
})"""


def test_live_team_view_draws_it_and_the_public_view_never_gets_it(browser, tmp_path):  # noqa: F811
    state = tmp_path / "state"
    m = start_match(state, "demo_room", teams=["red", "blue"])
    web = None
    try:
        m.robots("red", 2)
        red = m.client("red", timeout=30)
        tags = [r["tag"] for r in wait_robots(red, 2)]
        out = red.upload(tags, "doodle.py", DOODLE)
        assert all(r["ok"] for r in out["results"]), out
        for tag in tags:
            red.give(tag, "doodle")
        web, url = start_web("--core", str(state), "--view-token-file", str(m.token_file("red")))
        frames: list[Any] = []
        public = open_page(browser, url, frames=frames)
        team = open_page(browser, url + f"#view=red&key={view_key(m.token('red'))}")
        team.wait_for_function("() => robo.S.view.kind === 'private'", timeout=15000)
        team.wait_for_function("() => robo.model.debug.size >= 2 && (robo.renderer.debugShown || 0) >= 6",
                               timeout=30000)
        # the side panel follows within a refresh of the page's panel (4 a second)
        wait_for(lambda: team.evaluate(DEBUG_STATE)["rows"][:2] == ["all", "red"], 10, "the debug panel's rows")
        got = team.evaluate(DEBUG_STATE)
        assert got["panel"], got
        path = shot(team, tmp_path, "debug-team-view.png")
        assert path.stat().st_size > 10_000
        # per team: red's box off → nothing drawn; on again → drawn
        team.click("#debug-list input[data-debug='red']")
        wait_for(lambda: team.evaluate(DEBUG_STATE)["shown"] == 0, 10, "red's drawing to go")
        team.click("#debug-list input[data-debug='red']")
        wait_for(lambda: team.evaluate(DEBUG_STATE)["shown"] >= 6, 10, "red's drawing to come back")
        # per robot: its info box switches it
        team.evaluate(f"() => robo.showInfo({{robot: {tags[0]}}})")
        team.click("#btn-debug")
        # (the other robot's frame may be between two of its turns on a loaded machine: at most its 3)
        wait_for(lambda: (lambda st: "1 robot hidden" in st["rows"][0] and st["shown"] <= 3)(team.evaluate(DEBUG_STATE)),
                 20, "one robot's drawing to go")
        # the public page: nothing of it, in its model or on its socket
        wait_for(lambda: public.evaluate("() => robo.model.robots.size") >= 2, 15, "the public page's robots")
        assert public.evaluate(DEBUG_STATE)["frames"] == 0 and not public.evaluate(DEBUG_STATE)["panel"]
        assert not any("debug.draw" in str(f) for f in frames)
        assert not team.errors and not public.errors, (team.errors, public.errors)
        team.close()
        public.close()
    finally:
        if web is not None:
            stop(web)
        m.close()
