"""The display wall against a real core with real robots: synthesised clicks become protocol
commands the robots really get, refusals are shown, and the real CLI takes screenshots."""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import numpy as np  # noqa: E402
import pygame  # noqa: E402
import pytest  # noqa: E402

from conftest import wait_for, wait_robots  # noqa: E402
from robo_comp.view import colours as C  # noqa: E402
from robo_comp.wall import render as R  # noqa: E402
from robo_comp.wall.app import LiveSource, WallApp  # noqa: E402
from robo_comp.view.model import MatchView  # noqa: E402
from robo_comp.wall.replay import ReplaySource  # noqa: E402
from robo_comp.wall.view import Layout, MapGeometry, TileSpec, ViewState  # noqa: E402


class FakeClock:
    """A clock the test moves by hand (double-click and path timing)."""

    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def walls_open():
    apps: list[WallApp] = []
    yield apps
    for a in apps:
        a.close()


def open_wall(core, team: str, apps: list[WallApp], clock: FakeClock) -> WallApp:
    src = LiveSource(str(core.state), core.token(team))
    model = MatchView()
    src.start(model)
    app = WallApp(model, TileSpec(width=1000, height=640), source=src, fps=0, clock=clock,
                  double_click=0.4, path_wait=0.5)
    apps.append(app)
    app.open_window()
    return app


def post_click(app: WallApp, canvas: tuple[int, int], button: int = 1) -> None:
    ox, oy = app.tile.origin
    pos = (canvas[0] - ox, canvas[1] - oy)
    pygame.event.post(pygame.event.Event(pygame.MOUSEBUTTONDOWN, pos=pos, button=button))
    pygame.event.post(pygame.event.Event(pygame.MOUSEBUTTONUP, pos=pos, button=button))
    app.step(wait=False)


def post_key(app: WallApp, key: int) -> None:
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=key, mod=0, unicode="", scancode=0))
    app.step(wait=False)


def free_cells_near(app: WallApp, x: float, y: float, n: int) -> list[tuple[int, int]]:
    walls = app.model.arena.walls
    cells = [(cx, cy) for cy in range(walls.shape[0]) for cx in range(walls.shape[1])
             if not walls[cy, cx] and 2 <= abs(cx - x) + abs(cy - y) <= 6
             and all(abs(cx - r.x) + abs(cy - r.y) >= 2 for r in app.model.robots.values())]
    return sorted(cells)[:n]


def robot_px(app: WallApp, tag: int) -> tuple[int, int]:
    r = app.model.robots[tag]
    return app.renderer.geometry().cell_centre(r.x, r.y)


def all_tasks(client, tag: int) -> list[dict]:
    t = client.tasks(tag)
    return [x for x in [t["current"], t["pending"], *t["queued"], *t["done"]] if x]


