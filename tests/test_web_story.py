"""The match's story in a real browser (Debian's chromium via Playwright) on a real match: a
core with phases, robot hosts, a find that is confirmed, a false report, a referee penalty and
broadcast, then the end. The page must show the legend, the ticker, the timeline's markers, one
match clock, the score-over-time chart, the winner banner and the revealed victims, live and in
the replay of the same match's log; finds look the same in the public and the team view.

Screenshots go to the test's temporary folder (and to ``$ROBO_COMP_SHOTS`` when set) so a
person can look at them.
"""
from __future__ import annotations

import os
import re
import shutil
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("starlette", reason="the web extra is not installed (pip install -e '.[web]')")

from conftest import wait_for, wait_robots
from robo_comp.testing import next_event_where, start_match
from robo_comp.web.server import view_key
from test_web import browser, open_page, start_web, stop  # noqa: F401  (the module's chromium fixture)


def shot(page: Any, tmp: Path, name: str) -> Path:
    """A screenshot in the test's folder (and in $ROBO_COMP_SHOTS, for looking at)."""
    path = tmp / name
    page.screenshot(path=str(path))
    keep = os.environ.get("ROBO_COMP_SHOTS")
    if keep:
        Path(keep).mkdir(parents=True, exist_ok=True)
        shutil.copy(path, Path(keep) / name)
    return path


@pytest.fixture(scope="module")
def played(tmp_path_factory: pytest.TempPathFactory, browser):  # noqa: F811
    """A real match on the demo room with phases, watched live by a gateway while it is played:
    red examines the area of victim v1 and reports it (confirmed), blue reports a victim where
    there is none (false report), the referee penalises blue and broadcasts, then finishes."""
    state = tmp_path_factory.mktemp("story") / "state"
    m = start_match(state, "demo_room", teams=["red", "blue"], practice=False)
    web = None
    try:
        m.robots("red", 2, speed=8)
        m.robots("blue", 2, speed=8)
        red, blue, ref = m.client("red", timeout=30), m.client("blue", timeout=30), m.referee()
        wait_robots(red, 2)
        wait_robots(blue, 2)
        web, url = start_web("--core", str(state), "--view-token-file", str(m.token_file("red")))
        page = open_page(browser, url)  # the gateway follows the core before the match starts
        page.close()
        m.start()
        red.watch(True)
        r1 = red.robots()[0]["tag"]
        task = red.give(r1, "examineArea", [9, 6])["task_id"]
        done = next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == task,
                                timeout=90)["data"]
        assert done["ok"], done
        found = red.request("find", tag=r1, x=9, y=5, kind="adult", evidence=done["result"]["pictures"])
        assert found["state"] == "confirmed", found
        b1 = blue.robots()[0]["tag"]
        wrong = blue.request("find", tag=b1, x=2, y=2, kind="adult", evidence=[])
        assert wrong["state"] == "rejected", wrong
        ref.request("penalty", team="blue", points=3, reason="pushed a red robot")
        ref.request("broadcast", message="two minutes left")
        yield m, url, web
    finally:
        if web is not None:
            stop(web)
        m.close()


PAGE_TEXT = """() => ({
  ticker: [...document.querySelectorAll('#ticker li')].map(li => li.innerText.replace(/\\s+/g, ' ').trim()),
  legend: [...document.querySelectorAll('#legend li')].map(li => li.innerText.trim()),
  header: document.getElementById('elapsed').innerText,
  remaining: document.getElementById('remaining').innerText,
  phase: document.getElementById('phase').innerText,
  tnow: document.getElementById('t-now').innerText,
  tend: document.getElementById('t-end').innerText,
  banner: document.getElementById('banner').classList.contains('hidden') ? null
          : document.getElementById('banner').innerText.replace(/\\s+/g, ' ').trim(),
  markers: [...document.querySelectorAll('#markers button')].map(b => b.title),
})"""


