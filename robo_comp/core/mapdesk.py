"""The map service behind the protocol: whole map, pieces around robots, pushed deltas.

Robot positions reach the map when it is read (the robots that reported since the last
read, with their newest poses), discoveries when a team reports a find, the obstacles a team's
robots report (kept by the match: :class:`robo_comp.match.teamwork.TeamWork`) before each read
and each push. Every heartbeat each robot host gets a
``map.delta`` push with what changed since the version it has, as its team may see it, but
robot positions; a host that is new, or whose version the service no longer knows, gets a
full snapshot (``type: "full"``).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from robo_comp import protocol as P
from robo_comp.core.desk import Access, Outbox
from robo_comp.protocol.states import RobotStatus
from robo_comp.errors import FieldError
from robo_comp.world.mapservice import MapService
from robo_comp.world.scenario import Scenario

MAX_PIECE_RADIUS = 100


class MapDesk:
    """The core's map service and who has which version of it."""

    def __init__(self, access: Access, out: Outbox, scenario: Scenario) -> None:
        self.access = access
        self.out = out
        self.service = MapService.from_scenario(scenario)
        self.pushed: dict[bytes, int] = {}  # host routing id -> map version it has
        self._synced = 0.0  # when robot positions last went onto the map (see _sync_robots)
        self._obstacles = 0  # how many of the match's obstacles are on the map (see _sync_obstacles)

    def handlers(self) -> dict[str, Callable[[bytes, P.Message], dict[str, Any] | None]]:
        """Request handlers this module adds to the core."""
        return {"map": self._on_map, "map.delta": self._on_delta}

    def _team(self, ident: bytes) -> str | None:
        who = self.access.session(ident).who
        return None if who.role == "referee" else who.team

    def _on_map(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        team = self._team(ident)
        self._sync_robots()
        self._sync_obstacles()
        tag = msg.body.get("tag")
        if tag is None:
            return self.service.snapshot(team)
        r = self.access.robot_for(ident, tag)
        radius = msg.body.get("radius", 5)
        if not 0 <= radius <= MAX_PIECE_RADIUS:
            raise FieldError(f"'radius' must be 0..{MAX_PIECE_RADIUS} cells")
        if ("robot", str(r.tag)) not in self.service._ent:
            self.service.report_position(str(r.tag), r.team, r.x, r.y, r.heading, time.time())
        return self.service.piece(str(r.tag), radius, team)

    def _on_delta(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        self._sync_robots()
        self._sync_obstacles()
        return self.service.delta_since(msg.body["since"], self._team(ident))

    def _sync_robots(self) -> None:
        """Put the robots that reported since the last read on the map, with their newest poses.

        Robots report many times a second and the map is read seldom (``map`` and ``map.delta``
        requests; the pushes to hosts carry no robots), so positions go onto the map when it is
        read, not with every ``robot.positions`` batch: the core's loop pays per read, not per
        report."""
        since, self._synced = self._synced, time.time()
        for r in self.access.registry.robots.values():
            if r.last_report >= since and r.status == RobotStatus.CONNECTED:
                self.service.report_position(str(r.tag), r.team, r.x, r.y, r.heading, r.last_report)

    def _sync_obstacles(self) -> None:
        """Put the obstacles the match took since the last sync on the map (also those a recovery
        rebuilt from the log): each on its team's map."""
        work = self.access.match.teamwork
        total = sum(len(k) for k in work.obstacles.values())
        if total == self._obstacles:
            return
        self._obstacles = total
        for team, (x, y) in work.cells(None):
            self.service.add_obstacle(team, x, y)

    def discovery(self, tag: int, team: str, x: float, y: float, kind: str, evidence: list[int]) -> dict[str, Any]:
        """Record a reported find on the map (the team's, unless the scenario shares finds)."""
        return self.service.add_discovery(str(tag), team, x, y, time.time(), kind=kind or "victim",
                                          evidence=[str(e) for e in evidence])

    def push(self) -> None:
        """Send every robot host the changes since the version it has, but robot positions
        (a host knows where its robots are; ``map`` and ``map.delta`` requests have them all)."""
        self._sync_obstacles()
        frames: dict[tuple[int, str | None], tuple[int, bytes]] = {}  # hosts at one version share a delta
        for ident in self.access.host_sessions():
            sess = self.access.session(ident)
            have = self.pushed.get(ident, 0)
            if have >= self.service.static_version:  # only robots moved since
                continue
            key = (have, sess.who.team)
            if key not in frames:
                delta = self.service.delta_since(have, sess.who.team, robots=False)
                frames[key] = (delta["version"], P.request("map.delta", 0, delta))
            self.pushed[ident], frame = frames[key]
            self.out.send(ident, frame)
        for gone in [i for i in self.pushed if not self.access.has_session(i)]:
            del self.pushed[gone]
