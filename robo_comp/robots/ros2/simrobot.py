"""A simulated ROS 2 robot: what the ROS 2 driver is tested against, on a real DDS bus.

``python -m robo_comp.robots.ros2.simrobot --ns tb1 --domain 42 --x 3 --y 4`` joins ROS 2 domain
42 (Cyclone DDS, configured by ``CYCLONEDDS_URI`` as any ROS 2 program) and behaves as a
differential-drive ROS 2 robot in an arena (the built-in one, or ``--scenario FILE``): it
subscribes ``/tb1/cmd_vel`` (``geometry_msgs/Twist``), integrates its pose from the latest
command at 100 Hz (a wall stops it: the move that would enter a wall cell is not made), and
publishes ``/tb1/odom`` (``nav_msgs/Odometry``, 20 Hz, the ``odom`` frame starting at zero
where it starts) and ``/tb1/scan`` (``sensor_msgs/LaserScan``, 360 rays, 5 Hz, ranges to the
arena's walls). It prints ``ready`` when it has joined and, on SIGTERM, its true pose in the
arena (``pose X Y HEADING``) before it exits. With ``--truth-pub URL --robot-id ID`` it also
publishes its true pose as a simulating robot host does (``robots --truth-pub``), so a synthetic
overhead camera (``robo-comp camera run --synthetic``) sees it. There is no ROS in it: only the
messages.
"""
from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from typing import Any

import numpy as np


