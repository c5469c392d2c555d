"""The team console driven by a pilot against a real core and real robot hosts."""
from __future__ import annotations

import asyncio
from pathlib import Path

from conftest import CoreHandle, wait_robots

from robo_comp.launch import start_core
from robo_comp.link import LinkState
from robo_comp.tui.screens.give_task import GiveTaskScreen
from robo_comp.tui.screens.upload import UploadScreen
from robo_comp.tui.team_app import TeamApp
from robo_comp.tui.testing import CannedLink, notifications, screen_text, until, until_shown


def team_app(core: CoreHandle, team: str = "red", **kw: object) -> TeamApp:
    return TeamApp(str(core.state), core.token(team), **kw)  # type: ignore[arg-type]


async def robots_shown(pilot, app: TeamApp, n: int) -> None:  # type: ignore[no-untyped-def]
    await until(pilot, lambda: sum(r.get("status") == "connected" for r in app.model.robots.values()) >= n,
                15, f"{n} robots in the table")
    await until(pilot, lambda: app.selected is not None and app.model.details.get(app.selected), 15,
                "the selected robot's monitor data")


async def type_text(pilot, text: str) -> None:  # type: ignore[no-untyped-def]
    await pilot.press(*["comma" if c == "," else "space" if c == " " else c for c in text])


def test_give_task_through_the_form_and_see_it_finish(core: CoreHandle) -> None:
    core.robots("red", 2)

    async def scenario() -> None:
        app = team_app(core)
        async with app.run_test(size=(100, 30)) as pilot:
            await robots_shown(pilot, app, 2)
            tag = app.selected
            assert tag == 101
            x, y = int(app.model.robots[tag]["x"]), int(app.model.robots[tag]["y"])
            await pilot.press("t")
            form = await until(pilot, lambda: isinstance(app.screen, GiveTaskScreen) and app.screen, 15, "the form")
            await until(pilot, lambda: len(form.query("ArgField")) == 2, 15, "goTo's two fields")
            # a wrong value is caught by the form, before anything is sent
            await type_text(pilot, "abc")
            await pilot.press("enter")  # next field
            await type_text(pilot, str(y + 1))
            await pilot.press("enter")  # last field: give ... refused by the form
            assert isinstance(app.screen, GiveTaskScreen)
            assert "whole number" in str(form.query_one("#form-error").render())
            first = form.query("ArgField Input").first()
            await pilot.click(first)
            await pilot.press("end")
            for _ in range(3):
                await pilot.press("backspace")
            await type_text(pilot, str(x + 2))
            await pilot.press("ctrl+g")  # give
            await until(pilot, lambda: not isinstance(app.screen, GiveTaskScreen), 15, "the form to close")
            await until(pilot, lambda: any(f"Robot {tag} finished" in n for n in notifications(app)), 15,
                        "the task.done toast")
            await until(pilot, lambda: any(d.get("ok") for d in app.model.details[tag].get("done", [])), 5,
                        "the done task in the monitor")
            row = app.model.robots[tag]
            assert (round(row["x"]), round(row["y"])) == (x + 2, y + 1)
            assert f"goTo({x + 2}, {y + 1})" in screen_text(app)  # the monitor's done list

    asyncio.run(scenario())


def test_stop_goes_out_at_once_while_a_form_is_open(core: CoreHandle) -> None:
    core.robots("red", 1, "--speed", "0.5")
    c = core.client("red")
    wait_robots(c, 1)

    async def scenario() -> None:
        app = team_app(core)
        async with app.run_test(size=(80, 24)) as pilot:
            await robots_shown(pilot, app, 1)
            tag = app.selected
            assert tag is not None
            reply = await app.give(tag, "goTo", [20, 17], False)
            assert reply is not None
            await until(pilot, lambda: app.model.robots[tag].get("moving"), 20, "the robot to move")
            await pilot.press("t")  # the form is open and waits for input ...
            await until(pilot, lambda: isinstance(app.screen, GiveTaskScreen), 15, "the form")
            slow = asyncio.ensure_future(app.link.request("tasks", tag=tag))  # ... and a request is in flight
            await pilot.press("ctrl+s")  # STOP anyway
            await until(pilot, lambda: any(f"Robot {tag} stopped" in n for n in notifications(app)), 5,
                        "the stop toast")
            assert isinstance(app.screen, GiveTaskScreen)  # the form stayed open
            await slow
            assert not app.model.robots[tag].get("moving")
            await pilot.press("escape")
        # the robot stays usable after a stop
        c.give(tag, "goTo", [2, 2])

    asyncio.run(scenario())


