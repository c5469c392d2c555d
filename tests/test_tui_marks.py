"""Every choice the consoles show by colour is also shown by text or a mark (issue 29: for
colour-blind students and monochrome terminals). Each check reads the screen as plain text, with
no colour at all, before and after a choice changes: the text must change with it."""
from __future__ import annotations

import asyncio
from pathlib import Path

from robo_comp.tui.referee_app import RefereeApp
from robo_comp.tui.screens.give_task import GiveTaskScreen
from robo_comp.tui.screens.upload import UploadScreen
from robo_comp.tui.team_app import TeamApp
from robo_comp.tui.testing import CannedLink, until, until_shown
from robo_comp.tui.widgets.map_view import MapView

FIXED = {"clock": lambda: 100.0, "wall_clock": lambda: 1002.5, "poll": False}


def test_radio_buttons_and_check_boxes_show_their_state_by_a_mark(tmp_path: Path) -> None:
    """Textual draws ``▐●▌`` and ``▐X▌`` whether on or off (colour tells them apart): the upload
    dialog's extension/code, run now and all robots, and the task form's now/queue."""
    async def scenario() -> None:
        app = TeamApp(link=CannedLink("team", "red", upload=True), upload_dir=tmp_path, **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(80, 24)) as pilot:
            await until(pilot, lambda: app.core_features.get("upload") and app.selected == 101, 15, "the console")
            await pilot.press("u")
            await until(pilot, lambda: isinstance(app.screen, UploadScreen), 15, "the upload dialog")
            await until_shown(pilot, app, "▐●▌ extension", "▐ ▌ code", "▐ ▌ run it now")
            await pilot.click("#code")
            await pilot.click("#run")
            await until_shown(pilot, app, "▐ ▌ extension", "▐●▌ code", "▐X▌ run it now")
            await pilot.press("escape")
            await until(pilot, lambda: not isinstance(app.screen, UploadScreen), 15, "the dialog closed")
            await pilot.press("t")
            await until(pilot, lambda: isinstance(app.screen, GiveTaskScreen), 15, "the task form")
            await until_shown(pilot, app, "▐●▌ now", "▐ ▌ queue")
            await pilot.click("#queue")
            await until_shown(pilot, app, "▐ ▌ now", "▐●▌ queue")

    asyncio.run(scenario())


def test_the_highlighted_robot_and_team_carry_a_mark() -> None:
    """The robot the table's cursor is on is the selected one (monitor, map, STOP), and the team
    the score table's cursor is on is the penalty form's first choice: each carries a ``▸``."""
    async def scenario() -> None:
        app = RefereeApp(link=CannedLink("referee", None), **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(120, 40)) as pilot:
            await until(pilot, lambda: app.selected == 101, 15, "the first robot selected")
            await until_shown(pilot, app, "▸101", " 102", "▸1   red", " 2   blue", absent=("▸102",))
            app.screen.query_one("#robots").focus()
            await pilot.press("down")
            await until(pilot, lambda: app.selected == 102, 15, "robot 102 selected")
            await until_shown(pilot, app, "▸102", absent=("▸101",))
            app.screen.query_one("#scores").focus()
            await pilot.press("down")
            await until_shown(pilot, app, "▸2   blue", absent=("▸1   red",))

    asyncio.run(scenario())


def test_a_failed_task_and_a_refused_find_are_said_not_only_coloured() -> None:
    """A task that ended not ok was logged "done" in yellow (green when ok); a refused find was a
    yellow ``+`` (green when confirmed)."""
    link = CannedLink("referee", None)
    link.data["snapshot"]["finds"].append({"id": 2, "team": "blue", "tag": 104, "x": 20.0, "y": 9.0,
                                           "state": "rejected", "verdict": {"valid": False}})

    async def scenario() -> None:
        app = RefereeApp(link=link, **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(160, 48)) as pilot:
            await until(pilot, lambda: len(app.model.finds) == 2, 15, "the finds")
            await until_shown(pilot, app, "robot 101 followPath #5 FAILED: blocked by a wall at (2, 2)")
            m = app.screen.query_one(MapView)

            def marks() -> dict | None:
                drawn = m.render().plain.splitlines()
                spot = {(f["x"], f["y"]): m.cell_to_screen(f["x"], f["y"]) for f in app.model.finds}
                try:
                    return {xy: drawn[line][col] for xy, (col, line) in spot.items()}
                except IndexError:  # the map not laid out at its size yet
                    return None

            expected = {(11.0, 9.0): "+", (20.0, 9.0): "-"}
            await until(pilot, lambda: marks() == expected, 15, "the finds drawn on the map")
            assert marks() == expected

    asyncio.run(scenario())


def test_a_key_the_core_does_not_offer_is_struck_through_not_only_dimmed() -> None:
    async def scenario() -> None:
        app = TeamApp(link=CannedLink("team", "red", upload=False), **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(100, 30)) as pilot:
            await until(pilot, lambda: app.core_features.get("upload") is False, 15, "feature detection")

            def upload_keys() -> list:
                return [k for k in app.screen.query("FooterKey") if getattr(k, "action", "") == "app.upload"]

            # the footer is composed again after the features arrive (later on a loaded machine)
            await until(pilot, lambda: any(k.has_class("-disabled") and k.rich_style.strike for k in upload_keys()),
                        15, "the upload key dimmed and struck through")
            off = upload_keys()
            assert off and off[0].has_class("-disabled")
            assert off[0].rich_style.strike, off[0].rich_style

    asyncio.run(scenario())
