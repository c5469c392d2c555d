"""Which poses a robot could have reached: the check behind every pose the match believes.

A robot host (the organiser's process) reports where each robot is; the overhead camera reports
where it sees each marker. Neither claim is taken on trust: a pose is *plausible* when it lies in
the arena, not inside a wall (beyond what the position's uncertainty explains), and no farther
from the last accepted pose than the robot can drive in the time between.

"Can drive" is a budget, as in a token bucket: it fills at the robot's top speed while time passes,
up to :data:`LAG` seconds' worth plus :data:`SLACK` cells (reports that arrive late, in a burst,
and position corrections of dead reckoning). Poses are measured from an *anchor*, an accepted
pose that stands for :data:`WINDOW` seconds: a pose is plausible when it lies within the budget,
plus the noise of both positions (3 sigma each), of the anchor. When the window has passed, the
next accepted pose becomes the anchor and the budget is charged with the distance between the two
anchors less that noise. Noise is forgiven once a window, not once a report, so a host that
reports ten times a second pays nothing for jitter and gains at most 6 sigma a window by lying:
over any stretch of time a robot's anchors move at most ``speed * t + capacity`` cells plus that,
however the claims are timed: a teleport is refused whether it comes in one report or in many
small ones. Each hop from the pose taken last is charged too (from a second bucket of the same
size), beyond the noise of its two ends: poses that hop about within a window, each near the
anchor and far from the one before, cost the driving between them, so no pose is taken that the
robot could not have driven to from the one before (a true path is never shorter than the hops'
lengths less the noise of their ends, so an honest robot is never charged more than it drove).

Coordinates are in cells; cell ``(cx, cy)`` holds the points with ``floor(x + 0.5) == cx`` (the
arena's convention), so the arena spans ``-0.5 <= x < width - 0.5``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

#: Seconds of driving the budget may hold: reports delayed or bunched this long are still taken.
LAG = 3.0
#: Cells the budget holds beyond that: a positioning fix that corrects dead reckoning may jump.
SLACK = 1.5
#: Sigma above this many cells counts as this many: a host cannot widen every check by claiming
#: a huge uncertainty.
MAX_SIGMA = 0.5
#: Seconds an anchor stands before the next accepted pose replaces it (and the budget is charged).
WINDOW = 1.0
#: Cells a host's claimed position (of a picture, a bump) may differ from the tracked one beyond
#: 3 sigma and what the robot can have driven since it was tracked.
CLAIM_SLACK = 0.5
#: How far into a wall cell a pose may lie (cells, beyond 2 sigma): a noisy estimate near a wall.
WALL_SLACK = 0.3
#: Half the side of the square inside a circle of radius 1, a hair under: the square's corners stay
#: inside the circle after rounding.
SQRT_HALF = math.sqrt(0.5) * (1.0 - 1e-9)
#: A :attr:`Track.box` that takes no pose (empty in both directions).
NO_BOX = (0.0, 0.0, -1.0, 0.0, -1.0)


@dataclass(slots=True)
class Verdict:
    """Why a pose was refused (``ok`` False), or that it was taken."""

    ok: bool
    reason: str = ""


@dataclass(slots=True)
class Track:
    """One robot's standing with a :class:`PoseGate`: its top speed and the budget's capacity at
    that speed, its anchor (``x``, ``y``, ``noise`` = 3 sigma capped, taken at ``t``; ``t`` 0 = not
    placed yet) and the driving budget left at ``t``. The core keeps one per robot, a robot host one
    per robot for its camera's fixes; :meth:`PoseGate.admit` is the one rule both follow."""

    speed: float = 0.0
    cap: float = 0.0
    t: float = 0.0
    x: float = 0.0
    y: float = 0.0
    noise: float = 0.0
    budget: float = 0.0
    #: Where a pose is taken without asking more, ``(until, x_lo, x_hi, y_lo, y_hi)``: before the
    #: anchor's window ends, in the square inside the circle the robot can reach from its anchor (its
    #: budget there plus its noise, clear of the nearest wall or edge). A hot path's test is one
    #: unpacking and chained comparisons; anything else asks :meth:`PoseGate.admit`. Not placed: an
    #: empty box.
    box: tuple[float, float, float, float, float] = NO_BOX
    #: The pose taken last and the driving left since it, ``(x, y, noise, left)`` (noise = 3 sigma
    #: capped): each hop from one taken pose to the next is charged beyond the noise of both ends, so
    #: that poses that hop about within the anchor's window (each near the anchor, far from each
    #: other) cost what driving between them would. ``left`` was refilled last at :attr:`hop_t`.
    hop: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    hop_t: float = 0.0


