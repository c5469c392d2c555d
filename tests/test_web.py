"""The web gateway in a real browser (Debian's chromium driven by Playwright) against a real
core with real robot hosts: robots move on the canvas, a team's private view shows nothing of
the other team, a replay seeks to the right state, and screenshots are taken.

One browser is launched for the module. Where no browser can be had the browser tests skip,
saying why; the protocol tests without a browser still run.
"""
from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("starlette", reason="the web extra is not installed (pip install -e '.[web]')")

from conftest import wait_for, wait_robots
from robo_comp.core.eventlog import EventLog
from robo_comp.testing import Match, start_match
from robo_comp.view.model import MatchView
from robo_comp.protocol import public_event
from robo_comp.world.public import arena_payload
from robo_comp.world.scenario import bundled_scenario_path, load_scenario

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]


def chromium_path() -> str | None:
    """Debian's chromium (never a browser downloaded by a tool's installer)."""
    for name in ("chromium", "chromium-browser"):
        p = shutil.which(name)
        if p:
            return p
    return None


def start_web(*args: str, cwd: Path | None = None) -> tuple[subprocess.Popen[str], str]:
    """Start ``robo-comp web`` on a free port; return the process and the URL it prints."""
    proc = subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "web", "--port", "0", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=cwd)
    line: list[str] = []
    t = threading.Thread(target=lambda: line.append(proc.stdout.readline() if proc.stdout else ""), daemon=True)
    t.start()
    t.join(30)
    m = re.search(r"http://\S+", line[0] if line else "")
    if m is None:
        proc.kill()
        out = proc.communicate()[0]
        raise RuntimeError(f"robo-comp web did not start: {(line[0] if line else '')}{out[-2000:]}")
    return proc, m.group(0)


def stop(proc: subprocess.Popen[str]) -> None:
    proc.terminate()
    try:
        proc.wait(5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def in_thread(fn: Any) -> Any:
    """Run ``fn`` in a thread of its own (Playwright's sync API holds this thread's event loop)."""
    out: list[Any] = []
    err: list[BaseException] = []

    def target() -> None:
        try:
            out.append(fn())
        except BaseException as e:  # handed to the caller
            err.append(e)

    t = threading.Thread(target=target)
    t.start()
    t.join(60)
    if err:
        raise err[0]
    return out[0]


# ---------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def browser():
    """One headless chromium for every browser test of this module."""
    exe = chromium_path()
    if exe is None:
        pytest.skip("no chromium on this machine (apt-get install chromium; .ci/run does it where apt exists)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("the playwright package is not installed (pip install -e '.[web]')")
    with sync_playwright() as p:
        try:
            b = p.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS)
        except Exception as e:  # a browser that cannot start here
            pytest.skip(f"chromium at {exe} does not start: {str(e).splitlines()[0]}")
        yield b
        b.close()


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory):
    """A core (demo room, practice), two robots each for red and blue, and a web gateway."""
    state = tmp_path_factory.mktemp("web") / "state"
    m = start_match(state, teams=["red", "blue"])
    web = None
    try:
        m.robots("red", 2)
        m.robots("blue", 2)
        red, blue = m.client("red"), m.client("blue")
        wait_robots(red, 2)
        wait_robots(blue, 2)
        for c, goals in ((red, [(5, 12), (6, 12)]), (blue, [(16, 13), (17, 13)])):
            for row, goal in zip(c.robots(), goals):
                c.give(row["tag"], "goTo", list(goal))
        web, url = start_web("--core", str(state), "--view-token-file", str(m.token_file("red")))
        yield m, url
    finally:
        if web is not None:
            stop(web)
        m.close()


def open_page(browser, url: str, *, width: int = 1280, height: int = 800, frames: list[str] | None = None):
    page = browser.new_page(viewport={"width": width, "height": height})
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    # what the page's Content-Security-Policy refused (an inline style, a script) counts as an error too
    page.on("console", lambda m: errors.append(m.text) if "Content Security Policy" in m.text else None)
    if frames is not None:
        page.on("websocket", lambda ws: ws.on("framereceived", lambda payload: frames.append(payload)))
    page.goto(url)
    page.wait_for_function("() => window.robo && robo.model.arena !== null", timeout=15000)
    page.errors = errors  # type: ignore[attr-defined]
    return page


