"""Debug drawing from team code: the shapes, their bounds and their check, in one place.

Team code draws dots, lines and short text on the map (``robot.draw_dot``, ``robot.draw_line``,
``robot.draw_text``, see docs/sandbox.md) to show what it was thinking. What one robot drew
since its previous movement call is its **frame**; a frame replaces the robot's last one on
screen. The bounds:

* per call: coordinates are finite numbers within :data:`MAX_COORD` cells, a text has at most
  :data:`MAX_TEXT` characters (longer is cut), a colour is a name of :data:`COLOURS` or ``#rrggbb``;
* per tick: a frame holds at most :data:`MAX_SHAPES` shapes (a call past that draws nothing and
  returns False), and each robot's frame is recorded at most once per :data:`TICK` seconds of
  match time (the newest frame of the tick wins; an unchanged frame is not recorded again).

Drawing costs nothing in score or simulated time: no call budget, no match-limit count, no
round trip (the shapes travel with the robot's next movement call). The recorded event is
``debug.draw`` ``{"tags": [tag, ...], "frames": [[shape, ...], ...]}`` for one team, a shape
being ``["d", x, y, colour]``, ``["l", x0, y0, x1, y1, colour]`` or ``["t", x, y, text, colour]``
(map cells, colours as ``#rrggbb``). Who may see it: :mod:`robo_comp.protocol.topics`.

Nothing here imports more than the standard library: the sandbox child builds its shapes with
the same functions that the trusted side checks them with.
"""
from __future__ import annotations

import math
import re
from typing import Any

#: Shapes one robot's frame holds at most (per tick).
MAX_SHAPES = 16
#: Characters of one text at most (longer text is cut).
MAX_TEXT = 32
#: Seconds of match time between two recordings of one robot's frame at most (the log's pose sampling).
TICK = 0.5
#: Coordinates (in cells) further from the map's origin than this are refused.
MAX_COORD = 10_000.0
#: The colour names team code may use (else ``#rrggbb``); the value is what is drawn.
COLOURS = {"red": "#ff3b30", "green": "#34c759", "blue": "#0a84ff", "yellow": "#ffd60a",
           "orange": "#ff9f0a", "purple": "#bf5af2", "cyan": "#64d2ff", "magenta": "#ff2d95",
           "white": "#ffffff", "black": "#000000", "grey": "#8e8e93", "pink": "#ff8fab"}
DEFAULT_COLOUR = "yellow"
_HEX = re.compile(r"#[0-9a-fA-F]{6}")
#: A shape's kind and its number of coordinates.
KINDS = {"d": 2, "l": 4, "t": 2}


def colour(value: Any) -> str:
    """A colour team code gave, as ``#rrggbb``; ValueError with a sentence for anything else."""
    if type(value) is str:
        if value in COLOURS:
            return COLOURS[value]
        if _HEX.fullmatch(value):
            return value.lower()
    raise ValueError(f"colour must be one of {', '.join(COLOURS)} or '#rrggbb', not {str(value)[:20]!r}")


def coord(value: Any, what: str) -> float:
    """A coordinate (cells) rounded to 1/100 cell; ValueError with a sentence when it is not one."""
    if type(value) not in (int, float) or not math.isfinite(value) or abs(value) > MAX_COORD:
        raise ValueError(f"{what} must be a number of cells (within {MAX_COORD:g}), not {str(value)[:20]!r}")
    return round(float(value), 2)


def dot(x: Any, y: Any, col: Any = DEFAULT_COLOUR) -> list[Any]:
    """A dot at cell (x, y)."""
    return ["d", coord(x, "x"), coord(y, "y"), colour(col)]


def line(x0: Any, y0: Any, x1: Any, y1: Any, col: Any = DEFAULT_COLOUR) -> list[Any]:
    """A line from (x0, y0) to (x1, y1)."""
    return ["l", coord(x0, "x0"), coord(y0, "y0"), coord(x1, "x1"), coord(y1, "y1"), colour(col)]


def text(x: Any, y: Any, words: Any, col: Any = "white") -> list[Any]:
    """A short text at (x, y), cut to :data:`MAX_TEXT` characters."""
    if type(words) is not str:
        words = str(words)
    return ["t", coord(x, "x"), coord(y, "y"), words[:MAX_TEXT], colour(col)]


def clean_frame(shapes: Any) -> list[list[Any]]:
    """A frame as the trusted side keeps it: well-formed shapes only (others dropped), at most
    :data:`MAX_SHAPES`, texts cut. Never raises: what a sandbox sends cannot be trusted."""
    out: list[list[Any]] = []
    if type(shapes) is not list:
        return out
    for s in shapes:
        if len(out) >= MAX_SHAPES:
            break
        try:
            if type(s) is not list or not s or s[0] not in KINDS:
                continue
            n = KINDS[s[0]]
            if s[0] == "t":
                if len(s) != 5:
                    continue
                out.append(text(s[1], s[2], s[3] if type(s[3]) is str else "", s[4]))
            elif len(s) == n + 2:
                out.append([s[0], *(coord(v, "coordinate") for v in s[1:1 + n]), colour(s[1 + n])])
        except ValueError:
            continue
    return out


__all__ = ["COLOURS", "DEFAULT_COLOUR", "KINDS", "MAX_COORD", "MAX_SHAPES", "MAX_TEXT", "TICK", "clean_frame",
           "colour", "coord", "dot", "line", "text"]
