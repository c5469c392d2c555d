"""The same match everywhere (issue 26): a league match's log replays with the table's final
scores on the wall (`wall --replay`: its model as the replay source feeds it) and the web page
(`web --replay`, in a real browser). `robo-comp replay` (the core's own recovery) is checked in
tests/test_league.py (test_the_league_score_is_the_official_score)."""
from __future__ import annotations

from pathlib import Path

import pytest

from robo_comp.league import reference
from robo_comp.league.engine import play_match
from robo_comp.protocol.logfile import read_log

from test_web import browser, open_page, start_web, stop  # noqa: F401  (browser: the module's chromium)


@pytest.fixture(scope="module")
def played(tmp_path_factory) -> tuple[Path, dict]:
    d = tmp_path_factory.mktemp("league-replay") / "match"
    d.mkdir()
    spec = {"id": 1, "scenario": "demo_room", "seed": 5, "seconds": 60, "robots": 2,
            "entrants": [{"team": t, "version": t, "files": {"play.py": reference.source(t)}}
                         for t in ("frontier", "random_walker")], "log": str(d / "events.log")}
    result = play_match(spec)
    assert result["scores"]["frontier"] > 0  # something to show
    return d / "events.log", result


def changes_until(log: Path, at: float) -> dict[str, float]:
    """The score of each team from the log's score lines up to ``at`` seconds."""
    recs = list(read_log(log))
    out: dict[str, float] = {}
    for r in recs:
        if r.topic == "score.change" and r.t - recs[0].t <= at:
            out[r.data["team"]] = out.get(r.data["team"], 0.0) + r.data["points"]
    return out


def test_the_wall_replay_shows_the_tables_scores(played):
    from robo_comp.view.model import MatchView
    from robo_comp.wall.replay import ReplaySource

    log, result = played
    src = ReplaySource(log, speed=1.0, clock=lambda: 0.0)
    m = MatchView()
    src.attach(m)
    half = src.duration / 2
    src.seek(m, half)
    mid = {r["team"]: r["score"] for r in m.score}
    assert {t: s for t, s in mid.items() if s} == {t: s for t, s in changes_until(log, half).items() if s}
    src.seek(m, src.duration + 1)
    assert {r["team"]: r["score"] for r in m.score} == result["scores"]
    assert m.score[0]["team"] == "frontier" and m.score[0]["rank"] == 1
    assert m.score[0]["victims"] == len(result["victims"]["frontier"])


def test_the_web_replay_shows_the_tables_scores(played):
    """The page's recording (its last keyframe and its events) ends with the table's scores."""
    import json

    from robo_comp.web.replay import Recording

    log, result = played
    view = Recording(log).build("public")
    last = json.loads(view.key_json[-1])
    assert {r["team"]: r["score"] for r in last["score"]} == result["scores"]
    scores = [json.loads(f)[1] for f in view.frags if json.loads(f)[0] == "score"]
    assert scores and {r["team"]: r["score"] for r in scores[-1]["teams"]} == result["scores"]


def test_the_web_replay_in_a_browser_ends_on_the_tables_scores(played, browser):  # noqa: F811
    log, result = played
    web, url = start_web("--replay", str(log))
    try:
        page = open_page(browser, url + "#t=1000")
        try:
            page.wait_for_function("() => robo.model.score.length === 2", timeout=15000)
            got = page.evaluate("() => Object.fromEntries(robo.model.score.map(r => [r.team, r.score]))")
            assert got == result["scores"]
            cells = page.evaluate("() => [...document.querySelectorAll('#score-table tbody td.num')]"
                                  ".map(td => td.textContent)")
            assert f"{result['scores']['frontier']:g}" in cells
            assert not page.errors
        finally:
            page.close()
    finally:
        stop(web)


def test_the_replay_fold_is_the_scoreboards_table():
    """The fold reads a log's score lines with the core's own Scoreboard (the rows a live core
    publishes), lets the match's final word fix lines a log lacks, and stops at a log's own tables."""
    from robo_comp.view.score import ScoreFold

    fold = ScoreFold()
    fold.feed("core.started", {"teams": ["a", "b"]})
    fold.feed("score.change", {"team": "a", "points": 10.0, "kind": "victim", "victim": "v1", "reason": "", "t": 3.0})
    fold.feed("score.change", {"team": "b", "points": -1.0, "kind": "collision", "reason": "", "t": 4.0})
    rows = {r["team"]: r for r in fold.feed("disqualified", {"team": "b"})["teams"]}
    assert rows["a"] == {"team": "a", "score": 10.0, "victims": 1, "penalties": 0.0, "last_change": 3.0,
                         "disqualified": False, "rank": 1}
    assert rows["b"]["penalties"] == 1.0 and rows["b"]["disqualified"] and rows["b"]["rank"] == 2
    end = fold.feed("match.phase", {"phase": "finished", "scores": {"a": 25.0, "b": -1.0},
                                    "victims": {"a": ["v1", "v2"]}})
    assert [(r["team"], r["score"], r["victims"]) for r in end["teams"]] == [("a", 25.0, 2), ("b", -1.0, 0)]
    core = ScoreFold()
    assert core.feed("score", {"teams": []}) is None  # a core's log: its own tables are shown
    assert core.feed("score.change", {"team": "a", "points": 1.0}) is None
