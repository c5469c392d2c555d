"""The ROS 2 driver: a robot that speaks ROS 2, driven over DDS without ROS installed.

One :class:`ROS2Driver` per robot, all of a host on one :class:`~robo_comp.robots.ros2.bus.Bus`.
The robot's ROS 2 namespace ``ns`` names its topics: the driver publishes
``geometry_msgs/Twist`` on ``/ns/cmd_vel`` and reads ``nav_msgs/Odometry`` from ``/ns/odom``
and ``sensor_msgs/LaserScan`` from ``/ns/scan``.

Frames. The arena's pose is in cells, heading in degrees with 0 = +x and 90 = +y (y pointing
down the map, so a positive heading change is clockwise on the map); ROS's odometry is in
metres in the ``odom`` frame, yaw counter-clockwise. The first odometry message anchors the
robot's start pose (``x``, ``y``, ``heading`` given by the host): what odometry says the robot
moved since, forward and to its left, is added to it (1 cell = ``cell_m`` metres), and a
counter-clockwise yaw turns the arena heading the other way (ROS's "left" is the arena's
``heading - 90``).

Steps. ``Move(x, y)`` turns on the spot towards the cell's centre, then drives to it with
proportional control on distance and heading, and there turns to face the way from its cell to
that one if it is more than ``FACE_SLACK`` degrees off (a grid robot's heading, so a path's end
heading is known); ``Turn`` turns until the heading is reached; both republish the command on every :meth:`update` (the host's tick) and end with a zero ``Twist``.
``halt`` publishes a zero ``Twist`` at once; so does ``pause`` (the host lost the core), which
keeps the step to resume it. A watchdog thread publishes a zero ``Twist`` for a robot that was
commanded to move but whose driver has not been updated for ``DEADMAN`` seconds (a paused match,
a stalled host). A step that gets no odometry for ``ODOM_TIMEOUT`` seconds fails like a bump.

Range. :meth:`readings` gives the front, left and right ranges of the latest scan in cm (the
rays nearest 0°, +90° and −90°), in the shape of the simulated sensors' readings.
"""
from __future__ import annotations

import math
import threading
import time
import weakref
from typing import Any

from robo_comp.robots.drivers import PoseReadings
from robo_comp.robots.ros2.bus import Bus, topic_name
from robo_comp.robots.ros2.msgs import LaserScan, Odometry, Twist, Vector3, yaw_of
from robo_comp.robots.steps import Move, Step, Turn

#: Seconds without an update after which a moving robot is sent a zero Twist by the watchdog.
DEADMAN = 0.5
#: Seconds a Move or Turn waits for odometry before it fails.
ODOM_TIMEOUT = 5.0
#: A Move is done within this many cells of the target, a Turn within this many degrees.
POS_TOLERANCE = 0.06
HEADING_TOLERANCE = 2.0
#: How far a camera fix moves the odometry pose towards it (a fix is noisy; odometry is smooth).
CAMERA_GAIN = 0.3
#: A Move that arrives within this many degrees of its direction does not turn to face it.
FACE_SLACK = 5.0
#: Within this many cells of the target a Move no longer turns on the spot towards it.
CLOSE = 0.2
#: Above this heading error (degrees) a Move turns on the spot before it drives.
TURN_FIRST = 20.0


def _wrap(deg: float) -> float:
    """An angle in degrees folded into [-180, 180)."""
    return (deg + 180.0) % 360.0 - 180.0


