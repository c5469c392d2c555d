"""The thesis's A* (appendix A, section 4.4.4), reimplemented as the benchmark baseline.

As described there: the map is a list of lists, the OPEN list is a binary heap (heapq)
ordered by F, CLOSED is a separate collection, neighbours are visited east, south, west,
north, a step costs 10 (normal cell cost 1 times 10) and H is the Manhattan distance times
10. The path is rebuilt by walking parents back from the goal. Deliberately unoptimised
beyond what the thesis did; used only to measure how far we have come.

The thesis does not say how equal F values are ordered. Its table 6.1 shows map 1 and
map 3 growing linearly with the map size (only the path is expanded) and map 3 reaching
the top-right corner first, so ties here go to the smaller H, then to the earlier pushed
entry (east before south): that reproduces the reported behaviour. Breaking ties on the
node tuple instead would sweep the whole map and make this baseline look far slower than
the thesis's code was.
"""
from __future__ import annotations

import heapq
import time

STEP = 10
NEIGHBOURS = ((1, 0), (0, 1), (-1, 0), (0, -1))  # east, south, west, north


def thesis_astar(grid: list[list[int]], start: tuple[int, int], goal: tuple[int, int],
                 deadline: float | None = None) -> list[tuple[int, int]] | None:
    """Path from start to goal on ``grid[y][x]`` (1 = wall), or None; raises TimeoutError
    when ``deadline`` (a ``time.perf_counter()`` value) passes."""
    height = len(grid)
    width = len(grid[0])
    gx, gy = goal
    g = {start: 0}
    parent: dict[tuple[int, int], tuple[int, int] | None] = {start: None}
    open_list: list[tuple[int, int, int, tuple[int, int]]] = []
    pushed = 0
    closed: set[tuple[int, int]] = set()
    current = start
    count = 0
    while True:
        closed.add(current)
        if current == goal:
            break
        cx, cy = current
        for dx, dy in NEIGHBOURS:
            nx, ny = cx + dx, cy + dy
            if not (0 <= nx < width and 0 <= ny < height):
                continue
            node = (nx, ny)
            if grid[ny][nx] == 1 or node in closed:
                continue
            new_g = g[current] + STEP
            if node not in g or new_g < g[node]:
                g[node] = new_g
                parent[node] = current
                h = (abs(gx - nx) + abs(gy - ny)) * STEP
                pushed += 1
                heapq.heappush(open_list, (new_g + h, h, pushed, node))
        # Take the lowest F from OPEN, skipping entries of nodes already closed.
        while open_list and open_list[0][3] in closed:
            heapq.heappop(open_list)
        if not open_list:
            return None
        current = heapq.heappop(open_list)[3]
        count += 1
        if deadline is not None and count % 4096 == 0 and time.perf_counter() > deadline:
            raise TimeoutError
    path = []
    node: tuple[int, int] | None = goal
    while node is not None:
        path.append(node)
        node = parent[node]
    return path[::-1]