class PoseGate:
    """The plausibility check for one arena: ``walls`` (h, w) bool, ``speed`` the fastest any robot
    may drive (cells/s, already multiplied by the fastest surface zone)."""

    def __init__(self, walls: np.ndarray, speed: float, *, lag: float = LAG, slack: float = SLACK) -> None:
        self.height, self.width = (int(v) for v in walls.shape)
        self.walls = np.asarray(walls, dtype=bool)
        #: Row-major wall flags as bytes: one index per check on the hot path, no numpy call.
        self.wall_bytes = self.walls.astype(np.uint8).tobytes()
        self.speed = float(speed)
        self.lag = float(lag)
        self.slack = float(slack)
        #: Per cell, how far any point of it is from every wall cell and the arena's edge (cells, at
        #: least): the distance between cell centres, less one cell's diagonal.
        free = np.pad(~self.walls, 1, constant_values=False).astype(np.uint8)
        centre = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)[1:-1, 1:-1]
        self.clearance = np.maximum(0.0, centre - math.sqrt(2.0))

    def capacity(self, speed: float) -> float:
        """The most a robot of top speed ``speed`` may move in one burst (cells)."""
        return speed * self.lag + self.slack

    def where(self, x: float, y: float, sigma: float = 0.0) -> Verdict:
        """Whether ``(x, y)`` is a place a robot can be: in the arena, and not deeper inside a
        wall than ``WALL_SLACK + 2 sigma``."""
        sigma = min(sigma, MAX_SIGMA)
        if not (math.isfinite(x) and math.isfinite(y)):
            return Verdict(False, "the position is not a finite number")
        if not (-0.5 <= x < self.width - 0.5 and -0.5 <= y < self.height - 0.5):
            return Verdict(False, f"({x:.2f}, {y:.2f}) is outside the {self.width}×{self.height} arena")
        cx, cy = math.floor(x + 0.5), math.floor(y + 0.5)
        if self.wall_bytes[cy * self.width + cx]:
            depth = self._depth_in_wall(x, y, WALL_SLACK + 2.0 * sigma + 1.0)
            if depth > WALL_SLACK + 2.0 * sigma:
                return Verdict(False, f"({x:.2f}, {y:.2f}) is inside the wall at cell ({cx}, {cy})")
        return Verdict(True)

    def step(self, anchor: tuple[float, float, float], budget: float, x: float, y: float, sigma: float,
             speed: float) -> tuple[Verdict, float]:
        """Whether a robot anchored at ``anchor`` (x, y, sigma) with ``budget`` cells of driving (already
        refilled for the time since the anchor) can be at ``(x, y)`` with uncertainty ``sigma`` now;
        returns the verdict and the budget left if this pose becomes the next anchor (unchanged when
        refused)."""
        x0, y0, sigma0 = anchor
        sigma, sigma0 = min(sigma, MAX_SIGMA), min(sigma0, MAX_SIGMA)
        here = self.where(x, y, sigma)
        if not here.ok:
            return here, budget
        d = math.hypot(x - x0, y - y0)
        noise = 3.0 * (sigma + sigma0)
        if d > budget + noise:
            return Verdict(False, f"a jump of {d:.1f} cells from ({x0:.2f}, {y0:.2f}) to ({x:.2f}, {y:.2f}); "
                                  f"at {speed:g} cells/s it could have driven {budget + noise:.1f}"), budget
        return Verdict(True), max(0.0, budget - max(0.0, d - noise))

    def track(self, speed: float) -> Track:
        """A new robot's track at top speed ``speed`` (not placed yet)."""
        return Track(speed=speed, cap=self.capacity(speed))

    def admit(self, tr: Track, x: float, y: float, sigma: float, now: float, away: bool = False) -> Verdict:
        """Whether a robot on track ``tr`` can be at ``(x, y)`` (uncertainty ``sigma``) at time
        ``now``; an admitted pose updates the track. Two tests, both from the driving budget: from
        the anchor (the pose's net distance beyond the noise of both; when the anchor's
        :data:`WINDOW` has passed, the pose taken last becomes the anchor first, so that a robot
        admitted far from its anchor is not measured from there for good), and from the pose taken
        last (the hop beyond the noise of both, charged). A robot not placed yet may be anywhere a
        robot can be; ``away``: it was away (a reconnect), so it may have driven all the time since,
        not only the budget's capacity."""
        if not tr.t:
            here = self.where(x, y, sigma)
            if here.ok:
                cap = self.capacity(tr.speed)
                self.anchor(tr, x, y, sigma, cap, now)
                tr.hop, tr.hop_t = (x, y, tr.noise, cap), now
            return here
        lx, ly, lnoise, left = tr.hop
        if now - tr.t >= WINDOW and (lx, ly) != (tr.x, tr.y):
            _, kept = self.step((tr.x, tr.y, tr.noise / 3.0), self.refill(tr.budget, now - tr.t, tr.speed),
                                lx, ly, lnoise / 3.0, tr.speed)
            self.anchor(tr, lx, ly, lnoise / 3.0, kept, now)
        budget = self.refill(tr.budget, now - tr.t, tr.speed)
        left = self.refill(left, now - tr.hop_t, tr.speed)
        if away:
            budget = max(budget, tr.speed * (now - tr.t))
            left = max(left, tr.speed * (now - tr.hop_t))
        verdict, kept = self.step((tr.x, tr.y, tr.noise / 3.0), budget, x, y, sigma, tr.speed)
        if not verdict.ok:
            return verdict
        noise = 3.0 * min(sigma, MAX_SIGMA)
        hop = math.hypot(x - lx, y - ly) - lnoise - noise
        if hop > left:
            return Verdict(False, f"a hop of {hop + lnoise + noise:.1f} cells from the pose taken last ({lx:.2f}, "
                                  f"{ly:.2f}) to ({x:.2f}, {y:.2f}); at {tr.speed:g} cells/s it could have "
                                  f"driven {left + lnoise + noise:.1f}")
        tr.hop, tr.hop_t = (x, y, noise, left - max(0.0, hop)), now
        if now - tr.t >= WINDOW:  # the anchor's window has passed: this pose is the next
            self.anchor(tr, x, y, sigma, kept, now)
        return verdict

    def anchor(self, tr: Track, x: float, y: float, sigma: float, budget: float, now: float) -> None:
        """Make ``(x, y)`` (an admitted pose) the anchor of ``tr`` at ``now`` with ``budget`` left."""
        tr.x, tr.y, tr.noise, tr.budget, tr.t = x, y, 3.0 * min(sigma, MAX_SIGMA), budget, now
        clear = float(self.clearance[min(self.height - 1, max(0, math.floor(y + 0.5))),
                                     min(self.width - 1, max(0, math.floor(x + 0.5)))])
        half = min(clear, budget + tr.noise) * SQRT_HALF  # the square inside the reachable circle
        # at or by a wall (no clearance) every pose asks admit: even the anchor's own place may be
        # refused there with a smaller sigma
        tr.box = (now + WINDOW, x - half, x + half, y - half, y + half) if half > 0.0 else NO_BOX

    def bears_out(self, tracked: tuple[float, float], sigma: float, since: float, speed: float,
                  claim: tuple[float, float]) -> Verdict:
        """Whether a claimed position agrees with the tracked one: no farther from it than the
        tracking's uncertainty (3 sigma + :data:`CLAIM_SLACK`) plus what the robot can have driven in
        the ``since`` seconds since it was tracked there."""
        sigma = min(sigma, MAX_SIGMA)
        d = math.hypot(claim[0] - tracked[0], claim[1] - tracked[1])
        allowed = 3.0 * sigma + CLAIM_SLACK + speed * max(0.0, min(since, self.lag))
        if d > allowed or not self.where(*claim, sigma=sigma).ok:
            return Verdict(False, f"claimed at ({claim[0]:.2f}, {claim[1]:.2f}), {d:.1f} cells from where the robot "
                                  f"is tracked ({tracked[0]:.2f}, {tracked[1]:.2f}; {allowed:.1f} allowed)")
        return Verdict(True)

    def refill(self, budget: float, dt: float, speed: float) -> float:
        """The budget after ``dt`` seconds at top speed ``speed`` (capped at :meth:`capacity`)."""
        return min(self.capacity(speed), budget + max(0.0, dt) * speed)

    def _depth_in_wall(self, x: float, y: float, reach: float) -> float:
        """The distance from ``(x, y)`` to the nearest free cell's square (at most ``reach`` cells
        are searched; ``reach`` is returned when none is that close)."""
        r = int(math.ceil(reach)) + 1
        cx, cy = math.floor(x + 0.5), math.floor(y + 0.5)
        best = reach
        for gy in range(max(0, cy - r), min(self.height, cy + r + 1)):
            for gx in range(max(0, cx - r), min(self.width, cx + r + 1)):
                if self.walls[gy, gx]:
                    continue
                dx = max(gx - 0.5 - x, 0.0, x - (gx + 0.5))
                dy = max(gy - 0.5 - y, 0.0, y - (gy + 0.5))
                best = min(best, math.hypot(dx, dy))
        return best


__all__ = ["CLAIM_SLACK", "LAG", "MAX_SIGMA", "WINDOW", "Track", "PoseGate", "SLACK", "Verdict", "WALL_SLACK"]
