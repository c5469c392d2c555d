"""The robot API team code sees, defined once.

:data:`ROBOT_API` names every call of the ``robot`` object: its parameters (those that must be
numbers, those with a default), whether it moves the robot (a movement: answered when it ends;
the runtime turns it into movement steps) and what it does. Both sides take it from here:

* the sandbox child (:mod:`robo_comp.sandbox.child`) builds the ``robot`` object's functions from
  it (real Python signatures, so a wrong call gets Python's own ``TypeError``);
* the robot host and the engine answer the calls through one table,
  :data:`robo_comp.robots.teamcode.ROBOT_CALLS` for those that take no time and
  :func:`robo_comp.robots.teamcode.movement_steps` for the movements; ``tests/test_robot_api.py``
  checks that they answer exactly the calls named here.

Calls ``local`` to the child (``log``, debug drawing) are answered in the sandbox itself. This
module imports nothing: the child loads it before it drops its privileges.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RobotCall:
    """One call of the ``robot`` object: ``params`` in order (``name=default`` for an optional one,
    the default a Python literal), ``numbers`` those that must be numbers, ``moves`` a movement,
    ``local`` answered in the sandbox (no robot host involved), ``doc`` what it does."""

    name: str
    params: tuple[str, ...] = ()
    numbers: frozenset[str] = frozenset()
    moves: bool = False
    local: bool = False
    doc: str = ""

    @property
    def names(self) -> tuple[str, ...]:
        """The parameters' names, without defaults."""
        return tuple(p.split("=", 1)[0] for p in self.params)


def _call(name: str, params: str = "", numbers: str = "", *, moves: bool = False, local: bool = False,
          doc: str) -> RobotCall:
    return RobotCall(name, tuple(params.split()), frozenset(numbers.split()), moves, local, doc)


#: Every call of the ``robot`` object, in the order docs/sandbox.md lists them.
ROBOT_API: tuple[RobotCall, ...] = (
    _call("move", "cells", "cells", moves=True,
          doc="Drive forward ``cells`` cells (negative: backwards); returns when done."),
    _call("turn", "degrees", "degrees", moves=True,
          doc="Turn on the spot by ``degrees`` (positive: clockwise on the map, y pointing down)."),
    _call("go_to", "x y", "x y", moves=True, doc="Go to cell (x, y) along a planned path; returns when there."),
    _call("sense", doc="The range-sensor readings (plain data)."),
    _call("position", doc="The robot's believed position and heading ``[x, y, heading]``."),
    _call("map_piece", "radius", "radius", doc="The map around the robot, ``radius`` cells each way."),
    _call("plan", "x y", "x y", doc="A planned path (list of points) from here to (x, y)."),
    _call("report_find", "x y kind evidence=None", "x y",
          doc="Report a find at (x, y) of ``kind`` with plain-data ``evidence`` (picture ids)."),
    _call("take_picture", doc="Take a picture; returns its id."),
    _call("look", doc='Take a picture and say what it shows: ``{"picture": id, "victims": [{"x", "y", "kind"}]}``.'),
    _call("upload_picture", "picture=None", doc="Upload a picture (the last one if not given) to the environment."),
    _call("radio", "to data", doc="Send plain ``data`` to another robot of the team (tag ``to``; None: all of it)."),
    _call("report_obstacle", "x y", "x y",
          doc="Report cell (x, y) blocked where the map shows it free: on your team's map from now on "
              "(True: new, False: known)."),
    _call("log", "text", local=True, doc="Write a line to the team's log (counts against the output limit)."),
    _call("draw_dot", 'x y colour="yellow"', local=True,
          doc="Draw a dot at cell (x, y) on your team's view (debug drawing: costs nothing; False when "
              "this frame already holds the most shapes)."),
    _call("draw_line", 'x0 y0 x1 y1 colour="yellow"', local=True,
          doc="Draw a line from cell (x0, y0) to (x1, y1) on your team's view (debug drawing)."),
    _call("draw_text", 'x y text colour="white"', local=True,
          doc="Write a short text at cell (x, y) on your team's view (debug drawing; cut to 32 characters)."),
)
#: The calls by name.
BY_NAME: dict[str, RobotCall] = {c.name: c for c in ROBOT_API}
#: The calls a robot host or the engine answers (by RPC): movements and the calls that take no time.
REMOTE = tuple(c.name for c in ROBOT_API if not c.local)
#: The movements among them.
MOVEMENTS = tuple(c.name for c in ROBOT_API if c.moves)


def factory_source() -> str:
    """Python source of ``_make(_rpc, _tag, _num)``, which returns the remote calls of one robot as
    plain functions by name: each with its signature from the table (Python's own ``TypeError`` for
    a wrong call), its numbers checked with ``_num``, then ``_rpc(_tag, name, [args])``. The child
    compiles it once and calls it for every robot object it makes."""
    out = ["def _make(_rpc, _tag, _num):"]
    for call in ROBOT_API:
        if call.local:
            continue
        out.append(f"    def {call.name}({', '.join(call.params)}):")
        out.append(f"        {call.doc!r}")
        out += [f"        _num({p}, {p!r})" for p in call.names if p in call.numbers]
        out.append(f"        return _rpc(_tag, {call.name!r}, [{', '.join(call.names)}])")
    out.append("    return {" + ", ".join(f"{n!r}: {n}" for n in REMOTE) + "}")
    return "\n".join(out) + "\n"


__all__ = ["BY_NAME", "MOVEMENTS", "REMOTE", "ROBOT_API", "RobotCall", "factory_source"]