def main(argv: list[str] | None = None) -> int:
    """Run the simulated robot until SIGTERM/SIGINT or ``--duration``."""
    ap = argparse.ArgumentParser(prog="python -m robo_comp.robots.ros2.simrobot", description=__doc__.split("\n\n")[0])
    ap.add_argument("--ns", default="", help="ROS 2 namespace of the robot's topics")
    ap.add_argument("--domain", type=int, default=0, help="ROS 2 domain id")
    ap.add_argument("--x", type=float, default=1.0, help="start x in cells")
    ap.add_argument("--y", type=float, default=1.0, help="start y in cells")
    ap.add_argument("--heading", type=float, default=0.0, help="start heading in degrees (arena convention)")
    ap.add_argument("--scenario", help="scenario file whose walls the scan sees (default: the built-in arena)")
    ap.add_argument("--max-speed", type=float, default=0.31, help="m/s (TurtleBot 4: 0.31)")
    ap.add_argument("--max-turn", type=float, default=1.9, help="rad/s")
    ap.add_argument("--duration", type=float, default=0.0, help="exit after S seconds (0: until SIGTERM)")
    ap.add_argument("--robot-id", default="", help="its robot id in the match (for --truth-pub)")
    ap.add_argument("--truth-pub", metavar="URL",
                    help="publish its true pose here, as a simulating host does, for synthetic overhead cameras "
                         "(robo-comp camera run --synthetic URL)")
    args = ap.parse_args(argv)

    from robo_comp.robots.ros2.bus import Bus, topic_name
    from robo_comp.robots.ros2.msgs import (Header, LaserScan, Odometry, Point, Pose, PoseWithCovariance, Twist,
                                            TwistWithCovariance, Vector3, quaternion_of, stamp)
    from robo_comp.world.scenario import default_scenario, load_scenario
    from robo_comp.world.sensors import cast_rays

    scenario = load_scenario(args.scenario) if args.scenario else default_scenario()
    walls = np.asarray(scenario.walls, dtype=bool)
    cell_m = scenario.cell_size / 100.0
    bus = Bus(args.domain)
    cmd_in = bus.reader(topic_name(args.ns, "cmd_vel"), Twist, reliable=True)
    odom_out = bus.writer(topic_name(args.ns, "odom"), Odometry)
    scan_out = bus.writer(topic_name(args.ns, "scan"), LaserScan, depth=2)

    running = True

    def _stop(*_: object) -> None:
        nonlocal running
        running = False

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    X = Y = yaw = 0.0  # odom frame: metres, counter-clockwise
    v = w = 0.0
    h0 = math.radians(args.heading)
    rays = 360
    angles = np.linspace(-math.pi, math.pi, rays, endpoint=False)

    def arena_pose() -> tuple[float, float, float]:
        x = args.x + (X * math.cos(h0) + Y * math.sin(h0)) / cell_m
        y = args.y + (X * math.sin(h0) - Y * math.cos(h0)) / cell_m
        return x, y, (args.heading - math.degrees(yaw)) % 360.0

    def blocked(x: float, y: float) -> bool:
        cx, cy = int(math.floor(x + 0.5)), int(math.floor(y + 0.5))
        h, wd = walls.shape
        return not (0 <= cx < wd and 0 <= cy < h) or bool(walls[cy, cx])

    truth_sock: Any = None
    if args.truth_pub:
        import zmq

        from robo_comp import protocol as P

        truth_sock = zmq.Context.instance().socket(zmq.PUB)
        truth_sock.setsockopt(zmq.LINGER, 0)
        truth_sock.bind(args.truth_pub)
        h_cells, w_cells = walls.shape
        packed = np.packbits(walls, axis=None).tobytes()
    next_truth = time.monotonic()
    print("ready", flush=True)
    dt = 0.01
    t0 = last = time.monotonic()
    next_odom = next_scan = last
    while running and (not args.duration or time.monotonic() - t0 < args.duration):
        for m in cmd_in.take(N=64):
            if not isinstance(m, Twist):  # a writer's disposal, not a command
                continue
            v = max(-args.max_speed, min(args.max_speed, m.linear.x))
            w = max(-args.max_turn, min(args.max_turn, m.angular.z))
        now = time.monotonic()
        step = min(now - last, 0.1)
        last = now
        nX = X + v * math.cos(yaw) * step
        nY = Y + v * math.sin(yaw) * step
        saved = (X, Y)
        X, Y = nX, nY
        if blocked(*arena_pose()[:2]):
            X, Y = saved
        yaw = math.atan2(math.sin(yaw + w * step), math.cos(yaw + w * step))
        if now >= next_odom:
            next_odom = now + 0.05
            odom_out.write(Odometry(
                header=Header(stamp=stamp(time.time()), frame_id="odom"), child_frame_id="base_link",
                pose=PoseWithCovariance(pose=Pose(position=Point(x=X, y=Y), orientation=quaternion_of(yaw))),
                twist=TwistWithCovariance(twist=Twist(linear=Vector3(x=v), angular=Vector3(z=w)))))
        if now >= next_scan:
            next_scan = now + 0.2
            x, y, hd = arena_pose()
            arena_angles = np.radians(hd) - angles  # a counter-clockwise ray turns the arena's way round
            d = cast_rays(walls, np.full(rays, x), np.full(rays, y), arena_angles, 12.0 / cell_m) * cell_m
            ranges: Any = [float(r) if math.isfinite(r) else math.inf for r in d]
            scan_out.write(LaserScan(header=Header(stamp=stamp(time.time()), frame_id="laser"),
                                     angle_min=-math.pi, angle_max=math.pi - 2 * math.pi / rays,
                                     angle_increment=2 * math.pi / rays, scan_time=0.2,
                                     range_min=0.15, range_max=12.0, ranges=ranges))
        if truth_sock is not None and now >= next_truth:
            next_truth = now + 0.05
            x, y, hd = arena_pose()
            truth_sock.send_multipart([b"truth", P.pack({"w": w_cells, "h": h_cells, "walls": packed,
                                                         "robots": [[args.robot_id, x, y, hd]]})])
        time.sleep(dt)
    if truth_sock is not None:
        truth_sock.close(0)
    x, y, hd = arena_pose()
    print(f"pose {x:.4f} {y:.4f} {hd:.3f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
