"""The referee console's league leaderboard (``robo-comp referee --league``), piloted with run_test()."""
from __future__ import annotations

import asyncio

from robo_comp.league import season
from robo_comp.league.engine import play_match
from robo_comp.league.store import LeagueStore
from robo_comp.tui.referee_app import RefereeApp
from robo_comp.tui.screens.leaderboard import LeaderboardScreen
from robo_comp.tui.testing import CannedLink, notifications, until

FIXED = {"clock": lambda: 100.0, "wall_clock": lambda: 1002.5, "poll": False}


def test_l_shows_the_league_and_r_reads_it_again(tmp_path) -> None:
    with LeagueStore(tmp_path / "lg", create=True) as store:
        store.configure(scenarios=["demo_room"], robots=2, seconds=60)
        season.submit_reference(store, 4)
        ids = store.schedule("scrimmage", 1, [["frontier", "sitter"]])
        store.finished(ids[0], play_match(store.spec(ids[0])))
        season.rate_played(store)
        expected = [r["team"] for r in season.league_view(store)["standings"]]
        scores = store.match(ids[0]).result["scores"]
    assert scores["frontier"] > scores["sitter"] and expected[0] == "frontier"  # the winner leads

    async def scenario() -> None:
        app = RefereeApp(link=CannedLink("referee", None), league=tmp_path / "lg", **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(120, 40)) as pilot:
            await pilot.press("l")
            await until(pilot, lambda: isinstance(app.screen, LeaderboardScreen), 10, "the leaderboard")
            board = app.screen
            assert isinstance(board, LeaderboardScreen)
            assert board.teams() == expected
            assert "1 matches played" in str(board.query_one("#league-footer").render())
            with LeagueStore(tmp_path / "lg") as store:  # another match is played meanwhile
                ids = store.schedule("scrimmage", 2, [["sitter", "explorer"]])
                store.finished(ids[0], play_match(store.spec(ids[0])))
                season.rate_played(store)
            await pilot.press("r")
            await until(pilot, lambda: "2 matches played" in str(board.query_one("#league-footer").render()),
                        10, "the refreshed view")
            await until(pilot, lambda: any("read again" in n for n in notifications(app)), 10, "the toast")
            await pilot.press("escape")
            await until(pilot, lambda: not isinstance(app.screen, LeaderboardScreen), 10, "back to the match")

    asyncio.run(scenario())


def test_without_a_league_l_says_how_to_get_one() -> None:
    async def scenario() -> None:
        app = RefereeApp(link=CannedLink("referee", None), **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(120, 40)) as pilot:
            await pilot.press("l")
            await until(pilot, lambda: any("--league" in n for n in notifications(app)), 10, "the hint")
            assert not isinstance(app.screen, LeaderboardScreen)

    asyncio.run(scenario())