def drive_far(c: Any) -> None:
    """Give each of the client's robots a goTo to the free cell farthest from where it is (so it
    drives for seconds whatever it did before)."""
    from robo_comp.protocol import unpack_walls

    walls = unpack_walls(c.arena())
    free = [(x, y) for y in range(walls.shape[0]) for x in range(walls.shape[1]) if not walls[y, x]]
    for i, r in enumerate(c.robots()):
        far = sorted(free, key=lambda p: -(abs(p[0] - r["x"]) + abs(p[1] - r["y"])))
        c.give(r["tag"], "goTo", list(far[i]))


COLOUR_PIXELS = """(hex) => {
  const c = document.getElementById('map');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  const r = parseInt(hex.slice(1, 3), 16), g = parseInt(hex.slice(3, 5), 16), b = parseInt(hex.slice(5, 7), 16);
  let n = 0, sx = 0, sy = 0;
  for (let i = 0; i < d.length; i += 4) {
    if (Math.abs(d[i] - r) <= 2 && Math.abs(d[i + 1] - g) <= 2 && Math.abs(d[i + 2] - b) <= 2) {
      const p = i / 4; n++; sx += p % c.width; sy += Math.floor(p / c.width);
    }
  }
  return n ? [n, sx / n, sy / n] : [0, 0, 0];
}"""


def team_colour(page, team: str) -> str:
    return page.evaluate("(t) => robo.model.colour(t)", team)


def pixels(page, team: str) -> list[float]:
    page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
    return page.evaluate(COLOUR_PIXELS, team_colour(page, team))


# ---------------------------------------------------------------------- live
def test_live_robots_move_on_the_canvas(browser, live, tmp_path: Path) -> None:
    m, url = live
    page = open_page(browser, url)
    try:
        page.wait_for_function("() => robo.model.robots.size >= 4", timeout=15000)
        view = page.evaluate("() => robo.S.view")
        assert view["kind"] == "public"
        before = {team: pixels(page, team) for team in ("red", "blue")}
        assert before["red"][0] > 20 and before["blue"][0] > 20, before  # robots drawn in team colours
        drive_far(m.client("red"))
        drive_far(m.client("blue"))

        def moved() -> bool:
            now = {team: pixels(page, team) for team in ("red", "blue")}
            return all(abs(now[t][1] - before[t][1]) + abs(now[t][2] - before[t][2]) > 6 for t in now)

        wait_for(moved, 20, "both teams' robots to move on the canvas")
        # what the page draws is where the core says the robots are
        rows = {r["tag"]: r for r in m.referee().robots()}
        drawn = page.evaluate("() => [...robo.model.robots.values()].map(r => [r.tag, r.x, r.y, r.team])")
        assert {d[0] for d in drawn} == set(rows)
        for tag, x, y, team in drawn:
            assert rows[tag]["team"] == team
            assert abs(rows[tag]["x"] - x) + abs(rows[tag]["y"] - y) < 3.0  # at most ~1 s of driving apart
        page.screenshot(path=str(tmp_path / "live.png"))
        assert (tmp_path / "live.png").stat().st_size > 10_000
        assert not page.errors
    finally:
        page.close()


def test_click_robot_shows_public_monitor_and_follows(browser, live) -> None:
    m, url = live
    page = open_page(browser, url)
    try:
        page.wait_for_function("() => robo.model.robots.size >= 4", timeout=15000)
        tag, sx, sy = page.evaluate("""() => {
          const r = [...robo.model.robots.values()].find(r => r.team === 'red');
          const [x, y] = r.pose(performance.now() / 1000);
          const [sx, sy] = robo.renderer.camera.toScreen(x + 0.5, y + 0.5);
          const box = document.getElementById('map').getBoundingClientRect();
          return [r.tag, box.left + sx, box.top + sy];
        }""")
        page.mouse.click(sx, sy)
        page.wait_for_function("() => !document.getElementById('info').classList.contains('hidden')")
        assert page.inner_text("#info-title") == f"Robot {tag}"
        page.wait_for_function("() => document.getElementById('info-fields').innerText.includes('public view')",
                               timeout=5000)
        text = page.inner_text("#info-fields")
        keys = text.split("\n")[0::2]
        assert "red" in text and "sensors" not in keys and "last report" not in keys  # no private monitor data
        assert "goTo" in text  # a task's name is public (its arguments are not)
        page.click("#btn-follow")
        page.wait_for_function(f"() => robo.S.follow === {tag}")
    finally:
        page.close()


