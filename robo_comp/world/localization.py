"""Localization: a simulated tracking positioning system, ``.xyz`` records and dead reckoning.

The thesis planned a Hexamite HX5 ultrasonic system in *tracking* mode: tags on the
robots, monitors in the roof, and a program (``xyz.exe``) writing each fix -- tag id,
position and time -- to a ``.xyz`` file (sections 2.2.2, 3.6). It never worked, so the
robots dead-reckoned ("walking blindfolded") and were given positions on request.

Here :class:`PositioningSystem` produces periodic noisy fixes with dropouts from the
arena's ground truth, :func:`format_xyz`/:func:`parse_xyz` write and read the line
format, :class:`DeadReckoner` integrates a robot's odometry with drift and corrects on
each fix, and :class:`Localization` runs both for every robot of an :class:`Arena`.
Ground truth stays in the arena; robots and teams only see the estimates.

``.xyz`` line format (one fix per line, whitespace separated, ``#`` starts a comment)::

    <tag> <x> <y> <z> <time>
    r1 12.431 8.102 0.000 15.250

positions in map cells (cell centres at integers), time in seconds of match time.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import IO, TYPE_CHECKING, Iterable, Sequence

import numpy as np

from robo_comp.errors import ScenarioError
from robo_comp.world.scenario import Drift, Positioning

if TYPE_CHECKING:  # for the annotation only (the caller brings the arena)
    from robo_comp.world.arena import Arena

__all__ = ["Fix", "format_xyz", "parse_xyz_line", "parse_xyz", "write_xyz", "read_xyz",
           "PositioningSystem", "DeadReckoner", "Localization"]


@dataclass(frozen=True)
class Fix:
    """One position fix of the positioning system: tag id, position (cells), time (s)."""

    tag: str
    x: float
    y: float
    z: float
    time: float

    def to_dict(self) -> dict[str, float | str]:
        """Plain-data form."""
        return {"tag": self.tag, "x": self.x, "y": self.y, "z": self.z, "time": self.time}


# ------------------------------------------------------------------ .xyz records


def format_xyz(fix: Fix, precision: int = 3) -> str:
    """One ``.xyz`` line (without newline) for ``fix``."""
    if not fix.tag or any(c.isspace() for c in fix.tag) or fix.tag.startswith("#"):
        raise ValueError(f"tag {fix.tag!r} cannot be written to an .xyz line")
    p = precision
    return f"{fix.tag} {fix.x:.{p}f} {fix.y:.{p}f} {fix.z:.{p}f} {fix.time:.{p}f}"


def parse_xyz_line(line: str, source: str = "<xyz>", lineno: int = 1) -> Fix | None:
    """Parse one ``.xyz`` line; ``None`` for blank and comment lines. Raises
    ScenarioError naming ``source`` and ``lineno`` for a malformed line."""
    text = line.split("#", 1)[0].strip()
    if not text:
        return None
    parts = text.split()
    if len(parts) != 5:
        raise ScenarioError(f"{source} line {lineno}: expected 'tag x y z time', got {len(parts)} fields")
    try:
        x, y, z, t = (float(p) for p in parts[1:])
    except ValueError:
        raise ScenarioError(f"{source} line {lineno}: x, y, z and time must be numbers") from None
    if not all(map(math.isfinite, (x, y, z, t))):
        raise ScenarioError(f"{source} line {lineno}: x, y, z and time must be finite")
    return Fix(parts[0], x, y, z, t)


def parse_xyz(text: str, source: str = "<xyz>") -> list[Fix]:
    """All fixes in ``.xyz`` text, in file order."""
    out = []
    for no, line in enumerate(text.splitlines(), start=1):
        f = parse_xyz_line(line, source, no)
        if f is not None:
            out.append(f)
    return out


def write_xyz(fixes: Iterable[Fix], fp: IO[str], precision: int = 3) -> int:
    """Append ``fixes`` to text file ``fp`` as ``.xyz`` lines; returns how many."""
    n = 0
    for f in fixes:
        fp.write(format_xyz(f, precision) + "\n")
        n += 1
    return n


def read_xyz(path: str) -> list[Fix]:
    """Read an ``.xyz`` file (ScenarioError if unreadable or malformed)."""
    try:
        with open(path, encoding="utf-8") as fp:
            text = fp.read()
    except (OSError, UnicodeDecodeError) as e:
        raise ScenarioError(f"{path}: cannot read .xyz file: {e}") from None
    return parse_xyz(text, str(path))


# ------------------------------------------------------------ positioning system


class PositioningSystem:
    """Simulated HX5-style tracking: every robot gets a fix every ``1/rate`` s (phase
    staggered per tag) with Gaussian noise of σ ``noise`` cells per axis; each due fix is
    lost with probability ``dropout``."""

    def __init__(self, cfg: Positioning | None = None, rng: np.random.Generator | None = None,
                 *, z: float = 0.0) -> None:
        self.cfg = cfg or Positioning()
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.z = z
        self.period = 1.0 / self.cfg.rate
        self._due: dict[str, float] = {}
        self.sent = 0
        self.dropped = 0

    def forget(self, tag: str) -> None:
        """Stop tracking ``tag`` (the robot left)."""
        self._due.pop(tag, None)

    def poll(self, now: float, tags: Sequence[str], x: Sequence[float] | np.ndarray,
             y: Sequence[float] | np.ndarray) -> list[Fix]:
        """Fixes due at time ``now`` for robots ``tags`` at true positions ``x``, ``y``."""
        n = len(tags)
        if n == 0:
            return []
        due = np.empty(n)
        for i, t in enumerate(tags):
            d = self._due.get(t)
            if d is None:
                d = now + float(self.rng.uniform(0.0, self.period))
                self._due[t] = d
            due[i] = d
        ready = np.flatnonzero(due <= now + 1e-12)
        if ready.size == 0:
            return []
        lost = self.rng.random(ready.size) < self.cfg.dropout
        noise = self.rng.normal(0.0, self.cfg.noise, (ready.size, 2)) if self.cfg.noise > 0 else np.zeros((ready.size, 2))
        xa = np.asarray(x, dtype=np.float64)
        ya = np.asarray(y, dtype=np.float64)
        out: list[Fix] = []
        for k, i in enumerate(ready.tolist()):
            t = tags[i]
            nxt = due[i] + self.period
            self._due[t] = nxt if nxt > now else now + self.period
            if lost[k]:
                self.dropped += 1
                continue
            self.sent += 1
            out.append(Fix(t, float(xa[i] + noise[k, 0]), float(ya[i] + noise[k, 1]), self.z, float(now)))
        return out


# ------------------------------------------------------------------ dead reckoning


#: A fix farther from the estimate than this many σ of both (chi-square, 2 degrees of freedom,
#: 99.7 %) means the estimate is wrong beyond what it believed (a wheel slipped, a turn was
#: stopped half-way): its variance is raised to what the fix says, so the fix weighs.
GATE = 11.8
#: Fixes in a row beyond :data:`GATE` after which the estimate, not the fixes, is taken to be wrong
#: (a single one is left out as the positioning system's own error).
DOUBTS = 2
#: The least position uncertainty (σ, cells) an estimate has when a fix comes: wheels slip, a
#: robot is nudged; without it an estimate that believes itself exact stops listening to fixes. It is
#: at least FLOOR_SHARE of the fixes' own noise: a filter that listens too little to noisy fixes lags
#: behind a robot whose heading is a little off (measured: bench/bench_teamwork.py --end-error).
POSE_FLOOR = 0.1
FLOOR_SHARE = 0.5
#: Cells the positioning system's fixes must have moved (at the least; more with noisier fixes:
#: :meth:`DeadReckoner.track_base`) before their track says which way the robot really drives.
TRACK_BASE = 2.0


class DeadReckoner:
    """A robot's own pose estimate: odometry with drift between fixes, corrected on a fix.

    :meth:`advance` integrates a measured turn and distance; the estimate deviates from
    the truth by the ``drift`` errors (distance scale error, heading error per turn and
    per cell). :meth:`correct` blends a fix in with a scalar Kalman gain from the
    estimate's variance and the fix noise ``fix_noise`` (σ, cells): with exact fixes the
    estimate jumps to the fix.

    The heading is corrected too: by a camera's fix, which measures it; by fixes that measure a
    position only (the HX5's) through their track: between two fixes at least
    :meth:`track_base` cells apart, the way the fixes moved and the way the estimate moved (by
    odometry alone) differ by the heading's error, weighed against the heading's own variance
    (``hvar``, degrees², which grows with turning and driving, and jumps when a movement was
    stopped half-way: :meth:`interrupted`). A fix beyond :data:`GATE` is left out unless the next
    one is too (:data:`DOUBTS`): then the estimate is wrong and its variance is raised to match.
    """

    def __init__(self, x: float, y: float, heading: float, drift: Drift | None = None,
                 rng: np.random.Generator | None = None, *, fix_noise: float = 0.25,
                 time: float = 0.0) -> None:
        self.x, self.y, self.heading = float(x), float(y), float(heading) % 360.0
        self.drift = drift or Drift()
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.fix_noise = float(fix_noise)
        self.var = 0.0                  # position variance (cells²) of the estimate
        self.hvar = 0.0                 # heading variance (degrees²) of the estimate
        self.last_fix: float | None = None
        self.time = time
        # the fix the next fix's track is measured from, and the way odometry moved the estimate since
        self.anchor: tuple[float, float] | None = None
        self.odo_x = self.odo_y = 0.0
        self.doubts = 0  # fixes in a row beyond GATE
        self.heading_doubts = 0  # tracks in a row beyond 3σ of the heading's and the bearing's noise

    def pose(self) -> tuple[float, float, float]:
        """The estimated (x, y, heading)."""
        return self.x, self.y, self.heading

    @property
    def sigma(self) -> float:
        """Estimated position uncertainty σ in cells."""
        return math.sqrt(self.var)

    def advance(self, distance: float, turn: float = 0.0) -> None:
        """Apply a measured turn (degrees, first) then a straight move (cells, signed)."""
        d = self.drift
        if turn:
            self.heading += turn + self.rng.normal(0.0, d.heading * abs(turn) / 90.0) if d.heading else turn
            self.hvar += (d.heading * abs(turn) / 90.0) ** 2
        if distance:
            self.hvar += d.heading_per_cell ** 2 * abs(distance)
            if d.heading_per_cell:
                self.heading += self.rng.normal(0.0, d.heading_per_cell * math.sqrt(abs(distance)))
            scale = 1.0 + (self.rng.normal(0.0, d.distance) if d.distance else 0.0)
            dist = distance * scale
            hr = math.radians(self.heading)
            self.x += dist * math.cos(hr)
            self.y += dist * math.sin(hr)
            self.odo_x += dist * math.cos(hr)
            self.odo_y += dist * math.sin(hr)
            # sideways, a heading that is off by its σ moves the robot by that much of the distance
            lateral = abs(distance) * math.radians(d.heading_per_cell + d.heading + math.sqrt(self.hvar))
            self.var += (d.distance * distance) ** 2 + lateral ** 2
        self.heading %= 360.0

    def correct(self, fix: Fix, gain: float | None = None, heading: float | None = None) -> None:
        """Move the estimate toward ``fix``: by ``gain`` (0..1) if given, else by the
        Kalman gain ``var / (var + fix_noise²)``; a fix that measured the ``heading`` too (a
        camera) turns the estimate toward it by the same gain."""
        r2 = self.fix_noise ** 2
        if gain is None:  # a robot's pose is never known better than this between two fixes
            self.var = max(self.var, max(POSE_FLOOR, FLOOR_SHARE * self.fix_noise) ** 2)
        miss = (fix.x - self.x) ** 2 + (fix.y - self.y) ** 2
        if gain is None and miss > GATE * (self.var + r2):
            self.doubts += 1
            if self.doubts < DOUBTS:  # one fix that far off is more likely the fix's error: left out
                return
            self.var = max(self.var, miss - r2)  # fixes keep saying so: the estimate is off
        self.doubts = 0
        if gain is None:
            gain = 1.0 if r2 == 0 else self.var / (self.var + r2)
        g = min(max(float(gain), 0.0), 1.0)
        if heading is None:
            self._track_heading(fix)
        self.x += g * (fix.x - self.x)
        self.y += g * (fix.y - self.y)
        if heading is not None:
            self.heading = (self.heading + g * ((heading - self.heading + 180.0) % 360.0 - 180.0)) % 360.0
            self.hvar = (1.0 - g) * self.hvar
        # Posterior variance of a blend with weight g: (1-g)² var + g² r².
        self.var = (1.0 - g) ** 2 * self.var + g * g * r2
        self.last_fix = fix.time
        if self.anchor is None:
            self.anchor = (fix.x, fix.y)
            self.odo_x = self.odo_y = 0.0

    def track_base(self) -> float:
        """Cells between two fixes before their track corrects the heading: :data:`TRACK_BASE`, more
        for noisier fixes (the bearing between two fixes is then known to about 10°)."""
        return max(TRACK_BASE, 8.0 * self.fix_noise)

    def _track_heading(self, fix: Fix) -> None:
        """Correct the heading from the way the fixes moved against the way the estimate moved."""
        a = self.anchor
        if a is None:
            return
        fdx, fdy = fix.x - a[0], fix.y - a[1]
        edx, edy = self.odo_x, self.odo_y
        moved = math.hypot(edx, edy)
        base = self.track_base()
        if moved < base or math.hypot(fdx, fdy) < base / 2:
            return
        err = (math.degrees(math.atan2(fdy, fdx) - math.atan2(edy, edx)) + 180.0) % 360.0 - 180.0
        r2 = math.degrees(math.sqrt(2.0) * self.fix_noise / moved) ** 2  # the bearing's noise, degrees²
        self.anchor = None  # the next track starts at this fix
        if err * err > 9.0 * (self.hvar + r2):
            self.heading_doubts += 1
            if self.heading_doubts < DOUBTS:  # one track that far off is more likely the fixes' noise
                return
            self.hvar = max(self.hvar, err * err - r2)  # tracks keep saying so: the heading is off
        self.heading_doubts = 0
        g = self.hvar / (self.hvar + r2) if self.hvar + r2 > 0 else 0.0
        self.heading = (self.heading + g * err) % 360.0
        self.hvar = (1.0 - g) * self.hvar

    def interrupted(self, turn: float = 45.0, distance: float = 0.5, grid: bool = False) -> None:
        """A movement was stopped half-way: how far the robot turned (up to ``turn`` degrees) and
        drove (up to ``distance`` cells) is not known: the variances grow by as much (uniform). A
        ``grid`` robot (the ER1 way: it stands only facing along the grid, and settles there when
        stopped) takes the grid's nearest heading instead."""
        if grid:
            self.heading = (round(self.heading / 90.0) * 90.0) % 360.0
        else:
            self.hvar += turn * turn / 3.0
        self.var += distance * distance / 3.0

    def reset(self, x: float, y: float, heading: float | None = None) -> None:
        """Set the estimate to a known pose (e.g. given by the referee)."""
        self.x, self.y = float(x), float(y)
        if heading is not None:
            self.heading = float(heading) % 360.0
        self.var = 0.0


#: Fixes in a row beyond :data:`GATE` after which the estimate, not the fixes, is taken to be wrong
#: (a single one is left out as the positioning system's own error).
DOUBTS = 2
#: The least position uncertainty (σ, cells) a robot's estimate has when a camera fix comes.
CAMERA_PRIOR = 0.1


class Localization:
    """Runs the positioning system over an arena and keeps every robot's estimate.

    Call :meth:`update` after each :meth:`Arena.step`: it feeds each robot's odometry
    to its :class:`DeadReckoner`, polls the positioning system and corrects the
    estimates with the fixes it returns (write those to the ``.xyz`` log with
    :func:`write_xyz` and report the estimates to the map service).
    """

    def __init__(self, arena: Arena, positioning: Positioning | None = None,
                 drift: Drift | None = None, rng: np.random.Generator | None = None, *,
                 external: bool = False) -> None:
        """``external``: fixes come from a real positioning system (:meth:`camera_fix`), not from
        the simulated one."""
        self.external = external
        self.arena = arena
        sc = arena.scenario
        self.positioning_cfg = positioning or sc.positioning
        self.drift = drift or sc.drift
        self.rng = rng if rng is not None else np.random.default_rng([sc.seed, 0x10C])
        self.system = PositioningSystem(self.positioning_cfg, self.rng)
        self.reckoners: dict[str, DeadReckoner] = {}

    def _reckoner(self, tag: str) -> DeadReckoner:
        r = self.reckoners.get(tag)
        if r is None:
            p = self.arena.pose(tag)
            self.arena.odometry(tag, reset=True)
            r = DeadReckoner(p.x, p.y, p.heading, self.drift, self.rng,
                             fix_noise=self.positioning_cfg.noise, time=self.arena.time)
            self.reckoners[tag] = r
        return r

    def update(self) -> list[Fix]:
        """Advance every estimate by odometry, then correct with the fixes now due.

        Vectorised over the arena's arrays: only the robots that drove or turned since the
        last update advance their estimate (a robot standing still has nothing to add)."""
        arena = self.arena
        tags = [t for t in arena.tags if t not in arena.placed] if arena.placed else arena.tags
        if len(self.reckoners) != len(tags) or not all(t in self.reckoners for t in tags):
            for gone in set(self.reckoners) - set(tags):
                del self.reckoners[gone]
                self.system.forget(gone)
            for t in tags:
                self._reckoner(t)
        slots = arena.slots(tags)
        dist, turn = arena.take_odometry(slots)
        moved = np.flatnonzero((dist != 0.0) | (turn != 0.0))
        if moved.size:
            reckoners = self.reckoners
            now = arena.time
            for i, d, a in zip(moved.tolist(), dist[moved].tolist(), turn[moved].tolist()):
                r = reckoners[tags[i]]
                r.advance(d, a)
                r.time = now
        if self.external:
            return []
        fixes = self.system.poll(arena.time, tags, arena.x[slots], arena.y[slots])
        for f in fixes:
            self.reckoners[f.tag].correct(f)
        return fixes

    def camera_fix(self, tag: str, x: float, y: float, heading: float, sigma: float, time: float) -> None:
        """Correct robot ``tag``'s estimate with a fix of an overhead camera: position and heading,
        with the camera's uncertainty ``sigma`` (cells) as the fix noise."""
        if tag not in self.reckoners and tag not in self.arena.tags:
            return
        r = self._reckoner(tag)
        r.fix_noise = max(float(sigma), 0.01)
        # between two frames a robot's pose is never known better than this (wheels slip, it is
        # lifted and put down): a camera's fix always weighs, even on a robot standing still
        r.var = max(r.var, CAMERA_PRIOR ** 2)
        r.correct(Fix(tag, x, y, 0.0, time), heading=heading)

    def settled(self, tag: str) -> None:
        """Robot ``tag`` finished a step. A grid4 robot (the ER1 way: it turns only by quarters)
        stands facing along the grid then, and knows it: its estimate's heading takes the grid's
        nearest (its turns' small errors do not add up into a heading that drifts sideways)."""
        if self.arena.drive == "grid4" and (tag in self.reckoners or tag in self.arena.tags):
            rk = self._reckoner(tag)
            dist, turn = self.arena.odometry(tag, reset=True)  # what it drove since the last update first
            if dist or turn:
                rk.advance(dist, turn)
            rk.heading = (round(rk.heading / 90.0) * 90.0) % 360.0

    def interrupted(self, tag: str) -> None:
        """Robot ``tag``'s movement was stopped half-way (a stop, a bump). On a grid4 arena the robot
        settles back on the grid, which its wheels do not measure: its estimate settles on the grid
        too and is less sure of its position (:meth:`DeadReckoner.interrupted`). A freely driving
        robot's wheels measured the part of the movement it made: nothing changes."""
        if tag in self.reckoners or tag in self.arena.tags:
            rk = self._reckoner(tag)
            dist, turn = self.arena.odometry(tag, reset=True)  # what it drove since the last update first
            if dist or turn:
                rk.advance(dist, turn)
            if self.arena.drive == "grid4":  # it settled back on the grid, unmeasured (a free robot's
                rk.interrupted(grid=True)      # wheels measured the part of the movement it made)

    def sigma(self, tag: str) -> float:
        """Robot ``tag``'s position uncertainty σ (cells): it grows while no fix comes."""
        r = self.reckoners.get(tag)
        return r.sigma if r is not None else 0.0

    def estimate(self, tag: str) -> tuple[float, float, float]:
        """The estimated (x, y, heading) of ``tag`` -- what its team sees."""
        return self._reckoner(tag).pose()

    def estimates(self) -> dict[str, tuple[float, float, float]]:
        """Estimated poses of all robots by tag."""
        return {t: self._reckoner(t).pose() for t in self.arena.tags if t not in self.arena.placed}
