"""The referee console driven by a pilot against a real core, with a team console watching."""
from __future__ import annotations

import asyncio

from conftest import CoreHandle

from robo_comp.link import LinkState
from robo_comp.tui.referee_app import RefereeApp
from robo_comp.tui.screens.confirm import ConfirmScreen
from robo_comp.tui.screens.forms import FormScreen
from robo_comp.tui.team_app import TeamApp
from robo_comp.tui.testing import notifications, screen_text, until


def test_referee_pauses_the_match_and_the_team_console_shows_it(core: CoreHandle) -> None:
    async def scenario() -> None:
        ref = RefereeApp(str(core.state), core.token("referee"))
        team = TeamApp(str(core.state), core.token("red"))
        async with ref.run_test(size=(120, 40)) as rp, team.run_test(size=(80, 24)) as tp:
            await until(rp, lambda: ref.model.match.phase == "running", 20, "the referee to see the match")
            await until(tp, lambda: team.model.match.phase == "running", 20, "the team to see the match")
            await rp.press("p")
            await until(rp, lambda: isinstance(ref.screen, ConfirmScreen), 15, "the confirmation")
            await rp.press("y")
            await until(tp, lambda: team.model.match.phase == "paused", 20, "the team console to see the pause")
            await tp.pause(0.6)
            assert "PAUSED" in screen_text(team)
            assert any("Match PAUSED" in n for n in notifications(team))
            assert ref.model.match.phase == "paused"
            # a cancelled confirmation changes nothing
            await rp.press("p")
            await until(rp, lambda: isinstance(ref.screen, ConfirmScreen), 15, "the confirmation")
            await rp.press("n")
            await rp.pause(0.3)
            assert ref.model.match.phase == "paused"
            # resume
            await rp.press("p", "y")
            await until(tp, lambda: team.model.match.phase == "running", 20, "the team console to see the resume")

    asyncio.run(scenario())


def test_penalty_and_broadcast_reach_the_team(core: CoreHandle) -> None:
    async def scenario() -> None:
        ref = RefereeApp(str(core.state), core.token("referee"))
        team = TeamApp(str(core.state), core.token("blue"))
        async with ref.run_test(size=(160, 48)) as rp, team.run_test(size=(100, 30)) as tp:
            await until(rp, lambda: ref.link.state is LinkState.CONNECTED and ref.model.teams, 20, "connected")
            await until(tp, lambda: team.link.state is LinkState.CONNECTED, 20, "connected")
            await rp.press("n")
            form = await until(rp, lambda: isinstance(ref.screen, FormScreen) and ref.screen, 15, "the penalty form")
            form.query_one("#f-team").value = "blue"
            form.query_one("#f-reason").value = "left the arena without leave"
            form.query_one("#f-reason").focus()
            await rp.press("enter")
            await until(tp, lambda: any("Penalty for blue" in n for n in notifications(team)), 20, "the penalty toast")
            await until(tp, lambda: (team.model.my_score() or {}).get("score") == -10, 20, "blue's score")
            await tp.pause(0.6)
            assert "score -10" in screen_text(team)
            # broadcast
            await rp.press("b")
            form = await until(rp, lambda: isinstance(ref.screen, FormScreen) and ref.screen, 15, "the form")
            form.query_one("#f-message").value = "two minutes left"
            form.query_one("#f-message").focus()
            await rp.press("enter")
            await until(tp, lambda: any("two minutes left" in n for n in notifications(team)), 20, "the broadcast")
            # the referee's log filter
            ref.screen.query_one("#filter").value = "penalty"
            await rp.pause(0.2)
            log = ref.screen.query_one("#log")
            assert log.lines and all("PENALTY" in line.text for line in log.lines)

    asyncio.run(scenario())


def test_referee_refusal_is_a_notification(core: CoreHandle) -> None:
    async def scenario() -> None:
        ref = RefereeApp(str(core.state), core.token("referee"))
        async with ref.run_test() as rp:
            await until(rp, lambda: ref.link.state is LinkState.CONNECTED and ref.model.match.phase != "?", 10,
                        "connected")
            await rp.press("g", "y")  # start: the practice core is already running
            await until(rp, lambda: any("Cannot start" in n for n in notifications(ref)), 15, "the refusal")

    asyncio.run(scenario())