def test_private_view_shows_nothing_of_the_other_team(browser, live, tmp_path: Path) -> None:
    m, url = live
    frames: list[str] = []
    page = open_page(browser, url, frames=frames)
    try:
        page.wait_for_function("() => robo.model.robots.size >= 4", timeout=15000)
        assert pixels(page, "blue")[0] > 20  # the public view shows blue's robots (so the check below can fail)
        blue_tags = {r["tag"] for r in m.client("blue").robots()}
        page.click("#btn-token")
        page.fill("#token-input", m.token("red"))
        page.click("#btn-token-ok")
        page.wait_for_function("() => robo.S.view.kind === 'private'", timeout=15000)
        start = len(frames)
        assert page.inner_text("#view-label").startswith("red")
        blue_before = {r["tag"]: (r["x"], r["y"]) for r in m.client("blue").robots()}
        drive_far(m.client("blue"))
        # blue keeps driving while red's page watches
        wait_for(lambda: any(abs(r["x"] - blue_before[r["tag"]][0]) + abs(r["y"] - blue_before[r["tag"]][1]) > 0.5
                             for r in m.client("blue").robots()), 20, "blue's robots to move")
        time.sleep(0.5)
        teams = page.evaluate("() => [...new Set([...robo.model.robots.values()].map(r => r.team))]")
        assert teams == ["red"]
        assert pixels(page, "blue")[0] == 0
        assert pixels(page, "red")[0] > 20
        leaked = []
        for f in frames[start:]:
            msg = json.loads(f)
            if msg.get("type") == "state":
                leaked += [r for r in msg["state"]["robots"] if r[1] != "red" or r[0] in blue_tags]
            for topic, data, *_ in msg.get("e") or []:
                if set(data.get("tags") or []) & blue_tags or data.get("tag") in blue_tags or data.get("team") == "blue":
                    leaked.append((topic, data))
        assert not leaked
        # a private view's monitor data comes from the core, in red's session
        tag = page.evaluate("() => [...robo.model.robots.keys()][0]")
        body = page.evaluate("(tag) => new Promise((ok, no) => { const id = 9999; "
                             "robo.S.pending.set(id, {resolve: ok, reject: e => ok({refused: e.message})}); "
                             "robo.S.ws.send(JSON.stringify({op: 'monitor', req: id, tag})); })", tag)
        assert "sensors" in body
        blue = sorted(blue_tags)[0]
        body = page.evaluate("(tag) => new Promise((ok) => { const id = 9998; "
                             "robo.S.pending.set(id, {resolve: ok, reject: e => ok({refused: e.message})}); "
                             "robo.S.ws.send(JSON.stringify({op: 'monitor', req: id, tag})); })", blue)
        assert "not one of team red's robots" in body.get("refused", "")  # the core's refusal, word for word
        page.screenshot(path=str(tmp_path / "private.png"))
        # a wrong token is refused by the core, and the page says so
        page.click("#btn-token")
        page.fill("#token-input", "not-a-token")
        page.click("#btn-token-ok")
        page.wait_for_function("() => document.getElementById('token-error').textContent.length > 0", timeout=15000)
        assert "token" in page.inner_text("#token-error").lower()
        assert not page.errors
    finally:
        page.close()


def test_the_video_examinearea_films_plays_in_its_teams_page(browser, live, tmp_path: Path) -> None:
    """Issue 33: examineArea films its turn; the public page shows where, the team's page plays it."""
    m, url = live
    red = m.client("red")
    tag = red.robots()[0]["tag"]
    red.give(tag, "examineArea", [3, 12])
    wait_for(lambda: m.logged_events("video"), 90, "the video")
    red.give(tag, "goTo", [6, 9])  # out of the way: a click there would open the robot
    wait_for(lambda: abs(red.monitor(tag)["y"] - 12) > 2, 30, "the robot to drive off")
    page = open_page(browser, url)
    try:
        page.wait_for_function("() => [...robo.model.things.keys()].some(k => k.startsWith('video:'))", timeout=15000)
        key = page.evaluate("() => [...robo.model.things.keys()].find(k => k.startsWith('video:'))")
        click_thing(page, key)
        page.wait_for_function("() => document.querySelector('#info-pictures .error')", timeout=10000)
        assert "videos belong to the team that filmed them" in page.inner_text("#info-pictures")
        page.click("#btn-token")
        page.fill("#token-input", m.token("red"))
        page.click("#btn-token-ok")
        page.wait_for_function("() => robo.S.view.kind === 'private'", timeout=15000)
        page.wait_for_function(f"() => robo.model.things.has({json.dumps(key)})", timeout=15000)
        click_thing(page, key)
        page.wait_for_function("() => { const v = document.querySelector('#info-pictures video'); "
                               "return v && v.readyState >= 2 && v.videoWidth === 96 && v.videoHeight === 64; }",
                               timeout=15000)
        page.wait_for_function("() => document.querySelector('#info-pictures video').currentTime > 0.2",
                               timeout=15000)  # it plays
        page.screenshot(path=str(tmp_path / "video.png"))
        assert not page.errors
    finally:
        page.close()


