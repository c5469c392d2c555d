"""The display wall without a core: model, pixel checks on headless renders, 2×2 tile stitching,
the click state machine and replays."""
from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import numpy as np  # noqa: E402
import pygame  # noqa: E402
import pytest  # noqa: E402

from robo_comp.core.eventlog import EventLog  # noqa: E402
from robo_comp.view import colours as C  # noqa: E402
from robo_comp.wall import render as R  # noqa: E402
from robo_comp.wall.interact import Command, Interaction  # noqa: E402
from robo_comp.view.model import MatchView  # noqa: E402
from robo_comp.wall.render import Overlay, Renderer  # noqa: E402
from robo_comp.wall.replay import ReplaySource  # noqa: E402
from robo_comp.wall.view import Layout, MapGeometry, TileSpec, ViewState  # noqa: E402

W, H = 30, 20
RED, BLUE = "#d03030", "#3060d0"


@pytest.fixture(scope="module", autouse=True)
def _pygame():
    pygame.display.init()
    pygame.font.init()
    yield


def arena_payload() -> dict:
    walls = np.zeros((H, W), bool)
    walls[0, :] = walls[-1, :] = walls[:, 0] = walls[:, -1] = True
    walls[4:16, 15] = True
    return {"name": "Test arena", "width": W, "height": H, "cell_cm": 25.0,
            "walls": np.packbits(walls, axis=None).tobytes(),
            "zones": [{"kind": "water", "x": 20, "y": 2, "w": 4, "h": 3}],
            "objects": [{"id": "door", "kind": "door", "x": 25, "y": 15, "description": "a door"}],
            "teams": [{"name": "red", "colour": RED, "start": {"x": 1, "y": 1, "w": 3, "h": 3}},
                      {"name": "blue", "colour": BLUE, "start": {"x": 26, "y": 16, "w": 3, "h": 3}}]}


def snapshot() -> dict:
    robots = [{"tag": 101, "team": "red", "status": "connected", "x": 5.0, "y": 5.0, "heading": 0.0},
              {"tag": 102, "team": "blue", "status": "connected", "x": 10.0, "y": 12.0, "heading": 90.0},
              {"tag": 103, "team": "red", "status": "lost", "x": 20.0, "y": 10.0, "heading": 180.0},
              {"tag": 104, "team": "blue", "status": "left", "x": 22.0, "y": 12.0, "heading": 0.0}]
    return {"arena": arena_payload(), "teams": ["red", "blue"], "robots": robots, "seq": 5,
            "match": {"phase": "running", "elapsed": 75.0, "remaining": 225.0},
            "score": [{"team": "blue", "score": 10, "victims": 1, "penalties": 0, "rank": 1},
                      {"team": "red", "score": 0, "victims": 0, "penalties": 0, "rank": 2}],
            "finds": []}


def model() -> MatchView:
    m = MatchView(clock=lambda: 0.0)
    m.load_snapshot(snapshot())
    m.apply("find.reported", {"id": 1, "team": "blue", "tag": 102, "x": 8.0, "y": 16.0, "kind": "victim",
                              "state": "confirmed", "evidence": [7]})
    m.apply("find.reported", {"id": 2, "team": "red", "tag": 101, "x": 3.0, "y": 16.0, "kind": "victim",
                              "state": "rejected", "evidence": []})
    m.apply("map.discovery", {"id": 3, "x": 12.0, "y": 2.0, "kind": "rubble", "team": "red", "finder": 101})
    m.apply("no.such.topic", {"whatever": 1})  # future events are ignored
    return m


def render(m: MatchView, tile: TileSpec, view: ViewState | None = None, overlay: Overlay | None = None):
    surf = pygame.Surface(tile.size, 0, 32)
    r = Renderer(m, tile, view or ViewState())
    r.draw(surf, None, overlay)
    return surf, r


def px(surf: pygame.Surface, p: tuple[int, int]) -> tuple[int, int, int]:
    return tuple(surf.get_at(p))[:3]


