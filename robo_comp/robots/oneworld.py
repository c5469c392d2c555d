"""One world for real and virtual robots, on each robot host (RAVE's idea, thesis ch. 2).

* **Camera-tracked robots are bodies here.** A fix of the organiser's overhead camera for a robot
  another host runs (another team's, real or simulated) puts that robot's body into this host's
  simulated arena (:meth:`robo_comp.world.arena.Arena.place`): this host's simulated range
  sensors and bump checks see it. A body no fix has moved for :data:`FOREIGN_TTL` seconds leaves.
* **A real robot of this host is a body at its own pose** (its driver's: odometry corrected by
  the camera), so this host's simulated robots see it too, and its pictures are drawn from there
  (virtual victims are found by real robots through the camera's pose).
* **A real robot's range readings include the virtual world**: each of its readings is the nearer
  of what its own sensor measured and what the simulated sensor at its pose sees (virtual walls
  and robots), see :func:`merge_readings`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from robo_comp.world.arena import Arena

#: Seconds after its last fix that another host's robot leaves this host's arena.
FOREIGN_TTL = 2.0
#: The team recorded for another host's robot (the camera knows robot ids, not teams).
FOREIGN_TEAM = ""


def is_real(driver: Any) -> bool:
    """True for a driver of a real robot whose arena body follows it (it is not simulated here)."""
    return bool(getattr(driver, "external_body", False))


@dataclass
class Foreign:
    """The bodies of robots other hosts run, placed by the camera's fixes."""

    seen: dict[str, float] = field(default_factory=dict)  # robot id -> monotonic time of its last fix

    def fix(self, world: Arena, robot_id: str, x: float, y: float, heading: float, now: float) -> None:
        """A camera fix of another host's robot: its body moves there (enters if new)."""
        world.place(robot_id, FOREIGN_TEAM, x, y, heading)
        self.seen[robot_id] = now

    def expire(self, world: Arena, now: float) -> None:
        """Take out the bodies no fix has moved for :data:`FOREIGN_TTL` seconds."""
        for rid, t in list(self.seen.items()):
            if now - t > FOREIGN_TTL:
                del self.seen[rid]
                if rid in world.tags:
                    world.remove_robot(rid)


def merge_readings(simulated: dict[str, Any], own: dict[str, Any]) -> dict[str, Any]:
    """A real robot's readings: per range (``front``, ``left``, ``right``, ``down``) the nearer of
    its own sensor's and the simulated sensor's at its pose (``None`` = no echo); the rest of the
    simulated row (``bump``, ``zone``, ...) as it is."""
    out = dict(simulated)
    for key, v in own.items():
        sim = simulated.get(key)
        if key in ("front", "left", "right", "down"):
            vals = [r for r in (v, sim) if r is not None]
            out[key] = min(vals) if vals else None
        else:
            out[key] = v
    return out