def test_a_view_the_server_offers(live) -> None:
    """``--view-token-file``: the server offers red's private view by name, with its key; other
    names, and red's without the key, are refused."""
    import asyncio

    import websockets

    m, url = live

    from robo_comp.web.server import view_key

    key = view_key(m.token("red"))

    async def talk() -> list[dict[str, Any]]:
        out = []
        async with websockets.connect(url.replace("http", "ws") + "ws") as ws:
            out.append(json.loads(await ws.recv()))
            for msg in ({"view": "blue", "key": key}, {"view": "red"}, {"view": "red", "key": "guess"},
                        {"view": "red", "key": key}):
                await ws.send(json.dumps({"op": "join", **msg}))
                out.append(json.loads(await ws.recv()))
        return out

    hello, blue, nokey, badkey, red = in_thread(lambda: asyncio.run(talk()))
    assert hello["views"] == ["red"]
    assert blue["type"] == "error" and "no view 'blue'" in blue["message"]
    # a view offered with --view-token-file opens only with its key (or the team's token)
    for refused in (nokey, badkey):
        assert refused["type"] == "error" and "opens with its link" in refused["message"]
    assert red["type"] == "state" and red["view"]["name"] == "red" and red["view"]["kind"] == "private"
    assert red["state"]["robots"] and {r[1] for r in red["state"]["robots"]} == {"red"}


