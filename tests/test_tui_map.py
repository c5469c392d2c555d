"""The consoles' map as a person reads it off the screen: the arena's aspect ratio kept, every cell
of a small arena shown (no room squashed into a block of wall), robots whose team and selection
are said in the legend, not by colour alone."""
from __future__ import annotations

import asyncio
from typing import Any

import numpy as np
import pytest

from robo_comp.tui.referee_app import RefereeApp
from robo_comp.tui.team_app import TeamApp
from robo_comp.tui.testing import CannedLink, screen_text, until, until_shown
from robo_comp.world.scenario import bundled_scenario_path, load_scenario

FIXED = {"clock": lambda: 100.0, "wall_clock": lambda: 1002.5, "poll": False}
#: What each character of the map says about the two pixels it shows (top, bottom): a wall or not.
PIXELS = {"█": (True, True), "▀": (True, False), "▄": (False, True), "·": (False, False)}


def arena_link(role: str, scenario: str, robots: bool = False) -> CannedLink:
    """The canned core with a bundled scenario's walls; without robots, finds and events unless
    ``robots`` (then two robots of each team, inside the arena)."""
    link = CannedLink(role, None if role == "referee" else "red")
    walls = load_scenario(bundled_scenario_path(scenario)).walls
    link.data["snapshot"]["arena"] = {"name": scenario, "width": walls.shape[1], "height": walls.shape[0],
                                      "walls": np.packbits(walls, axis=None).tobytes()}
    rows: list[dict[str, Any]] = []
    if robots:
        free = [(x, y) for y in range(walls.shape[0]) for x in range(walls.shape[1]) if not walls[y, x]]
        rows = [{"tag": 101 + i, "team": ("red", "blue")[i // 2], "robot_id": f"r{i}", "status": "connected",
                 "x": float(free[i * 7][0]), "y": float(free[i * 7][1]), "heading": 0.0, "task": None, "queue": 0}
                for i in range(4)]
        if role == "team":
            rows = [r for r in rows if r["team"] == "red"]
    link.data["snapshot"].update(robots=rows, finds=[])
    link.data["robots"] = rows
    link.data["monitor"] = {}
    link.data["events"] = []
    return link


def map_block(app: Any) -> list[str]:
    """The map's characters off the screen: the lines inside the Map panel above its legend."""
    lines = screen_text(app).splitlines()
    top = next(i for i, ln in enumerate(lines) if "─ Map ─" in ln)
    left = lines[top].index("╭─ Map") + 1
    out: list[str] = []
    for ln in lines[top + 1:]:
        cells = ln[left:]
        row = cells[:cells.index("│")] if "│" in cells else cells
        if "█ wall" in row or not row.strip():
            break  # the legend (or the panel's end)
        out.append(row.rstrip())
    return out


def decode(block: list[str]) -> np.ndarray:
    """Wall pixels, two per character (top, bottom); a robot's or a find's character counts as
    unknown (-1)."""
    width = max(len(ln) for ln in block)
    px = np.full((2 * len(block), width), -1, dtype=int)
    for r, ln in enumerate(block):
        for c, ch in enumerate(ln):
            if ch in PIXELS:
                px[2 * r:2 * r + 2, c] = PIXELS[ch]
    return px


@pytest.mark.parametrize("size", [(120, 40), (160, 48)], ids=lambda s: f"{s[0]}x{s[1]}")
def test_the_referee_map_keeps_the_arena_s_aspect_and_shows_every_cell(size: tuple[int, int]) -> None:
    """demo_room (24×16) in the referee console: the map is as wide, in cells, as it is high (a
    character is two pixels high), and the pixel at the centre of each cell shows that cell; the
    old map squashed the closet and the rubble into solid wall at 120×40."""
    walls = load_scenario(bundled_scenario_path("demo_room")).walls
    rows, cols = walls.shape

    async def scenario() -> None:
        app = RefereeApp(link=arena_link("referee", "demo_room"), **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=size) as pilot:
            await until(pilot, lambda: app.model.walls is not None, 15, "the arena")
            await pilot.pause(0.5)
            block = map_block(app)
            px = decode(block)
            width = max(len(ln) for ln in block)
            scale = width / cols  # pixels per cell, as drawn
            assert scale >= 1, f"the map is {width} characters wide for {cols} columns: {block}"
            high = rows * scale  # the pixels the arena's rows need at that scale
            assert high <= px.shape[0] <= high + 2, (width, len(block), block)  # the aspect ratio kept
            shown = np.array([[px[int((y + 0.5) * scale), int((x + 0.5) * scale)] for x in range(cols)]
                              for y in range(rows)])
            assert (shown == walls).all(), "\n".join(block)

    asyncio.run(scenario())


def test_a_big_arena_keeps_its_aspect_in_the_narrow_map_panel() -> None:
    """office (64×48) at 80×24, the map panel of a narrow console: scaled down, the same shape."""
    rows, cols = load_scenario(bundled_scenario_path("office")).walls.shape

    async def scenario() -> None:
        app = RefereeApp(link=arena_link("referee", "office"), **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(80, 24)) as pilot:
            await until(pilot, lambda: app.model.walls is not None, 15, "the arena")
            await pilot.press("v", "v")  # events → monitor → map
            await pilot.pause(0.5)
            block = map_block(app)
            width, high = max(len(ln) for ln in block), 2 * len(block)
            assert abs(width * rows - high * cols) <= 2 * cols, (width, high, block)

    asyncio.run(scenario())


def test_the_map_legend_says_whose_robots_and_which_is_selected() -> None:
    """Teams are told apart by colour on the map: the legend names each team's robots (the last
    digit of their tags) and the selected robot, in words."""
    async def scenario() -> None:
        app = RefereeApp(link=arena_link("referee", "demo_room", robots=True), **FIXED)  # type: ignore[arg-type]
        async with app.run_test(size=(160, 48)) as pilot:
            await until(pilot, lambda: app.selected == 101, 15, "the first robot selected")
            await until_shown(pilot, app, "red 1 2 · blue 3 4", "▸ 101 selected")
        team = TeamApp(link=arena_link("team", "demo_room", robots=True), **FIXED)  # type: ignore[arg-type]
        async with team.run_test(size=(160, 48)) as pilot:
            await until(pilot, lambda: team.selected == 101, 15, "the first robot selected")
            await pilot.pause(0.5)
            assert "red 1 2" not in screen_text(team)  # one team: nothing to tell apart

    asyncio.run(scenario())
