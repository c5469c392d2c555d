"""What the symbols and colours on the map mean: the legend every viewer shows (no pygame).

:func:`legend_colours` is what the web gateway sends the page (``state.legend``; the page
writes its list from it, ``static/app.js``); :func:`legend` is the same list as entries, in the
page's order and wording, which the wall draws (each viewer draws its own symbol for an entry's
``key``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from robo_comp.view import colours as R
from robo_comp.view.model import MatchView


@dataclass(frozen=True)
class LegendEntry:
    """One line of the legend: what it explains (``key``: ``robot``, ``lost``, ``disqualified``,
    ``left``, ``find``, ``picture``, ``video``, ``discovery``, ``victim_found``,
    ``victim_missed``, ``wall``, ``costly``, ``start``, ``zone``), its colour and its words;
    ``team``: the team of a robot or start-zone line."""

    key: str
    colour: R.RGB
    text: str
    team: str | None = None
    state: str = ""  # a find's state


def _hex(c: R.RGB) -> str:
    return "#%02x%02x%02x" % tuple(int(v) for v in c)


def legend_colours(model: MatchView) -> dict[str, Any]:
    """The legend's colours as ``#rrggbb`` (the web page's ``state.legend``): the find states,
    the zone kinds on this map, walls, floor, costly cells, discoveries and the lost mark."""
    zones = sorted({str(z.get("kind")) for z in (model.arena.zones if model.arena else [])})
    return {"finds": {k: _hex(v) for k, v in R.FIND_COLOURS.items()},
            "zones": {k: _hex(R.ZONE_COLOURS.get(k, R.ZONE_DEFAULT)) for k in zones},
            "wall": _hex(R.WALL), "floor": _hex(R.FLOOR), "costly": _hex(R.NEAR_WALL),
            "discovery": _hex(R.DISCOVERY), "lost": _hex(R.LOST_MARK)}


def legend(model: MatchView) -> list[LegendEntry]:
    """The legend of this match's map, in the page's order and words (empty before the arena)."""
    a = model.arena
    if a is None:
        return []
    teams = [str(t.get("name")) for t in a.teams]
    out = [LegendEntry("robot", R.hex_rgb(a.colour(t)), f"robot of {t} (line: heading)", t) for t in teams]
    out += [LegendEntry("lost", R.LOST_MARK, "lost robot"),
            LegendEntry("disqualified", R.DQ_MARK, "disqualified robot"),
            LegendEntry("left", R.LEFT, "robot that left")]
    out += [LegendEntry("find", c, f"find, {state}", state=state) for state, c in R.FIND_COLOURS.items()]
    out += [LegendEntry("picture", R.PICTURE, "picture taken"),
            LegendEntry("video", R.VIDEO, "video filmed"),
            LegendEntry("discovery", R.DISCOVERY, "discovery (team view)"),
            LegendEntry("victim_found", R.VICTIM_FOUND, "victim found (at the end)"),
            LegendEntry("victim_missed", R.VICTIM_MISSED, "victim missed (at the end)"),
            LegendEntry("wall", R.WALL, "wall"),
            LegendEntry("costly", R.NEAR_WALL, "costly cell (near a wall)")]
    out += [LegendEntry("start", R.hex_rgb(a.colour(str(t.get("name")))), f"start zone of {t.get('name')}",
                        str(t.get("name"))) for t in a.teams if t.get("start")]
    kinds = sorted({str(z.get("kind")) for z in a.zones})
    out += [LegendEntry("zone", R.ZONE_COLOURS.get(k, R.ZONE_DEFAULT), f"zone: {k}") for k in kinds]
    return out


__all__ = ["LegendEntry", "legend", "legend_colours"]