def test_a_wrong_gateway_token_is_refused_at_start(live) -> None:
    m, _ = live
    r = subprocess.run([sys.executable, "-m", "robo_comp.cli", "web", "--core", str(m.state), "--token", "nope",
                        "--port", "0"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.startswith("robo-comp web: ") and "token" in r.stderr


def test_phone_layout(browser, live, tmp_path: Path) -> None:
    m, url = live
    page = open_page(browser, url, width=390, height=844)
    try:
        page.wait_for_function("() => robo.model.robots.size >= 4", timeout=15000)
        box = page.evaluate("() => { const r = document.getElementById('map').getBoundingClientRect(); "
                            "return [r.width, r.height, document.documentElement.scrollWidth]; }")
        assert box[0] == 390 and box[1] > 500 and box[2] <= 390  # the map fills the phone, no sideways scroll
        a = page.evaluate("() => [robo.renderer.camera.scale, robo.model.arena.width]")
        assert a[0] * a[1] <= 390  # fitted to the narrow window
        page.screenshot(path=str(tmp_path / "phone.png"))
    finally:
        page.close()


# ---------------------------------------------------------------------- replay
def write_log(path: Path, seconds: int = 95) -> list[tuple[float, float]]:
    """A recorded match: the demo room, robot 101 (red) driving one cell every 10 s along y=8,
    robot 201 (blue) standing; returns robot 101's (time, x)."""
    sc = load_scenario(bundled_scenario_path("demo_room"))
    path.parent.mkdir(parents=True, exist_ok=True)
    log = EventLog(path)
    t0 = 1_700_000_000.0
    log.append("core.started", None, {"router": "tcp://x", "teams": ["red", "blue"],
                                      "arena": arena_payload(sc, ["red", "blue"])}, t=t0)
    log.append("robot.registered", "red", {"tag": 101, "team": "red", "robot_id": "r1", "x": 2, "y": 8, "heading": 0}, t=t0 + 0.5)
    log.append("robot.registered", "blue", {"tag": 201, "team": "blue", "robot_id": "b1", "x": 20, "y": 2, "heading": 90}, t=t0 + 0.5)
    track = []
    for s in range(1, seconds + 1):
        x = 2 + s * 0.1
        track.append((float(s), x))
        log.append("robot.positions", None, {"tags": [101, 201], "x": [x, 20.0], "y": [8.0, 2.0],
                                             "heading": [0.0, 90.0], "moving": [True, False]}, t=t0 + s)
        if s == 50:
            log.append("robot.lost", "red", {"tag": 101, "x": x, "y": 8.0, "message": "silent"}, t=t0 + s + 0.2)
        if s == 60:
            log.append("robot.returned", "red", {"tag": 101, "x": x, "y": 8.0}, t=t0 + s + 0.2)
        if s == 30:  # red's robot photographs a victim and reports it with the picture as evidence
            log.append("picture", "red", {"id": 1, "tag": 101, "team": "red", "x": 4, "y": 8, "heading": 0,
                                          "t": t0 + s, "victims": ["v1"], "sha256": "00"}, t=t0 + s + 0.3)
            log.append("find.reported", "red", {"id": 1, "team": "red", "tag": 101, "x": 5, "y": 8, "kind": "victim",
                                                "state": "confirmed", "evidence": [1],
                                                "message": "victim v1 confirmed"}, t=t0 + s + 0.4)
    log.close()
    return track


def expected_x(track: list[tuple[float, float]], at: float) -> float:
    xs = [x for t, x in track if t <= at]
    return xs[-1] if xs else 2.0


def test_replay_seek_lands_on_the_right_state(browser, tmp_path: Path) -> None:
    log = tmp_path / "match" / "events.log"
    track = write_log(log)
    web, url = start_web("--replay", str(log))
    try:
        page = open_page(browser, url + "#t=37")
        try:
            page.wait_for_function("() => robo.model.robots.has(101)", timeout=15000)
            r = page.evaluate("() => [robo.S.replay.t, robo.model.robots.get(101).x, robo.model.robots.get(101).status]")
            assert r[0] == pytest.approx(37, abs=0.01) and r[1] == pytest.approx(expected_x(track, 37)) and r[2] == "connected"
            for at, status in ((55.5, "lost"), (12.25, "connected"), (94.0, "connected"), (0.6, "connected")):
                page.evaluate("(t) => { const tl = document.getElementById('timeline'); tl.value = String(t); "
                              "tl.dispatchEvent(new Event('change')); }", at)
                page.wait_for_function(f"() => Math.abs(robo.S.replay.t - {at}) < 0.01", timeout=10000)
                page.wait_for_function("() => robo.model.robots.size > 0", timeout=10000)
                got = page.evaluate("() => [robo.model.robots.get(101).x, robo.model.robots.get(101).status]")
                # the reference: the display wall's model fed with the log's public events up to `at`
                ref = MatchView()
                from robo_comp.protocol.logfile import read_log
                recs = list(read_log(log))
                for rec in recs:
                    if rec.t - recs[0].t <= at:
                        d = public_event(rec.topic, rec.data)
                        if d is not None:
                            ref.apply(rec.topic, d)
                assert got[0] == pytest.approx(ref.robots[101].x) == pytest.approx(expected_x(track, at))
                assert got[1] == ref.robots[101].status == status
            # the robot is drawn where the state says: its pixels sit at the camera's point for it
            n, cx, cy = pixels(page, "red")
            sx, sy = page.evaluate("() => { const r = robo.model.robots.get(101); "
                                   "return robo.renderer.camera.toScreen(r.x + 0.5, r.y + 0.5); }")
            dpr = page.evaluate("() => robo.renderer.dpr")
            assert n > 10 and abs(cx / dpr - sx) < 4 and abs(cy / dpr - sy) < 4
            page.screenshot(path=str(tmp_path / "replay.png"))
            # a paused replay is idle: the page stops drawing (no battery spent on equal frames)
            idle = page.evaluate("""() => new Promise(ok => {
              const d0 = robo.S.stats.drawn, f0 = robo.S.stats.frames;
              const wait = () => robo.S.stats.frames - f0 >= 20 ? ok(robo.S.stats.drawn - d0) : requestAnimationFrame(wait);
              requestAnimationFrame(wait);
            })""")
            assert idle == 0
            assert not page.errors
        finally:
            page.close()
        # a link opens at a time and speed, playing
        page = open_page(browser, url + "#t=20&speed=8&play=1")
        try:
            page.wait_for_function("() => robo.S.replay.playing && robo.S.replay.t > 21", timeout=15000)
            assert page.evaluate("() => robo.S.replay.speed") == 8
            assert page.input_value("#speed") == "8"
            page.click("#btn-play")
            page.wait_for_function("() => !robo.S.replay.playing", timeout=5000)
        finally:
            page.close()
    finally:
        stop(web)


def click_thing(page, key: str) -> None:
    sx, sy = page.evaluate("""(key) => {
      const th = robo.model.things.get(key);
      const [sx, sy] = robo.renderer.camera.toScreen(th.x + 0.5, th.y + 0.5);
      const box = document.getElementById('map').getBoundingClientRect();
      return [box.left + sx, box.top + sy];
    }""", key)
    page.mouse.click(sx, sy)
    page.wait_for_function(f"() => robo.renderer.selectedThing === {json.dumps(key)}", timeout=5000)


def test_replay_find_evidence_needs_the_team_token(browser, tmp_path: Path) -> None:
    from robo_comp.web.state import png_rgb
    import numpy as np

    log = tmp_path / "match" / "events.log"
    write_log(log)
    (log.parent / "pictures").mkdir()
    img = np.zeros((24, 32, 3), np.uint8)
    img[..., 0] = np.arange(32, dtype=np.uint8)[None, :] * 8
    (log.parent / "pictures" / "1.png").write_bytes(png_rgb(img))
    (log.parent / "teams").mkdir()
    (log.parent / "teams" / "red.token").write_text("red-secret\n")
    web, url = start_web("--replay", str(log))
    try:
        page = open_page(browser, url + "#t=40")
        try:
            page.wait_for_function("() => robo.model.things.has('find:1')", timeout=15000)
            click_thing(page, "find:1")
            page.wait_for_function("() => document.getElementById('info-fields').innerText.includes('private')")
            assert page.inner_text("#info-title") == "Find 1"
            assert "confirmed" in page.inner_text("#info-fields")
            assert page.locator("#info-pictures img").count() == 0
            page.click("#btn-token")
            page.fill("#token-input", "red-secret")
            page.click("#btn-token-ok")
            page.wait_for_function("() => robo.S.view.kind === 'private'", timeout=15000)
            assert page.evaluate("() => robo.S.replay.t") == pytest.approx(40, abs=0.5)  # the view changed, not the time
            click_thing(page, "find:1")
            page.wait_for_function("() => { const i = document.querySelector('#info-pictures img'); "
                                   "return i && i.complete && i.naturalWidth === 32; }", timeout=10000)
            assert "victim v1 confirmed" in page.inner_text("#info-fields")
            page.screenshot(path=str(tmp_path / "evidence.png"))
            assert not page.errors
        finally:
            page.close()
    finally:
        stop(web)


# ---------------------------------------------------------------------- without a browser
def test_cli_refuses_bad_options(tmp_path: Path) -> None:
    def run(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "robo_comp.cli", "web", *args], capture_output=True,
                              text=True, timeout=60)

    r = run()
    assert r.returncode == 2 and "--core" in r.stderr and "--replay" in r.stderr
    r = run("--replay", str(tmp_path / "nope.log"))
    assert r.returncode == 2 and "no such event log" in r.stderr
    r = run("--core", "tcp://127.0.0.1:1")
    assert r.returncode == 2 and "--token-file" in r.stderr
    r = run("--replay", str(tmp_path / "x.log"), "--core", str(tmp_path))
    assert r.returncode == 2 and "not both" in r.stderr


def test_websocket_protocol_errors(tmp_path: Path) -> None:
    """Bad messages from a page get clear errors and the connection goes on (no browser needed)."""
    import asyncio

    import websockets

    log = tmp_path / "m" / "events.log"
    write_log(log, seconds=30)
    (log.parent / "teams").mkdir()
    (log.parent / "teams" / "red.token").write_text("red-secret\n")
    web, url = start_web("--replay", str(log))

    async def talk() -> list[dict[str, Any]]:
        out = []
        async with websockets.connect(url.replace("http", "ws") + "ws") as ws:
            out.append(json.loads(await ws.recv()))  # hello
            for msg in ("not json", json.dumps({"op": "seek", "req": 1, "t": 3})):
                await ws.send(msg)
                out.append(json.loads(await ws.recv()))
            await ws.send(json.dumps({"op": "join", "token": "wrong"}))
            out.append(json.loads(await ws.recv()))
            await ws.send(json.dumps({"op": "join", "t": 12}))
            story = json.loads(await ws.recv())  # a view's story comes first, once
            assert story["type"] == "story" and story["view"] == "public", story
            out.append(json.loads(await ws.recv()))
            await ws.send(json.dumps({"op": "speed", "req": 2, "value": 100}))
            while True:
                m = json.loads(await ws.recv())
                if m.get("type") == "reply":
                    out.append(m)
                    break
            # a token of the recorded match (beside the log) opens that team's view of the replay
            await ws.send(json.dumps({"op": "join", "token": "red-secret", "t": 20}))
            while True:
                m = json.loads(await ws.recv())
                if m.get("type") == "state":
                    out.append(m)
                    break
        return out

    try:
        hello, bad_json, early, bad_token, state, speed, red = in_thread(lambda: asyncio.run(talk()))
    finally:
        stop(web)
    assert hello["mode"] == "replay" and hello["duration"] == pytest.approx(30.4, abs=0.01)
    assert "JSON" in bad_json["message"]
    assert not early["ok"] and "join" in early["error"]["message"]
    assert bad_token["type"] == "error" and "token" in bad_token["message"]
    assert state["type"] == "state" and state["t"] == pytest.approx(12)
    assert not speed["ok"] and "between 0.25 and 16" in speed["error"]["message"]
    assert {r[0] for r in state["state"]["robots"]} == {101, 201}  # the public view: both teams
    assert red["view"] == {"name": "red", "kind": "private"}
    robots = red["state"]["robots"] + [[t] for _, d, _ in red["after"] for t in d.get("tags", [d.get("tag")])]
    assert {r[0] for r in robots} == {101}  # red's view of the replay: nothing of blue


def test_gateway_follows_a_core_restart(tmp_path: Path) -> None:
    """The core stops and starts again (recovering from its state folder): the gateway
    reconnects on its own, pages get a fresh state, and new robots show (no browser needed)."""
    import asyncio

    import websockets

    from robo_comp.launch import start_core

    state = tmp_path / "state"
    m = start_match(state, teams=["red", "blue"])
    web = None
    try:
        web, url = start_web("--core", str(state))

        async def talk() -> list[str]:
            seen: list[str] = []
            async with websockets.connect(url.replace("http", "ws") + "ws") as ws:
                await ws.recv()  # hello
                await ws.send(json.dumps({"op": "join"}))
                first = json.loads(await ws.recv())
                seen.append(first["type"])
                m.proc.terminate()
                m.proc.wait(10)
                m.proc = start_core(state, "--heartbeat", "0.2", "--scenario", str(m.scenario), "--teams", "red,blue",
                                    "--practice")
                deadline = time.monotonic() + 40
                restarted = False
                while time.monotonic() < deadline:
                    try:
                        msg = json.loads(await asyncio.wait_for(ws.recv(), 1.0))
                    except asyncio.TimeoutError:
                        continue
                    if msg["type"] == "state" and not restarted:
                        restarted = True
                        seen.append("state after restart")
                        m.robots("red", 1)
                    elif restarted and msg["type"] == "ev" and any(t == "robot.registered" for t, *_ in msg["e"]):
                        seen.append("robot registered")
                        break
            return seen

        seen = in_thread(lambda: asyncio.run(talk()))
        assert seen == ["state", "state after restart", "robot registered"]
    finally:
        if web is not None:
            stop(web)
        m.close()


def test_public_view_filters_and_a_slow_browser_is_resynchronised() -> None:
    """The public view's rules on logged data, and a browser that cannot keep up gets a fresh
    state instead of an ever longer queue (pure asyncio, no processes)."""
    import asyncio

    from robo_comp.web.hub import Hub, Subscriber
    from robo_comp.web.state import public_snapshot
    from robo_comp.web.wire import AsgiWire

    assert public_event("radio", {"from": 101, "data": "secret"}) is None
    assert public_event("task.done", {"tag": 101, "ok": True, "result": {"map": 1}, "status": "x"}) == {"tag": 101, "ok": True}
    assert public_event("picture", {"id": 3, "tag": 101, "team": "red", "x": 1, "y": 2, "heading": 0, "t": 5.0,
                                    "victims": ["v1"], "sha256": "ab"}) == {"id": 3, "tag": 101, "team": "red", "x": 1,
                                                                             "y": 2, "heading": 0, "t": 5.0}
    snap = public_snapshot({"arena": {}, "robots": [{"tag": 101, "team": "red", "robot_id": "r1", "x": 1, "y": 2,
                                                     "heading": 0, "status": "connected", "moving": True, "queue": 2,
                                                     "task": {"name": "goTo", "task_id": 4, "args": [3, 4]}}],
                            "finds": [{"id": 1, "team": "red", "tag": 101, "x": 3, "y": 3, "kind": "victim",
                                       "state": "confirmed", "evidence": [7], "verdict": {"valid": True}}]})
    assert snap["robots"] == [{"tag": 101, "team": "red", "status": "connected", "x": 1, "y": 2, "heading": 0,
                               "moving": True, "task": {"name": "goTo", "task_id": 4}}]
    assert snap["finds"] == [{"id": 1, "team": "red", "tag": 101, "x": 3, "y": 3, "kind": "victim", "state": "confirmed"}]

    async def scenario() -> list[str]:
        sent: list[str] = []
        gate = asyncio.Event()

        async def slow_send(text: str) -> None:
            await gate.wait()  # the browser reads nothing until the gate opens
            sent.append(text)

        hub = Hub("public")
        sub = Subscriber(AsgiWire(slow_send), limit=5)  # a server without the wire extension
        hub.attach(sub)
        for i in range(50):
            hub.publish([("broadcast", {"message": f"m{i}"})])
        assert sub.behind and not sub.held  # too much waited: nothing more is held for this browser
        gate.set()
        for _ in range(20):
            await asyncio.sleep(0.01)
        sub.close()
        return sent

    sent = in_thread(lambda: asyncio.run(scenario()))
    kinds = [json.loads(t)["type"] for t in sent]
    assert kinds[-1] == "state" and len(sent) <= 3  # after the first, at most one queued message, then a state
    assert json.loads(sent[-1])["state"]["messages"][-1]["text"] == "m49"  # the state holds the newest


def test_gateway_on_a_curve_core(tmp_path: Path) -> None:
    """With CurveZMQ the gateway's session and its SUB socket use the referee's keys (found in the
    state folder), and a team's private view opens with that team's key (no browser needed)."""
    import asyncio

    import websockets

    from robo_comp.launch import start_core

    state = tmp_path / "state"
    subprocess.run([sys.executable, "-m", "robo_comp.cli", "keys", "--state", str(state), "--teams", "red,blue"],
                   check=True, capture_output=True, timeout=60)
    core = start_core(state, "--heartbeat", "0.2", "--teams", "red,blue", "--curve")
    m = Match(state, None, core)
    web = None
    try:
        m.robots("red", 1, "--curve-cert", str(state / "keys" / "organiser.key_secret"),
                 "--core-key", str(state / "keys" / "core.key"))
        web, url = start_web("--core", str(state))

        async def talk() -> tuple[dict[str, Any], dict[str, Any]]:
            async with websockets.connect(url.replace("http", "ws") + "ws") as ws:
                await ws.recv()
                await ws.send(json.dumps({"op": "join"}))
                deadline = time.monotonic() + 30
                public = None
                while time.monotonic() < deadline:
                    msg = json.loads(await asyncio.wait_for(ws.recv(), 30))
                    if msg["type"] == "ev" and any(t == "robot.positions" for t, *_ in msg["e"]):
                        public = msg
                        break
                    if msg["type"] == "state" and msg["state"]["robots"]:
                        public = msg
                        break
                await ws.send(json.dumps({"op": "join", "token": m.token("blue")}))
                while True:
                    msg = json.loads(await asyncio.wait_for(ws.recv(), 30))
                    if msg["type"] in ("state", "error"):
                        return public, msg

        public, blue = in_thread(lambda: asyncio.run(talk()))
        assert public is not None  # red's robot reached the page through the CURVE PUB feed
        assert blue["type"] == "state" and blue["view"]["name"] == "blue" and blue["state"]["robots"] == []
    finally:
        if web is not None:
            stop(web)
        m.close()
