"""The story on the wall (issue 29): a real match's log (played by the engine, as the league plays
it) replayed on real pygame surfaces shows the winner banner and every hidden victim at the finish,
the ticker shows only what happened up to where a replay seeks back, the legend is drawn and the
key l toggles it; the match clock reads as the web page's. Screenshots are saved into
``$ROBO_COMP_SHOTS`` when set, for looking at."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import numpy as np  # noqa: E402
import pygame  # noqa: E402
import pytest  # noqa: E402

from robo_comp.league import reference  # noqa: E402
from robo_comp.league.engine import play_match  # noqa: E402
from robo_comp.view import colours as C  # noqa: E402
from robo_comp.view.model import MatchView  # noqa: E402
from robo_comp.wall.app import WallApp  # noqa: E402
from robo_comp.wall.replay import ReplaySource  # noqa: E402
from robo_comp.wall.view import TileSpec  # noqa: E402

TILE = TileSpec(1, 1, 0, 0, 1280, 800)


@pytest.fixture(scope="module", autouse=True)
def _pygame():
    pygame.display.init()
    pygame.font.init()
    yield


@pytest.fixture(scope="module")
def played(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """60 simulated seconds of the reference teams on the demo room (the league's engine)."""
    log = tmp_path_factory.mktemp("wall-story") / "events.log"
    spec = {"id": 1, "scenario": "demo_room", "seed": 5, "seconds": 60, "robots": 2, "log": str(log),
            "entrants": [{"team": t, "version": t, "files": {"play.py": reference.source(t)}}
                         for t in ("frontier", "random_walker")]}
    result = play_match(spec)
    assert result["scores"]["frontier"] > result["scores"]["random_walker"]  # a winner to name
    return log, result


def replay_at(log: Path, at: float) -> tuple[WallApp, ReplaySource]:
    src = ReplaySource(log, clock=lambda: 0.0)
    m = MatchView()
    src.attach(m)
    src.seek(m, at)
    return WallApp(m, TILE, source=src, fps=0), src


def frame(app: WallApp, name: str) -> pygame.Surface:
    surf = pygame.Surface(TILE.size, 0, 32)
    app.render(surf, None)
    shots = os.environ.get("ROBO_COMP_SHOTS")
    if shots:
        Path(shots).mkdir(parents=True, exist_ok=True)
        pygame.image.save(surf, str(Path(shots) / f"wall-story-{name}.png"))
    return surf


def colour_in(surf: pygame.Surface, rect: tuple[int, int, int, int], rgb: tuple[int, int, int]) -> int:
    """How many pixels of ``rect`` are exactly ``rgb``."""
    px = pygame.surfarray.pixels3d(surf)[rect[0]:rect[0] + rect[2], rect[1]:rect[1] + rect[3]]
    return int((px == np.array(rgb)).all(axis=2).sum())


def test_a_finished_replay_shows_the_winner_and_every_victim(played, tmp_path: Path) -> None:
    log, result = played
    app, src = replay_at(log, 1e9)  # its end
    m = app.model
    assert m.match.phase == "finished", "the engine's log ends with the match's finish"
    surf = frame(app, "end")
    b = app.renderer.banner
    assert b is not None and b.title == "frontier wins" and b.winner == "frontier"
    found = {v for vs in result["victims"].values() for v in vs}
    victims = src.story.victims
    assert victims and {v["id"] for v in victims} >= found
    assert b.detail.startswith("frontier 45 · random_walker 20") and f"{len(found)} of {len(victims)} victims found" \
        in b.detail
    # the title is written in the winner's colour, in the banner's box over the map
    assert colour_in(surf, app.renderer.over["banner"], C.hex_rgb(m.colour("frontier"))) > 50
    geom = app.renderer.geometry()
    assert geom is not None
    for v in victims:  # every victim: its cross in green (found) or red (missed) at its cell
        want = C.VICTIM_FOUND if v["found_by"] else C.VICTIM_MISSED
        assert tuple(surf.get_at(geom.cell_centre(v["x"], v["y"])))[:3] == want, v
    # one match clock: the page's header text, no time left once finished
    from robo_comp.view.story import clock_line

    assert str(clock_line(m.match.phase, *m.match.now(None), replay=True)) == "finished   1:00"


def test_the_ticker_after_a_seek_back_shows_only_the_lines_up_to_then(played) -> None:
    log, _ = played
    app, src = replay_at(log, 1e9)
    frame(app, "end-for-seek")
    back = 30.0
    src.seek(app.model, back)  # the user seeks back ([, Home, or the page's timeline)
    sought = frame(app, "seek-back")
    # the same frame as a replay opened there: robots, trails, finds, scores, clock and ticker
    fresh_app, _ = replay_at(log, back)
    fresh = frame(fresh_app, "opened-there")
    diff = (pygame.surfarray.array3d(sought) != pygame.surfarray.array3d(fresh)).any(axis=2)
    assert not diff.any(), f"{int(diff.sum())} pixels differ from a replay opened at {back} s"
    assert app.model.match.phase == "running"
    lines = app.renderer.ticker
    told = [it for it in src.story.items if it.t <= back]
    assert max(it.t for it in src.story.items) > back
    assert lines and [it.id for it in lines] == [it.id for it in reversed(told)]
    assert any(it.kind == "find" for it in lines) and app.renderer.banner is None


def test_the_legend_is_drawn_and_the_key_l_toggles_it(played) -> None:
    log, _ = played
    app, _ = replay_at(log, 20.0)
    with_legend = frame(app, "legend")
    words = pygame.surfarray.array3d(with_legend)
    app.handle(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_l, unicode="l", mod=0), 0.0)
    without = frame(app, "no-legend")
    assert (pygame.surfarray.array3d(without) != words).any(), "the key l changed nothing"
    rect = app.renderer.over.get("legend") or (0, 0, 0, 0)
    assert rect == (0, 0, 0, 0)
    app.handle(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_l, unicode="l", mod=0), 0.0)
    again = frame(app, "legend-again")
    assert (pygame.surfarray.array3d(again) == words).all()
    rect = app.renderer.over["legend"]
    for colour in (C.FIND_COLOURS["confirmed"], C.VICTIM_FOUND, C.PICTURE, C.LOST_MARK):
        assert colour_in(with_legend, rect, colour) > 0, colour
    assert colour_in(without, rect, C.VICTIM_FOUND) == 0
    x, y, w, h = rect
    assert (pygame.surfarray.array3d(without)[x:x + w, y:y + h] != words[x:x + w, y:y + h]).any()
    app.handle(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_l, unicode="l", mod=0), 0.0)
    exe = shutil.which("robo-comp", path=str(Path(sys.executable).parent)) or "robo-comp"
    help_text = subprocess.run([exe, "wall", "--help"], capture_output=True, text=True, check=True).stdout
    assert "l legend on/off" in help_text