def test_clicks_give_goto_and_followpath_and_double_click_opens_the_monitor(core, walls_open):
    core.robots("red", 2, "--speed", "10")
    red = core.client("red")
    tags = [r["tag"] for r in wait_robots(red, 2)]
    clock = FakeClock()
    app = open_wall(core, "red", walls_open, clock)
    wait_for(lambda: (app.step(wait=False), set(tags) <= set(app.model.robots))[1], 5, "robots on the wall")
    tag = tags[0]
    r = app.model.robots[tag]
    # robot, then one point, then the path wait: goTo
    target = free_cells_near(app, r.x, r.y, 1)[0]
    post_click(app, robot_px(app, tag))
    assert app.interaction.selected == tag
    clock.t += 0.1
    post_click(app, app.renderer.geometry().cell_centre(*target))
    clock.t += 0.6
    app.step(wait=False)
    goto = wait_for(lambda: [t for t in all_tasks(red, tag) if t["name"] == "goTo"], 5, "the goTo")
    assert goto[0]["args"] == list(target) and goto[0]["mode"] == "now"
    assert "given" in app.model.messages[-1].text
    wait_for(lambda: red.tasks(tag)["done"], 10, "the goTo to finish")
    app.step(wait=False)
    # another robot, then three points, then Enter: followPath
    other = tags[1]
    o = app.model.robots[other]
    ox_, oy_ = round(o.x), round(o.y)
    path = [(ox_ + 2, oy_), (ox_ + 4, oy_), (ox_ + 4, oy_ + 2)]  # away from the first robot
    assert not any(app.model.arena.walls[y, x] for x, y in path)
    clock.t += 5
    post_click(app, robot_px(app, other))
    for c in path:
        clock.t += 0.2
        post_click(app, app.renderer.geometry().cell_centre(*c))
    clock.t += 2  # a path does not time out into a goTo
    app.step(wait=False)
    assert app.interaction.points == path
    post_key(app, pygame.K_RETURN)
    assert "followPath" in app.model.messages[-1].text, list(app.model.messages)
    fp = wait_for(lambda: [t for t in all_tasks(red, other) if t["name"] == "followPath"], 5, "the followPath")
    assert fp[0]["args"] == [[list(c) for c in path]]
    # double click a robot: its monitor box, filled from the core (tried again, up to three times,
    # when the other robot, driving its path, was drawn over it at a click)
    for _ in range(3):
        clock.t += 5
        post_click(app, robot_px(app, tag))
        clock.t += 0.2
        post_click(app, robot_px(app, tag))
        if app.view.monitors:
            break
    assert app.view.monitors == [tag]
    clock.t += 2
    wait_for(lambda: (app.step(wait=False), tag in app.monitor_data)[1], 5, "the monitor's answer")
    assert app.monitor_data[tag]["tag"] == tag and app.monitor_data[tag]["advertised"]
    assert ("monitor", tag) in app.renderer.boxes
    # a find reported with a picture as evidence: click it, see what is known and the picture
    r = app.model.robots[tag]
    wait_for(lambda: all(red.tasks(t)["current"] is None for t in tags), 15, "both robots to arrive")
    m = red.monitor(tag)
    red.give(tag, "examineArea", [round(m["x"]), round(m["y"])])
    pics = wait_for(lambda: (app.step(wait=False), [t for t in app.model.things.values() if t.kind == "picture"])[1],
                    15, "a picture on the wall")
    spot = free_cells_near(app, r.x, r.y, 1)[0]
    red.request("find", tag=tag, x=spot[0], y=spot[1], kind="victim", evidence=[pics[0].id])
    wait_for(lambda: (app.step(wait=False), "find:1" in app.model.things)[1], 5, "the find on the wall")
    # the ticker follows the live feed: the find is its newest line (issue 29)
    app.step(wait=False)
    assert app.renderer.ticker and app.renderer.ticker[0].kind == "find" and app.renderer.ticker[0].tag == tag
    clock.t += 5
    post_click(app, app.renderer.geometry().cell_centre(*spot))
    assert app.view.info == "find:1"
    png = app.pictures[pics[0].id]
    assert isinstance(png, bytes) and png.startswith(b"\x89PNG")
    assert "info" in app.renderer.boxes and app.model.things["find:1"].state in ("rejected", "confirmed")


def test_a_team_wall_cannot_command_another_teams_robot_and_shows_the_refusal(core, walls_open, tmp_path):
    core.robots("red", 1)
    red = core.client("red")
    tag = wait_robots(red, 1)[0]["tag"]
    clock = FakeClock()
    app = open_wall(core, "blue", walls_open, clock)
    # blue's snapshot holds no red robots; the public feed shows them
    wait_for(lambda: (app.step(wait=False), tag in app.model.robots)[1], 5, "the red robot on blue's wall")
    r = app.model.robots[tag]
    target = free_cells_near(app, r.x, r.y, 1)[0]
    post_click(app, robot_px(app, tag))
    clock.t += 0.1
    post_click(app, app.renderer.geometry().cell_centre(*target))
    clock.t += 0.6
    app.step(wait=False)
    msg = app.model.messages[-1]
    assert msg.level == "error" and msg.text.startswith("refused: goTo for robot")
    assert "not one of team blue" in msg.text
    assert not [t for t in all_tasks(red, tag) if t["name"] == "goTo"]
    # the refusal is on the message bar, in the error colour
    shot = pygame.image.load(str(app.screenshot(tmp_path / "refused.png")))
    bx, by, bw, bh = app.renderer.layout.bar
    bar = pygame.surfarray.array3d(shot)[bx:bx + bw, by:by + bh]
    assert (bar == R.ERROR).all(axis=2).sum() > 20
    # blue may not read red's monitor either: the box says so
    clock.t += 5
    post_click(app, robot_px(app, tag))
    clock.t += 0.1
    post_click(app, robot_px(app, tag))
    clock.t += 2
    wait_for(lambda: (app.step(wait=False), tag in app.monitor_data)[1], 5, "the monitor's answer")
    assert str(app.monitor_data[tag]).startswith("refused:")
    # several walls at once: the referee's wall beside blue's sees the same robot
    ref_model = MatchView()
    ref_src = LiveSource(str(core.state), core.token("referee"))
    walls_open.append(WallApp(ref_model, TileSpec(), source=ref_src))
    ref_src.start(ref_model)
    assert tag in ref_model.robots and ref_model.robots[tag].team == "red"
    app.step(wait=False)
    assert app.model.robots[tag].status == "connected"


