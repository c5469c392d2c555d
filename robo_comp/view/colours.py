"""The colours of a match, the same on the wall, the web page and in its legend (no pygame)."""
from __future__ import annotations

import numpy as np

from robo_comp.view.model import Arena

RGB = tuple[int, int, int]

FLOOR: RGB = (236, 234, 226)
WALL: RGB = (44, 44, 52)
NEAR_WALL: RGB = (214, 206, 190)  # cost shading: cells next to walls cost more to cross
ZONE_COLOURS: dict[str, RGB] = {"rubble": (176, 142, 98), "water": (110, 160, 220), "stairs": (160, 160, 170),
                                "drop": (96, 96, 110), "hole": (96, 96, 110), "edge": (96, 96, 110),
                                "sand": (222, 200, 130), "grass": (120, 190, 110)}
ZONE_DEFAULT: RGB = (200, 160, 200)
LOST_MARK: RGB = (255, 210, 0)
FIND_COLOURS: dict[str, RGB] = {"reported": (250, 200, 40), "confirmed": (40, 190, 70),
                                "rejected": (220, 40, 40), "duplicate": (150, 150, 150)}
DISCOVERY: RGB = (255, 140, 0)
DQ_MARK: RGB = (20, 20, 20)  # the cross on a disqualified robot (the wall)
LEFT: RGB = (90, 90, 100)  # a robot that left (the page greys it; the wall no longer draws it)
PICTURE: RGB = (122, 184, 255)  # the mark where a robot took a picture
VIDEO: RGB = (199, 125, 255)  # the mark where a robot filmed a video
#: The hidden victims revealed at the finish: found by a team, or missed by all.
VICTIM_FOUND: RGB = (40, 190, 70)
VICTIM_MISSED: RGB = (255, 59, 48)
#: A ticker line's swatch by the story item's kind, where no team or find state colours it.
KIND_COLOURS: dict[str, RGB] = {"find": (40, 190, 70), "penalty": (255, 86, 70), "bump": (255, 159, 26),
                                "lost": (255, 210, 0), "phase": (255, 176, 32), "broadcast": (122, 184, 255),
                                "disqualified": (255, 45, 85), "score": (192, 192, 208)}


def hex_rgb(colour: str) -> RGB:
    """``#rrggbb`` to an RGB tuple (grey when malformed)."""
    try:
        c = colour.lstrip("#")
        return int(c[0:2], 16), int(c[2:4], 16), int(c[4:6], 16)
    except (ValueError, AttributeError, IndexError):
        return (128, 128, 128)


def cell_colours(arena: Arena) -> np.ndarray:
    """RGB per cell ``[y, x, 3]``: floor, cost shading near walls, zones, start zones, walls."""
    h, w = arena.height, arena.width
    img = np.empty((h, w, 3), np.float32)
    img[:] = FLOOR
    walls = arena.walls
    near = np.zeros_like(walls)
    near[1:, :] |= walls[:-1, :]
    near[:-1, :] |= walls[1:, :]
    near[:, 1:] |= walls[:, :-1]
    near[:, :-1] |= walls[:, 1:]
    near[1:, 1:] |= walls[:-1, :-1]
    near[:-1, :-1] |= walls[1:, 1:]
    near[1:, :-1] |= walls[:-1, 1:]
    near[:-1, 1:] |= walls[1:, :-1]
    if arena.costs is not None:  # the map service's costs: shade by cost, darkest at the highest
        c = np.maximum(arena.costs.astype(np.float32), 1.0)
        top = float(c[~walls].max()) if (~walls).any() else 1.0
        if top > 1.0:
            t = (np.log(c) / np.log(top))[..., None]
            img[:] = img * (1 - t) + np.array(NEAR_WALL, np.float32) * t
    else:  # no cost grid (replays): cells next to walls are the expensive ones (thesis app. A)
        img[near] = NEAR_WALL
    for z in arena.zones:
        col = np.array(ZONE_COLOURS.get(str(z.get("kind")), ZONE_DEFAULT), np.float32)
        x, y, zw, zh = int(z["x"]), int(z["y"]), int(z["w"]), int(z["h"])
        img[max(0, y):y + zh, max(0, x):x + zw] = img[max(0, y):y + zh, max(0, x):x + zw] * 0.45 + col * 0.55
    for t in arena.teams:
        s = t.get("start")
        if s:
            col = np.array(hex_rgb(t.get("colour", "")), np.float32)
            x, y, sw, sh = int(s["x"]), int(s["y"]), int(s["w"]), int(s["h"])
            img[max(0, y):y + sh, max(0, x):x + sw] = img[max(0, y):y + sh, max(0, x):x + sw] * 0.8 + col * 0.2
    img[walls] = WALL
    return np.floor(img + 0.5).astype(np.uint8)


__all__ = ["DISCOVERY", "DQ_MARK", "FIND_COLOURS", "FLOOR", "KIND_COLOURS", "LEFT", "LOST_MARK", "NEAR_WALL",
           "PICTURE", "RGB", "VICTIM_FOUND", "VICTIM_MISSED", "VIDEO", "WALL", "ZONE_COLOURS", "ZONE_DEFAULT",
           "cell_colours", "hex_rgb"]
