"""Reading the arena payload the core sends (``arena`` request, ``core.started`` event)."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np


def unpack_walls(arena: dict[str, Any]) -> np.ndarray:
    """Rebuild the bool wall grid ``[y, x]`` from an arena payload."""
    import numpy as np  # here: a client that never reads walls (a robot's sandbox) does not load numpy
    h, w = arena["height"], arena["width"]
    bits = np.unpackbits(np.frombuffer(arena["walls"], dtype=np.uint8), count=h * w)
    return bits.reshape(h, w).astype(bool)