def test_model_follows_events():
    m = model()
    assert set(m.robots) == {101, 102, 103, 104}
    m.apply("robot.lost", {"tag": 101, "x": 5.0, "y": 5.0})
    assert m.robots[101].status == "lost"
    m.apply("robot.returned", {"tag": 101, "x": 5.0, "y": 5.0})
    assert m.robots[101].status == "connected"
    m.apply("robot.positions", {"team": "blue", "tags": [201, 202], "x": [3.0, 6.0], "y": [4.0, 7.0],
                                "heading": [45.0, 90.0], "moving": [True, False]})
    assert (m.robots[201].team, m.robots[201].x, m.robots[201].heading) == ("blue", 3.0, 45.0)
    assert (m.robots[202].y, m.robots[202].moving, m.robots[201].moving) == (7.0, False, True)
    m.apply("match.phase", {"phase": "paused", "elapsed": 80.0, "remaining": 220.0})
    assert m.match.now(100.0) == (80.0, 220.0)  # a paused clock does not run
    m.apply("score", {"teams": [{"team": "red", "score": 5, "rank": 1}]})
    assert m.score[0]["team"] == "red"
    m.apply("broadcast", {"message": "five minutes left"})
    assert m.messages[-1].level == "broadcast"
    assert m.things["find:1"].state == "confirmed" and m.things["find:1"].pictures() == [7]
    assert m.things["object:door"].info["description"] == "a door"


