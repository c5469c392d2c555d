"""The public part of a scenario as plain data, and back: what the core tells every client.

Walls, zones, known objects, teams with their start zones, and the physics a simulator needs
(costs, positioning, drift, kinematics, sensors, camera). Victims are never included: they are
the match's secret, known to the core and to organiser-run robot hosts only.
"""
from __future__ import annotations

from dataclasses import asdict
from typing import Any

import numpy as np

from robo_comp.protocol.arena import unpack_walls
from robo_comp.world.scenario import (
    CameraConfig,
    CostConfig,
    Drift,
    Kinematics,
    KnownObject,
    Positioning,
    Rect,
    Scenario,
    SensorConfig,
    Team,
    Zone,
)

FALLBACK_COLOURS = ("#d62728", "#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b")


def arena_payload(scenario: Scenario, teams: list[str]) -> dict[str, Any]:
    """The public arena: ``walls`` is ``np.packbits`` of ``walls[y, x]`` (row-major)."""
    h, w = scenario.walls.shape
    known = {t.name: t for t in scenario.teams}
    team_rows = []
    for i, name in enumerate(teams):
        t = known.get(name)
        team_rows.append(t.to_dict() if t else {"name": name, "colour": FALLBACK_COLOURS[i % len(FALLBACK_COLOURS)],
                                               "start": None, "robots": 0})
    return {"name": scenario.name, "width": int(w), "height": int(h), "cell_cm": scenario.cell_size,
            "walls": np.packbits(scenario.walls.astype(bool), axis=None).tobytes(),
            "zones": [z.to_dict() for z in scenario.zones],
            "objects": [o.to_dict() for o in scenario.objects], "teams": team_rows,
            "seed": scenario.seed, "duration": scenario.duration,
            "costs": asdict(scenario.costs), "positioning": asdict(scenario.positioning),
            "drift": asdict(scenario.drift), "robot": asdict(scenario.kinematics),
            "sensors": asdict(scenario.sensors), "camera": asdict(scenario.camera)}


def _rect(d: dict[str, Any]) -> Rect:
    return Rect(int(d["x"]), int(d["y"]), int(d["w"]), int(d["h"]))


def scenario_from_payload(arena: dict[str, Any]) -> Scenario:
    """A :class:`Scenario` with the public arena and no victims (for robot hosts run by teams)."""
    teams = [Team(t["name"], t["colour"], _rect(t["start"]) if t.get("start") else Rect(0, 0, 0, 0),
                  int(t.get("robots", 0))) for t in arena.get("teams", [])]
    zones = [Zone(z["kind"], _rect(z), float(z["speed_factor"]), float(z["danger"]), float(z["cost"]),
                  bool(z["drop"]), z.get("name", "")) for z in arena.get("zones", [])]
    objects = [KnownObject(o["id"], o["kind"], int(o["x"]), int(o["y"]), o.get("description", ""))
               for o in arena.get("objects", [])]
    return Scenario(
        name=arena["name"], source="<core>", walls=unpack_walls(arena), cell_size=float(arena["cell_cm"]),
        costs=CostConfig(**arena.get("costs", {})), zones=zones, objects=objects, victims=[], teams=teams,
        duration=float(arena.get("duration", 600.0)), seed=int(arena.get("seed", 0)),
        positioning=Positioning(**arena.get("positioning", {})), drift=Drift(**arena.get("drift", {})),
        kinematics=Kinematics(**arena.get("robot", {})), sensors=SensorConfig(**arena.get("sensors", {})),
        camera=CameraConfig(**arena.get("camera", {})))