def test_live_story_and_the_end(browser, played, tmp_path: Path) -> None:  # noqa: F811
    m, url, _ = played
    page = open_page(browser, url)
    try:
        page.wait_for_function("() => robo.model.robots.size >= 4", timeout=15000)
        wait_for(lambda: len(page.evaluate(PAGE_TEXT)["ticker"]) >= 4, 15, "the ticker to fill")
        got = page.evaluate(PAGE_TEXT)
        lines = " | ".join(got["ticker"])
        assert re.search(r"red robot \d+ reported an adult at \(9, 5\): confirmed.*\+\d+", lines), lines
        assert re.search(r"blue robot \d+ reported an adult at \(2, 2\): rejected\s*−\d+", lines), lines
        assert "referee: penalty for blue: pushed a red robot −3" in lines, lines
        assert "referee: two minutes left" in lines and "the match started" in lines, lines
        legend = " | ".join(got["legend"])
        for want in ("robot of red", "robot of blue", "lost robot", "find, confirmed", "find, rejected",
                     "wall", "victim missed"):
            assert want in legend, legend
        assert got["banner"] is None  # no winner while the match runs
        # one clock: the header counts the match clock
        assert re.fullmatch(r"\d+:\d\d", got["header"]) and "left" in got["remaining"], got
        # the score chart drew both teams' lines
        assert page.evaluate("() => robo.model.story.scores.length") >= 2
        shot(page, tmp_path, "story-live-running.png")
        # trails survive a view switch: the team's view keeps what the page drew of red's robots
        trail = page.evaluate("() => Math.max(...[...robo.model.robots.values()].filter(r => r.team === 'red')"
                              ".map(r => r.trail.length))")
        assert trail >= 6, trail
        page.click("#btn-token")
        page.fill("#token-input", m.token("red"))
        page.click("#btn-token-ok")
        page.wait_for_function("() => robo.S.view.kind === 'private'", timeout=15000)
        after = page.evaluate("() => Math.max(...[...robo.model.robots.values()].filter(r => r.team === 'red')"
                              ".map(r => r.trail.length))")
        assert after >= trail, (trail, after)
        assert page.evaluate("() => robo.model.story.items.length") >= 4  # the team's view tells the story too
        page.click("#btn-token")
        page.click("#btn-public")
        page.wait_for_function("() => robo.S.view.kind === 'public'", timeout=15000)

        m.referee().request("match", action="finish")
        page.wait_for_function("() => !document.getElementById('banner').classList.contains('hidden')",
                               timeout=10000)
        page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
        got = page.evaluate(PAGE_TEXT)
        assert got["banner"].startswith("red wins"), got["banner"]
        assert "1 of 3 victims found" in got["banner"], got["banner"]
        assert got["phase"].lower() == "finished" and got["remaining"] == "", got  # no "03:14 left" at the end
        assert "the match finished" in " | ".join(got["ticker"])
        victims = page.evaluate("() => robo.model.story.victims.map(v => [v.id, v.found_by])")
        assert sorted(victims) == [["v1", ["red"]], ["v2", []], ["v3", []]]
        # the revealed victim v2 is drawn: the missed colour where the map shows it
        col = page.evaluate("""() => { const v = robo.model.story.victims.find(v => v.id === 'v2');
            const [sx, sy] = robo.renderer.camera.toScreen(+v.x + 0.5, +v.y + 0.5);
            const r = Math.max(6, robo.renderer.camera.scale * 0.5), d = robo.renderer.dpr;
            const px = robo.renderer.ctx.getImageData(Math.round((sx + r) * d), Math.round(sy * d), 1, 1).data;
            return [px[0], px[1], px[2]]; }""")
        assert col[0] > 200 and col[1] < 120 and col[2] < 120, col
        shot(page, tmp_path, "story-live-finished.png")
        assert not page.errors, page.errors
    finally:
        page.close()


def test_a_find_looks_the_same_in_every_view(browser, played) -> None:  # noqa: F811
    """A page that joins after the finds (from the core's snapshot) draws each find in the state
    the public feed announced, in the public view and the team's view alike."""
    m, url, _ = played
    states = {}
    for view in ("public", "red"):
        page = open_page(browser, url + (f"#view=red&key={view_key(m.token('red'))}" if view == "red" else ""))
        try:
            page.wait_for_function("() => robo.S.view.kind === %r" % ("private" if view == "red" else "public"),
                                   timeout=15000)
            page.wait_for_function("() => [...robo.model.things.keys()].some(k => k.startsWith('find:'))",
                                   timeout=15000)
            states[view] = page.evaluate("""() => [...robo.model.things.values()].filter(t => t.kind === 'find'
                && t.team === 'red').map(t => [t.id, t.state, robo.model.findColour(t.state)])""")
        finally:
            page.close()
    assert states["public"] == states["red"] and states["red"][0][1] == "confirmed", states