def test_screenshot_pixels_walls_robots_lost_marker_finds_scoreboard(tmp_path):
    tile = TileSpec(width=1000, height=640)
    m = model()
    surf, r = render(m, tile)
    geom = r.geometry()
    assert geom is not None
    # a wall cell (the inner wall at column 15) and a free floor cell
    assert px(surf, geom.cell_centre(15, 8)) == C.WALL
    assert px(surf, geom.cell_centre(8, 8)) == C.FLOOR
    assert px(surf, geom.cell_centre(14, 8)) == C.NEAR_WALL  # cost shading beside the wall
    # one robot of each team in its colour; the lost robot under its marker; the left one not drawn
    assert px(surf, geom.cell_centre(5, 5)) == C.hex_rgb(RED)
    assert px(surf, geom.cell_centre(10, 12)) == C.hex_rgb(BLUE)
    assert px(surf, geom.cell_centre(20, 10)) == C.LOST_MARK
    assert px(surf, geom.cell_centre(22, 12)) == C.FLOOR
    # finds by state, a discovery, a known object
    assert px(surf, geom.cell_centre(8, 16)) == C.FIND_COLOURS["confirmed"]
    assert px(surf, geom.cell_centre(3, 16)) == C.FIND_COLOURS["rejected"]
    assert px(surf, geom.cell_centre(12, 2)) == C.DISCOVERY
    assert px(surf, geom.cell_centre(25, 15)) == R.OBJECT
    # the scoreboard: a row per team, in rank order, with text on it
    rows = r.score_rows
    assert rows["blue"][1] < rows["red"][1]
    x, y, w, h = rows["blue"]
    # the row shows exactly "1. blue" as the renderer's font draws it, after the swatch
    label = r.text("1. blue", r.layout.px(20), R.TEXT)
    expect = pygame.Surface(label.get_size(), 0, 32)
    expect.fill(R.BOX_BG)
    expect.blit(label, (0, 0))
    tx = x + r.layout.px(22)
    got = pygame.surfarray.array3d(surf)[tx:tx + label.get_width(), y:y + label.get_height()]
    assert (got != R.BOX_BG).any(axis=2).sum() > 20
    assert np.array_equal(got, pygame.surfarray.array3d(expect))
    # the team swatch in the scoreboard row
    assert px(surf, (x + 3, y + h // 2)) == C.hex_rgb(BLUE)
    pygame.image.save(surf, str(tmp_path / "wall.png"))
    assert pygame.image.load(str(tmp_path / "wall.png")).get_size() == (1000, 640)


@pytest.mark.parametrize("zoom,pan", [(1.0, (0.0, 0.0)), (1.9, (3.3, -2.7)), (0.6, (0.0, 1.0))])
def test_tiles_of_a_2x2_grid_stitch_to_the_single_window(zoom, pan):
    m = model()
    for r in m.robots.values():  # trails that cross tile edges
        for k in range(6):
            r.move(r.x + 0.7, r.y + 0.4, r.heading)
    m.note("refused: not yours", "error")
    tw, th = 317, 203  # odd sizes: nothing may rely on even halves
    view = ViewState(zoom, *pan, monitors=[101], info="find:1")
    overlay = Overlay(selected=102, points=[(3, 3), (25, 17)], monitor_data={101: {"status": "connected"}},
                      info_thing=m.things["find:1"])
    single, _ = render(m, TileSpec(1, 1, 0, 0, 2 * tw, 2 * th), view, overlay)
    stitched = pygame.Surface((2 * tw, 2 * th), 0, 32)
    for c in range(2):
        for r in range(2):
            tile, _ = render(m, TileSpec(2, 2, c, r, tw, th), view, overlay)
            stitched.blit(tile, (c * tw, r * th))
    a, b = pygame.surfarray.array3d(single), pygame.surfarray.array3d(stitched)
    diff = np.argwhere((a != b).any(axis=2))
    assert len(diff) == 0, f"{len(diff)} pixels differ, first {diff[:5].tolist()}"


def test_incremental_frames_equal_full_redraws():
    m = model()
    tile = TileSpec(2, 1, 1, 0, 500, 320)  # a tile whose edge cuts the map
    view = ViewState(1.4, 1.0, 0.5)
    r = Renderer(m, tile, view)
    screen = pygame.Surface(tile.size, 0, 32)
    rng = np.random.default_rng(3)
    for frame in range(40):
        tags = list(m.robots)
        m.apply("robot.positions", {
            "tags": tags, "x": [float(np.clip(m.robots[t].x + rng.uniform(-0.4, 0.6), 1, W - 2)) for t in tags],
            "y": [float(np.clip(m.robots[t].y + rng.uniform(-0.4, 0.5), 1, H - 2)) for t in tags],
            "heading": [float(rng.uniform(0, 360)) for _ in tags]})
        if frame == 10:
            m.apply("robot.lost", {"tag": 102})
        if frame == 20:
            view.monitors.append(101)
            m.note("refused: something", "error")
        selected = 101 if 15 <= frame < 30 else None
        overlay = Overlay(selected=selected, points=[(20, 5), (25, 12)] if selected else [])
        r.draw(screen, None, overlay, incremental=True)
        fresh = pygame.Surface(tile.size, 0, 32)
        Renderer(m, tile, view).draw(fresh, None, overlay)
        a, b = pygame.surfarray.array3d(screen), pygame.surfarray.array3d(fresh)
        assert np.array_equal(a, b), f"frame {frame}: {int((a != b).any(axis=2).sum())} pixels differ"


def test_zoom_factor_fits_any_arena_into_any_window():
    for size, arena in (((1024, 768), (10, 10)), ((7168, 3072), (512, 512)), ((640, 400), (2000, 300))):
        layout = Layout.of(size)
        g = MapGeometry.of(layout, arena[0], arena[1], ViewState())
        mx, my, mw, mh = layout.map
        assert mx <= g.edge_x(0) and g.edge_x(arena[0]) <= mx + mw
        assert my <= g.edge_y(0) and g.edge_y(arena[1]) <= my + mh
        assert g.edge_x(arena[0]) - g.edge_x(0) >= mw - 2 or g.edge_y(arena[1]) - g.edge_y(0) >= mh - 2


def interaction(m: MatchView, view: ViewState, tile: TileSpec) -> tuple[Interaction, Renderer]:
    r = Renderer(m, tile, view)
    return Interaction(m, view, r.layout, r.geometry, r.panel_boxes, r.robot_radius,
                       double_click=0.4, path_wait=1.0), r


def test_click_state_machine():
    m, view, tile = model(), ViewState(), TileSpec(width=1000, height=640)
    it, r = interaction(m, view, tile)
    g = r.geometry()
    robot = g.cell_centre(5, 5)
    # robot then one point: goTo once the path wait is over
    assert it.click(*robot, 1, now=10.0) == []
    assert it.click(*g.cell_centre(8, 9), 1, now=10.5) == []
    assert it.tick(11.0) == []
    assert it.tick(11.6) == [Command("give", tag=101, task="goTo", args=[8, 9])]
    # robot then several points then Enter: followPath
    it.click(*robot, 1, now=20.0)
    for i, c in enumerate([(8, 9), (9, 12), (3, 14)]):
        it.click(*g.cell_centre(*c), 1, now=21.0 + i * 0.3)
    assert it.tick(30.0) == []  # a path waits for Enter or a right click
    assert it.key("enter", 30.0) == [Command("give", tag=101, task="followPath", args=[[[8, 9], [9, 12], [3, 14]]])]
    # right click ends a path too; Esc drops it
    it.click(*robot, 1, now=40.0)
    it.click(*g.cell_centre(8, 9), 1, now=40.2)
    it.click(*g.cell_centre(9, 9), 1, now=40.4)
    assert it.click(0, 0, 3, now=40.6)[0].task == "followPath"
    it.click(*robot, 1, now=50.0)
    it.click(*g.cell_centre(8, 9), 1, now=50.2)
    it.key("escape", 50.3)
    assert it.tick(60.0) == [] and it.selected is None
    # double click: monitor; a slow second click only selects
    it.click(*robot, 1, now=70.0)
    assert it.click(*robot, 1, now=70.3) == [Command("monitor", tag=101)]
    it.click(*robot, 1, now=80.0)
    assert it.click(*robot, 1, now=81.0) == [] and it.selected == 101
    it.cancel()
    # an object: its info
    assert it.click(*g.cell_centre(8, 16), 1, now=90.0) == [Command("info", key="find:1")]
    # zoom and pan keys change the shared view
    it.key("+", 91.0)
    it.key("right", 91.0)
    assert view.zoom == pytest.approx(1.25) and view.pan_x > 0
    it.key("0", 92.0)
    assert (view.zoom, view.pan_x) == (1.0, 0.0)


def test_clicks_in_a_tile_map_to_the_same_cells_as_on_the_whole_canvas():
    m = model()
    whole, _ = interaction(m, ViewState(), TileSpec(1, 1, 0, 0, 2000, 1280))
    t11, r11 = interaction(m, ViewState(), TileSpec(2, 2, 1, 1, 1000, 640))
    for cell in [(20, 10), (25, 15), (16, 12)]:
        cx, cy = r11.geometry().cell_centre(*cell)
        assert whole.hit(cx, cy) == t11.hit(cx, cy)


def test_replay_feeds_the_model_from_an_event_log(tmp_path: Path):
    log = EventLog(tmp_path / "events.log")
    t0 = 1000.0
    log.append("core.started", None, {"router": "tcp://x", "teams": ["red", "blue"], "arena": arena_payload()}, t=t0)
    log.append("robot.registered", "red", {"tag": 101, "team": "red", "x": 1.0, "y": 1.0, "heading": 0.0}, t=t0 + 1)
    log.append("match.phase", "*", {"phase": "running", "elapsed": 0.0, "remaining": 300.0}, t=t0 + 1)
    log.append("robot.positions", None, {"tags": [101], "x": [4.0], "y": [2.0], "heading": [0.0]}, t=t0 + 5)
    log.append("robot.lost", "red", {"tag": 101, "x": 4.0, "y": 2.0, "message": "gone"}, t=t0 + 9)
    log.close()
    fake = [0.0]
    src = ReplaySource(tmp_path / "events.log", speed=4.0, clock=lambda: fake[0])
    m = MatchView()
    src.attach(m)
    src.advance(m)
    assert m.arena is not None and not m.robots  # the log's first event carries the arena
    fake[0] = 0.5  # 2 s of match at 4x
    src.advance(m)
    assert m.robots[101].x == 1.0 and m.match.phase == "running"
    fake[0] = 1.5  # 6 s
    src.advance(m)
    assert m.robots[101].x == 4.0 and m.robots[101].status == "connected"
    fake[0] = 3.0
    src.advance(m)
    assert src.done and m.robots[101].status == "lost"


def test_a_master_tile_shares_zoom_pan_and_panels_with_its_followers():
    import time

    from robo_comp.wall.app import WallApp

    m = model()
    master = WallApp(m, TileSpec(2, 1, 0, 0, 400, 300), view_pub="tcp://127.0.0.1:*", fps=0)
    follower = WallApp(m, TileSpec(2, 1, 1, 0, 400, 300), view_sub=master.view_pub_url, fps=0)
    try:
        master.interaction.key("+", 0.0)
        master.interaction.key("down", 0.0)
        master.view.monitors.append(101)
        t_end = time.monotonic() + 5
        while follower.view.to_dict() != master.view.to_dict() and time.monotonic() < t_end:
            master.step(wait=False)
            master._view_sent = (None, 0.0)  # resend every turn: the follower may join late
            follower.step(wait=False)
            time.sleep(0.02)
        assert follower.view.to_dict() == master.view.to_dict()
        assert follower.view.zoom == pytest.approx(1.25) and follower.view.monitors == [101]
    finally:
        master.close()
        follower.close()


def test_a_storage_fault_stays_on_the_message_bar_while_it_lasts():
    m = model()
    tile = TileSpec(1, 1, 0, 0, 1000, 640)

    def bar_has_error_text() -> bool:
        surf, r = render(m, tile)
        x, y, w, h = r.layout.bar
        pixels = pygame.surfarray.array3d(surf.subsurface((x, y, w, h)))
        return bool((pixels == np.array(R.ERROR)).all(axis=2).any())

    assert not bar_has_error_text()
    m.apply("core.storage", {"ok": False, "message": "the core cannot write its event log (disk full)"})
    assert m.storage and bar_has_error_text()
    m.messages.clear()  # the message bar's lines time out; the fault stays until the core says it is over
    assert bar_has_error_text()
    m.apply("core.storage", {"ok": True, "message": "the event log is written again (after 3.0 s)"})
    assert m.storage is None
    m.messages.clear()
    assert not bar_has_error_text()


def test_a_video_plays_in_the_info_box_of_a_replay(tmp_path: Path):
    """examineArea's video (issue 33), beside a recorded match as the core keeps it: the wall reads
    its frames back and plays them in the info box, frame after frame."""
    from robo_comp.wall.app import WallApp
    from robo_comp.wall.interact import Command
    from robo_comp.world.video import FPS, encode_webm

    colours = [(250, 20, 20), (20, 250, 20), (20, 20, 250), (250, 250, 20)]
    frames = [np.full((64, 96, 3), c, np.uint8) for c in colours]
    log = EventLog(tmp_path / "events.log")
    t0 = 1000.0
    log.append("core.started", None, {"router": "tcp://x", "teams": ["red", "blue"], "arena": arena_payload()}, t=t0)
    log.append("video", "red", {"id": 1, "tag": 101, "team": "red", "x": 6.0, "y": 6.0, "heading": 0.0, "t": t0 + 1,
                                "seconds": 0.5, "frames": 4, "label": "examine-6-6"}, t=t0 + 1)
    log.close()
    (tmp_path / "videos").mkdir()
    (tmp_path / "videos" / "1.webm").write_bytes(encode_webm(frames))
    fake = [0.0]
    src = ReplaySource(tmp_path / "events.log", speed=100.0, clock=lambda: fake[0])
    m = MatchView()
    src.attach(m)
    src.advance(m)
    fake[0] = 1.0  # 100 s of the match at 100x
    src.advance(m)
    assert "video:1" in m.things
    app = WallApp(m, TileSpec(width=1000, height=640), source=src)
    app.execute(Command("info", key="video:1"))
    assert isinstance(app.videos[1], list) and len(app.videos[1]) == 4
    seen = []
    for k in range(4):  # the frame shown follows the clock
        surf = pygame.Surface((1000, 640), 0, 32)
        app.renderer.draw(surf, (k + 0.5) / FPS, app.overlay())
        pix = pygame.surfarray.array3d(surf)
        seen.append([c for c in colours if (np.abs(pix.astype(int) - c).sum(axis=2) < 40).sum() > 2000])
    assert [s[0] for s in seen if len(s) == 1] == colours, seen