BAD_EXTENSION = '''"""A square extension whose init breaks the checked contract (it must take exactly robot)."""
MANIFEST = {
    "name": "badsquare", "version": "1.0", "kind": "extension",
    "tasks": {"badsquare": {"description": "never loads",
                            "args": [{"name": "side", "type": "int", "description": "cells"}]}},
}


def init(robot, extra):
    pass


def badsquare(robot, side):
    robot.move(side)
'''


def test_upload_a_bad_module_shows_the_checked_error(core: CoreHandle, tmp_path: Path) -> None:
    core.robots("red", 1)
    (tmp_path / "bad_ext.py").write_text(BAD_EXTENSION)

    async def scenario() -> None:
        app = team_app(core, upload_dir=tmp_path)
        async with app.run_test(size=(100, 30)) as pilot:
            await robots_shown(pilot, app, 1)
            assert app.core_features.get("upload"), "the core serves uploads"
            await pilot.press("u")
            dlg = await until(pilot, lambda: isinstance(app.screen, UploadScreen) and app.screen, 15, "the dialog")
            dlg.query_one("#path").value = str(tmp_path / "bad_ext.py")
            await pilot.press("ctrl+u")
            await until(pilot, lambda: any("Upload of bad_ext.py" in n for n in notifications(app)), 15,
                        "the upload verdict")
            shown = screen_text(app)
            assert "✗" in shown and "init" in shown, shown
            assert "Traceback" not in shown

    asyncio.run(scenario())


def test_upload_greyed_out_when_the_core_lacks_it() -> None:
    """An older core without uploads: the action is disabled, the key does nothing."""
    async def scenario() -> None:
        app = TeamApp(link=CannedLink("team", "red", upload=False))  # type: ignore[arg-type]
        async with app.run_test() as pilot:
            await until(pilot, lambda: "upload" in app.core_features, 20, "feature detection")
            assert app.core_features["upload"] is False
            assert app.check_action("upload", ()) is None  # shown disabled in the footer
            await pilot.press("u")
            assert not isinstance(app.screen, UploadScreen)

    asyncio.run(scenario())


def test_reconnects_when_the_core_restarts(core: CoreHandle) -> None:
    core.robots("red", 1)

    async def scenario() -> None:
        app = team_app(core)
        async with app.run_test() as pilot:
            await robots_shown(pilot, app, 1)
            port = int(app.link.url.rsplit(":", 1)[1])  # the robot host reconnects to the same port
            core.proc.terminate()
            await asyncio.to_thread(core.proc.wait, 5)
            await until(pilot, lambda: app.link.state is LinkState.RECONNECTING, 20, "reconnecting")
            assert any("reconnecting" in n for n in notifications(app))
            assert "reconnecting" in screen_text(app)
            core.proc = await asyncio.to_thread(start_core, core.state, "--heartbeat", "0.2", "--teams", "red,blue",
                                                port=port)
            await until(pilot, lambda: app.link.state is LinkState.CONNECTED, 30, "reconnected")
            await until(pilot, lambda: any("Reconnected" in n for n in notifications(app)), 15, "the toast")
            await until_shown(pilot, app, "online")
            # and the session works again: the robot host re-registers with the new core
            await until(pilot, lambda: app.model.robots.get(101, {}).get("status") == "connected", 15,
                        "robot 101 back in the table")

    asyncio.run(scenario())


def test_core_errors_are_notifications_not_tracebacks(core: CoreHandle) -> None:
    async def scenario() -> None:
        app = team_app(core, team="blue")
        async with app.run_test() as pilot:
            await until(pilot, lambda: app.link.state is LinkState.CONNECTED, 20, "connected")
            assert await app.give(999, "goTo", [1, 1], False) is None  # no such robot
            await pilot.pause()
            assert any("999" in n for n in notifications(app))
            app.action_give_task()  # nothing selected
            assert any("select a robot first" in n for n in notifications(app))

    asyncio.run(scenario())


def test_wrong_token_is_said_on_screen(core: CoreHandle) -> None:
    async def scenario() -> None:
        app = TeamApp(str(core.state), "not-a-token")
        async with app.run_test() as pilot:
            await until(pilot, lambda: any("Cannot connect" in n for n in notifications(app)), 20, "the refusal")
            await until_shown(pilot, app, "offline")

    asyncio.run(scenario())