def test_a_core_that_does_not_answer_never_holds_up_the_frames(core, walls_open, monkeypatch):
    core.robots("red", 1)
    tag = wait_robots(core.client("red"), 1)[0]["tag"]
    clock = FakeClock()
    app = open_wall(core, "red", walls_open, clock)
    app.view.monitors.append(tag)
    wait_for(lambda: (app.step(wait=False), isinstance(app.monitor_data.get(tag), dict))[1], 5, "the monitor")
    os.kill(core.proc.pid, signal.SIGSTOP)  # a core that answers nothing
    with monkeypatch.context() as m:  # no frame may wait for the core's answer
        m.setattr(app.source.client, "request", lambda *a, **k: pytest.fail("a frame waited for the core"))
        try:
            clock.t += 2  # a refresh is due: the wall asks, and draws on without the answer
            for _ in range(5):
                app.step(wait=False)
            assert isinstance(app.monitor_data[tag], dict)  # the last answer stays up meanwhile
            clock.t += 4  # longer than the client's timeout (3 s)
            app.step(wait=False)
            assert str(app.monitor_data[tag]).startswith("no answer from the core")
        finally:
            os.kill(core.proc.pid, signal.SIGCONT)
    clock.t += 2
    wait_for(lambda: (app.step(wait=False), isinstance(app.monitor_data.get(tag), dict))[1], 5,
             "the monitor once the core answers again")


def wall_cli(*args: str) -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-m", "robo_comp.wall.cli", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


def finish(p: subprocess.Popen[bytes]) -> str:
    out = p.communicate(timeout=60)[0].decode()
    assert p.returncode == 0, out
    return out


def test_cli_screenshots_live_and_from_a_replay_in_tiles(core, tmp_path):
    core.robots("red", 2, "--speed", "10")
    core.robots("blue", 2, "--speed", "10")
    ref = core.client("referee")
    rows = wait_robots(ref, 4)
    shot = tmp_path / "live.png"
    finish(wall_cli("--core", str(core.state), "--token-file", str(core.state / "referee.token"),
                    "--screenshot", str(shot), "--size", "900x560"))
    img = pygame.image.load(str(shot))
    arena = ref.arena()
    colours = {t["name"]: C.hex_rgb(t["colour"]) for t in arena["teams"]}
    geom = MapGeometry.of(Layout.of((900, 560)), arena["width"], arena["height"], ViewState())
    for row in rows:  # every robot, in its team's colour, where the core says it is (a standing
        # robot's reported pose moves with the positioning's noise, a pixel or two, which can put
        # the centre pixel on its heading line: the team's colour within 3 pixels of it)
        cx, cy = geom.cell_centre(row["x"], row["y"])
        near = {tuple(img.get_at((cx + dx, cy + dy)))[:3] for dx in range(-3, 4) for dy in range(-3, 4)}
        assert colours[row["team"]] in near, (row, near)
    # a recorded match: 4 tiles of a 2x2 wall from 4 processes stitch to the single window
    ref.give(rows[0]["tag"], "goTo", [4, 4])
    wait_for(lambda: ref.tasks(rows[0]["tag"])["done"], 15, "the goTo to finish")
    log = tmp_path / "events.log"
    shutil.copy(core.state / "events.log", log)
    common = ["--replay", str(log), "--zoom", "1.3", "--pan", "2,1"]
    procs = []
    for c in range(2):
        for r in range(2):
            procs.append(wall_cli(*common, "--grid", "2x2", "--tile", f"{c},{r}", "--size", "320x200",
                                  "--screenshot", str(tmp_path / f"tile{c}{r}.png")))
    for p in procs:
        finish(p)
    # the single window, rendered here from the same log with the same view
    model = MatchView()
    src = ReplaySource(log)
    src.attach(model)
    src.seek(model, src.duration)
    whole_app = WallApp(model, TileSpec(1, 1, 0, 0, 640, 400), ViewState(1.3, 2.0, 1.0), source=src)
    whole = pygame.surfarray.array3d(pygame.image.load(str(whole_app.screenshot(tmp_path / "whole.png"))))
    stitched = np.zeros_like(whole)
    for c in range(2):
        for r in range(2):
            stitched[c * 320:(c + 1) * 320, r * 200:(r + 1) * 200] = pygame.surfarray.array3d(
                pygame.image.load(str(tmp_path / f"tile{c}{r}.png")))
    assert np.array_equal(whole, stitched)
    assert (whole == colours["red"]).all(axis=2).sum() > 20  # the replay shows the robots


def test_cli_explains_bad_flags(tmp_path: Path):
    p = wall_cli("--screenshot", str(tmp_path / "x.png"))
    out = p.communicate(timeout=60)[0].decode()
    assert p.returncode == 2 and "--core" in out
    p = wall_cli("--replay", str(tmp_path / "nope.log"), "--grid", "2x2", "--tile", "2,0", "--screenshot", "x.png")
    out = p.communicate(timeout=60)[0].decode()
    assert p.returncode == 2 and "outside the 2x2 grid" in out