class ROS2Driver(PoseReadings):
    """One ROS 2 robot (same interface as :class:`robo_comp.robots.drivers.ArenaDriver`)."""

    #: A real robot: the host keeps its arena body at :attr:`pose` (see :mod:`robo_comp.robots.oneworld`).
    external_body = True

    def __init__(self, bus: Bus, namespace: str, *, cell_m: float, x: float, y: float, heading: float = 0.0,
                 max_speed: float = 0.2, max_turn: float = 1.0) -> None:
        self.bus = bus
        self.namespace = namespace.strip("/")
        self.cell_m = float(cell_m)
        self.max_speed = float(max_speed)  # m/s
        self.max_turn = float(max_turn)  # rad/s
        self.start = (float(x), float(y), float(heading))
        self._pose = self.start
        self.step: Step | None = None
        self.bump: dict[str, Any] | None = None
        self._timer = 0.0
        self._anchor: tuple[float, float, float] | None = None  # the odometry (X, Y, yaw) at ``start``
        self._raw: tuple[float, float, float] | None = None  # the latest odometry
        self._target_heading = 0.0
        self._facing = False  # a Move is turning to its final heading
        self._waited = 0.0
        self._scan: LaserScan | None = None
        self.odom_count = 0
        self.scan_count = 0
        self._lock = threading.Lock()
        self._commanded = False  # the last published command was not zero
        self._last_update = time.monotonic()
        self.cmd = bus.writer(topic_name(self.namespace, "cmd_vel"), Twist)
        self.odom = bus.reader(topic_name(self.namespace, "odom"), Odometry)
        self.scan = bus.reader(topic_name(self.namespace, "scan"), LaserScan, depth=2)
        _Watchdog.watch(self)

    # ------------------------------------------------------------------ what the robot believes
    @property
    def pose(self) -> tuple[float, float, float]:
        """Odometry's pose in arena coordinates (cells, degrees)."""
        return self._pose

    def truth(self) -> tuple[float, float, float]:
        """A real robot's truth is not known here: the odometry pose."""
        return self._pose

    def readings(self) -> dict[str, float | None]:
        """Front, left and right range of the latest scan in cm (None: no echo in range or no
        scan yet); ``down`` is None (a ROS 2 robot's cliff sensors are not read)."""
        out: dict[str, float | None] = {"front": None, "left": None, "right": None, "down": None}
        s = self._scan
        if s is None or not s.ranges or s.angle_increment == 0:
            return out
        ranges: Any = s.ranges  # a list (Cyclone's sequence annotation is not one to mypy)
        n = len(ranges)
        for key, angle in (("front", 0.0), ("left", math.pi / 2), ("right", -math.pi / 2)):
            i = int(round(((angle - s.angle_min) % (2 * math.pi)) / s.angle_increment))
            if 0 <= i < n:
                r = float(ranges[i])
                if math.isfinite(r) and s.range_min <= r <= s.range_max:
                    out[key] = round(r * 100.0, 2)
        return out

    def _poll(self) -> None:
        """Take what odometry and scans arrived (never blocking)."""
        msgs = [m for m in self.odom.take(N=64) if isinstance(m, Odometry)]  # not a writer's disposal
        if msgs:
            m = msgs[-1]
            p = m.pose.pose
            X, Y, yaw = p.position.x, p.position.y, yaw_of(p.orientation)
            self._raw = (X, Y, yaw)
            if self._anchor is None:
                self._anchor = (X, Y, yaw)
            X0, Y0, yaw0 = self._anchor
            dX, dY = X - X0, Y - Y0
            fwd = math.cos(yaw0) * dX + math.sin(yaw0) * dY
            left = -math.sin(yaw0) * dX + math.cos(yaw0) * dY
            x0, y0, h0 = self.start
            h = math.radians(h0)
            x = x0 + (fwd * math.cos(h) + left * math.sin(h)) / self.cell_m
            y = y0 + (fwd * math.sin(h) - left * math.cos(h)) / self.cell_m
            self._pose = (x, y, (h0 - math.degrees(yaw - yaw0)) % 360.0)
            self.odom_count += len(msgs)
        scans = [m for m in self.scan.take(N=8) if isinstance(m, LaserScan)]
        if scans:
            self._scan = scans[-1]
            self.scan_count += len(scans)

    def camera_fix(self, x: float, y: float, heading: float) -> None:
        """A fix of the organiser's overhead camera: the pose moves :data:`CAMERA_GAIN` of the way
        to it (all of it before any odometry), and odometry counts on from there."""
        px, py, ph = self._pose
        g = 1.0 if self._raw is None else CAMERA_GAIN
        self.start = (px + g * (x - px), py + g * (y - py), (ph + g * _wrap(heading - ph)) % 360.0)
        self._pose = self.start
        self._anchor = self._raw  # None before odometry: the first odometry anchors the new start

    # ------------------------------------------------------------------ commands
    def _publish(self, v: float, w: float) -> None:
        with self._lock:
            self.cmd.write(Twist(linear=Vector3(x=v), angular=Vector3(z=w)))
            self._commanded = v != 0.0 or w != 0.0

    def _zero(self) -> None:
        self._publish(0.0, 0.0)

    def begin(self, step: Step) -> None:
        """Start ``step``."""
        self.step = step
        self.bump = None
        self._waited = 0.0
        self._facing = False
        self._last_update = time.monotonic()
        if isinstance(step, Turn):
            self._target_heading = (self._pose[2] + step.degrees) % 360.0
        elif isinstance(step, Move):  # it ends facing the way from its cell to the next, as a grid robot
            cx, cy = self.cell()
            self._target_heading = math.degrees(math.atan2(step.y - cy, step.x - cx)) % 360.0 \
                if (step.x, step.y) != (cx, cy) else self._pose[2]
        else:
            self._start_timer(step)

    def halt(self) -> None:
        """Stop at once: a zero Twist, no step."""
        self._zero()
        self.step = None

    def pause(self) -> None:
        """Stand still at once but keep the step (the host lost the core; it resumes on update)."""
        self._zero()

    def close(self) -> None:
        """Stop the robot and stop watching it."""
        self._zero()
        _Watchdog.forget(self)

    def update(self, dt: float) -> bool:
        """Read odometry and scans, command the robot; True when the step finished (or failed)."""
        self._last_update = time.monotonic()
        self._poll()
        step = self.step
        if step is None:
            return False
        if not isinstance(step, (Move, Turn)):
            return self._step_ended(False, dt)
        if self._anchor is None:
            self._waited += dt
            if self._waited > ODOM_TIMEOUT:
                return self._fail(f"no odometry from {topic_name(self.namespace, 'odom')} "
                                  f"for {ODOM_TIMEOUT:.0f} s (is the robot on ROS 2 domain {self.bus.domain_id}?)")
            return False
        cmd = self._control(step)
        if cmd is None:
            self._zero()
            self.step = None
            return True
        self._publish(*cmd)
        return False

    def _control(self, step: Move | Turn) -> tuple[float, float] | None:
        """(m/s, rad/s counter-clockwise) towards the step's goal, or None when it is reached."""
        x, y, h = self._pose
        if isinstance(step, Turn):
            err = _wrap(self._target_heading - h)
            if abs(err) <= HEADING_TOLERANCE:
                return None
            return 0.0, -self._turn_rate(err)
        dx, dy = step.x - x, step.y - y
        dist = math.hypot(dx, dy)
        err = _wrap(math.degrees(math.atan2(dy, dx)) - h)
        # there, or beside or just past it (turning on the spot towards a point a few cm away only
        # chases the noise of the pose): face the way it came, if it is more than a little off
        if dist <= POS_TOLERANCE or (dist < CLOSE and abs(err) > 45.0):
            final = _wrap(self._target_heading - h)
            if abs(final) <= HEADING_TOLERANCE or (abs(final) <= FACE_SLACK and not self._facing):
                self._facing = False
                return None
            self._facing = True
            return 0.0, -self._turn_rate(final)
        if abs(err) > TURN_FIRST and dist >= CLOSE:
            return 0.0, -self._turn_rate(err)
        v = min(self.max_speed, max(0.06, 2.0 * dist * self.cell_m))
        w = max(-self.max_turn, min(self.max_turn, 2.5 * math.radians(err)))  # steer, no floor
        return v, -w

    def _turn_rate(self, err_deg: float) -> float:
        """Turn rate (rad/s, positive clockwise on the map) for a heading error in degrees."""
        w = min(self.max_turn, max(0.2, 2.5 * abs(math.radians(err_deg))))
        return math.copysign(w, err_deg)

    def _fail(self, what: str) -> bool:
        self._zero()
        self.bump = {"error": what, "x": self._pose[0], "y": self._pose[1]}
        self.step = None
        return True


class _Watchdog:
    """One thread for all ROS 2 drivers of a process: a driver that commanded motion and was
    not updated for :data:`DEADMAN` seconds gets a zero Twist."""

    _drivers: weakref.WeakSet[ROS2Driver] = weakref.WeakSet()
    _thread: threading.Thread | None = None
    _guard = threading.Lock()

    @classmethod
    def watch(cls, d: ROS2Driver) -> None:
        with cls._guard:
            cls._drivers.add(d)
            if cls._thread is None:
                cls._thread = threading.Thread(target=cls._run, name="ros2-deadman", daemon=True)
                cls._thread.start()

    @classmethod
    def forget(cls, d: ROS2Driver) -> None:
        with cls._guard:
            cls._drivers.discard(d)

    @classmethod
    def _run(cls) -> None:
        while True:
            time.sleep(DEADMAN / 5)
            now = time.monotonic()
            with cls._guard:
                drivers = list(cls._drivers)
            for d in drivers:
                if d._commanded and now - d._last_update > DEADMAN:
                    try:
                        d._zero()
                    except Exception:  # a closed participant at exit
                        pass