def test_the_banners_rule_and_the_match_clock_are_the_pages() -> None:
    from robo_comp.view.story import banner, clock_line

    rows = [{"team": "red", "score": 20, "victims": 2, "rank": 1},
            {"team": "blue", "score": 20, "victims": 2, "rank": 2}]
    assert banner("running", rows, []) is None
    assert banner("finished", rows, []).title == "A draw"
    rows[1]["victims"] = 1
    assert banner("finished", rows, []).title == "red wins"
    rows[0]["disqualified"] = True  # a disqualified team wins nothing
    b = banner("finished", rows, [{"id": "v1", "found_by": []}, {"id": "v2", "found_by": ["blue"]}])
    assert (b.title, b.detail) == ("blue wins", "blue 20 — 1 of 2 victims found (shown on the map)")
    assert str(clock_line("running", 24.4, 275.2, replay=False)) == "running   0:24   (4:35 left)"
    assert str(clock_line(None, 0.0, None, replay=True, recording_t=3725.0)) == "replay   1:02:05"
    assert str(clock_line(None, 0.0, None, replay=False)) == "live   0:00"


def test_the_score_fold_reads_the_victims_a_finish_reveals() -> None:
    """A log without score tables whose finish carries the revealed victims (a list, as the match
    emits it; the fold read only a team → ids table and stopped on the list)."""
    from robo_comp.view.score import ScoreFold

    fold = ScoreFold()
    fold.feed("core.started", {"teams": ["red", "blue"]})
    fold.feed("score.change", {"team": "red", "points": 10.0, "kind": "victim", "reason": "v1", "victim": "v1"})
    table = fold.feed("match.phase", {"phase": "finished", "scores": {"red": 10.0, "blue": 0.0},
                                      "victims": [{"id": "v1", "x": 1, "y": 1, "found_by": ["red"]},
                                                  {"id": "v2", "x": 2, "y": 2, "found_by": []}]})
    assert table is not None
    assert {r["team"]: (r["score"], r["victims"]) for r in table["teams"]} == {"red": (10.0, 1), "blue": (0.0, 0)}
