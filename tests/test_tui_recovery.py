"""The referee console and the core's own faults (issue 32): the outage rule of the match clock,
shown and changed from the console, and what a restarted core recovered from a damaged log,
shown prominently. A real core process, killed and restarted with one byte of its log changed,
with the console connected all along (``App.run_test()``)."""
from __future__ import annotations

import asyncio
from pathlib import Path

from conftest import CoreHandle
from test_faults import _flip, _kill9_between_writes

from robo_comp.launch import start_core
from robo_comp.protocol.logfile import read_log
from robo_comp.tui.referee_app import RefereeApp
from robo_comp.tui.screens.forms import FormScreen
from robo_comp.tui.screens.recovery import RecoveryScreen
from robo_comp.tui.testing import notifications, until, until_shown


def _damage_one_score_line(log: Path) -> int:
    """Change one byte inside the score line of the penalty "foul 05"; return that record's seq."""
    victim = next(r for r in read_log(log) if r.topic == "score.change" and r.data["reason"] == "foul 05")
    raw = log.read_bytes()
    at = raw.index(b"foul 05", raw.index(b"foul 05") + 1)  # the second mention: the score line's
    _flip(log, raw.rindex(b"\xa6points", 0, at) + 9, 0x04)  # its points: -1.0 would read -1.25
    return victim.seq


def test_the_referee_console_shows_what_a_restarted_core_lost_and_sets_the_outage_rule(tmp_path: Path) -> None:
    state = tmp_path / "state"
    proc = start_core(state, "--heartbeat", "0.2", "--teams", "red,blue")
    match = CoreHandle(state, None, proc)
    try:
        ref = match.referee()
        for i in range(10):
            ref.request("penalty", team=("red", "blue")[i % 2], points=-1, reason=f"foul {i:02d}")

        async def scenario() -> None:
            app = RefereeApp(str(state), match.token("referee"))
            async with app.run_test(size=(120, 40)) as pilot:
                await until(pilot, lambda: app.model.recovery_known and app.model.outage, 30, "the core's report")
                await until_shown(pilot, app, "log: started on an empty folder · outage: clock pauses (o)")
                # kill -9, one byte of a score line changed, a restart: the console reconnects by itself
                await asyncio.to_thread(_kill9_between_writes, match.proc)
                seq = _damage_one_score_line(state / "events.log")
                match.proc = await asyncio.to_thread(start_core, state)
                await until(pilot, lambda: (app.model.recovered or {}).get("lost"), 60,
                            "the console to hear what the restarted core lost")
                await until_shown(pilot, app, f"⚠ LOG DAMAGED, 1 event lost: {seq} score.change (r)")
                assert app.screen.query_one("#core-line").has_class("-lost")
                assert any(f"The core's event log was damaged: 1 event lost: {seq} score.change" in n
                           for n in notifications(app)), notifications(app)
                # the report names the lost event, its topic and the damage; the same as ctl recovery
                await pilot.press("r")
                await until(pilot, lambda: isinstance(app.screen, RecoveryScreen), 15, "the report")
                report = await until_shown(pilot, app, f"seq {seq:>7}  score.change")
                assert "1 event LOST from the log" in report and "lost event" in report, report
                assert "Outage rule 'pause': a core outage pauses the clock" in report, report
                await pilot.press("escape")
                await until(pilot, lambda: not isinstance(app.screen, RecoveryScreen), 15, "the report closed")
                # the referee changes the rule as `ctl match outage --rule count` does
                await pilot.press("o")
                form = await until(pilot, lambda: isinstance(app.screen, FormScreen) and app.screen, 15, "the form")
                assert form.query_one("#f-rule").value == "pause"
                form.query_one("#f-rule").value = "count"
                await pilot.click("#ok")
                await until(pilot, lambda: app.model.outage == "count", 20, "the core's answer")
                assert match.referee().score()["outage"] == "count"
                await until_shown(pilot, app, "outage: clock counts it (o)")
                assert any("a core outage now counts as match time" in n for n in notifications(app))

        asyncio.run(scenario())
    finally:
        match.close()
