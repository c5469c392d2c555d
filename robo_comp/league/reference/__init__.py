"""Reference teams: single-module league entrants of clearly different strength.

Each module advertises a ``play`` task, which the league starts on every robot of the team at
the beginning of a match. They seed a league and give students opponents (docs/league.md):

* ``frontier``: claims the nearest unvisited waypoint (shared between the team's robots),
  drives there cell by cell, waits instead of driving into a robot it senses ahead or a cell a
  teammate holds, looks around and reports what it sees. No points lost to bumps.
* ``explorer``: the template's explorer made autonomous: a fixed sweep of waypoints per robot,
  driven with ``go_to``, looking around at each; it bumps into the other team's robots now and
  then (the robot host keeps teammates apart).
* ``random_walker``: random turns and moves, looking now and then.
* ``sitter``: looks around once where it starts and stops.

``HANDICAP`` (a module global, 0 by default) makes a reference team weaker in known steps: its
robots start ``HANDICAP * LATE`` seconds (4 s a step) into the match, turning on the spot until then.
``handicapped(source, n)`` returns a module's source with its handicap set.
"""
from __future__ import annotations

import re
from pathlib import Path

#: The reference teams, strongest first (as measured in docs/performance.md).
NAMES = ("frontier", "explorer", "random_walker", "sitter")


def source(name: str) -> str:
    """The source text of reference team ``name``."""
    if name not in NAMES:
        raise KeyError(f"no reference team {name!r}; they are {', '.join(NAMES)}")
    return (Path(__file__).parent / f"{name}.py").read_text(encoding="utf-8")


def handicapped(text: str, handicap: int) -> str:
    """``text`` (a reference team's source) with ``HANDICAP = handicap``."""
    return re.sub(r"^HANDICAP = \d+", f"HANDICAP = {int(handicap)}", text, count=1, flags=re.M)


__all__ = ["NAMES", "handicapped", "source"]