def test_replay_opens_on_the_match_and_tells_it(browser, played, tmp_path: Path) -> None:  # noqa: F811
    m, _, _ = played
    if not any(e["data"].get("phase") == "finished" for e in m.logged_events("match.phase")):
        m.referee().request("match", action="finish")  # (the live test finished it already when it ran first)
    wait_for(lambda: any(e["data"].get("phase") == "finished" for e in m.logged_events("match.phase")), 20,
             "the match's end in the log")
    log = m.state / "events.log"
    web, url = start_web("--replay", str(log))
    try:
        page = open_page(browser, url)  # no time given: it opens where the match started, playing
        try:
            page.wait_for_function("() => robo.model.robots.size >= 4 && robo.S.replay.playing", timeout=15000)
            start = page.evaluate("() => robo.S.replay.t")
            assert start > 0.5, start  # not the empty arena of the log's first second
            page.wait_for_function("() => robo.model.story.items.length >= 5", timeout=10000)
            got = page.evaluate(PAGE_TEXT)
            assert len(got["markers"]) >= 5, got["markers"]
            if page.evaluate("() => robo.S.replay.playing"):
                page.click("#btn-play")  # pause (at the end it has stopped by itself)
            page.wait_for_function("() => !robo.S.replay.playing", timeout=5000)
            # a marker seeks: the ticker then ends with that event (or one logged in the same millisecond)
            at = page.evaluate("() => robo.model.story.items.find(i => i.kind === 'penalty').t")
            page.evaluate("() => [...document.querySelectorAll('#markers button')].find(b => b.title.includes('penalty')).click()")
            page.wait_for_function(f"() => Math.abs(robo.S.replay.t - {at}) < 0.01", timeout=10000)
            page.wait_for_function("() => [...document.querySelectorAll('#ticker li')].slice(0, 2)"
                                   ".some(li => li.innerText.includes('penalty for blue'))", timeout=10000)
            got = page.evaluate(PAGE_TEXT)
            assert got["banner"] is None and "the match finished" not in " | ".join(got["ticker"])
            assert got["tnow"] == got["header"], got  # one clock: the replay bar shows the header's
            duration = page.evaluate("() => robo.S.replay.duration")
            page.evaluate("(t) => { const tl = document.getElementById('timeline'); tl.value = String(t); "
                          "tl.dispatchEvent(new Event('change')); }", duration)
            page.wait_for_function("() => !document.getElementById('banner').classList.contains('hidden')",
                                   timeout=10000)
            page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
            got = page.evaluate(PAGE_TEXT)
            assert got["banner"].startswith("red wins") and "1 of 3 victims found" in got["banner"], got
            assert got["tnow"] == got["header"] == got["tend"], got
            # trails came with the seek's state (a seek keeps where the robots were)
            assert page.evaluate("() => [...robo.model.robots.values()].some(r => r.trail.length >= 4)")
            shot(page, tmp_path, "story-replay-end.png")
            assert not page.errors, page.errors
        finally:
            page.close()
    finally:
        stop(web)


def test_a_score_line_joins_the_latest_item_it_explains_within_the_fold_window() -> None:
    from robo_comp.view.story import FOLD_WITHIN, Story

    s = Story(limit=None)
    s.apply("penalty", {"team": "blue", "reason": "first"}, 0.0, None)
    s.apply("penalty", {"team": "blue", "reason": "second"}, 1.0, None)
    s.apply("robot.bump", {"team": "blue", "tag": 7}, 1.5, None)
    (it,) = s.apply("score.change", {"team": "blue", "kind": "penalty", "points": -3}, 2.0, None)
    assert (it.id, it.points) == (2, -3.0)  # the latest blue penalty, past the bump after it
    (red,) = s.apply("score.change", {"team": "red", "kind": "penalty", "points": -2}, 2.5, None)
    assert red.kind == "score"  # blue's penalty does not explain red's line
    (late,) = s.apply("score.change", {"team": "blue", "kind": "penalty", "points": -1}, 1.0 + FOLD_WITHIN + 0.1,
                      None)
    assert late.kind == "score" and late.points == -1.0 and "−1" in late.text  # too late to explain it
    assert [i.points for i in s.items if i.kind == "penalty"] == [0.0, -3.0]
