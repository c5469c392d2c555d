"""One world for real and virtual robots: a ROS 2 robot (the simulated ROS 2 robot process on a
loopback-only DDS bus) and a simulated robot of another team's host, both located by a synthetic
overhead camera (``robo-comp camera run --synthetic``), see each other: the simulated robot's
range sensor sees the ROS 2 robot's body, and the ROS 2 robot's readings include the virtual
robot its own lidar cannot see."""
from __future__ import annotations

import math
import os
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

from conftest import wait_for, wait_robots  # noqa: E402
from robo_comp.client import resolve_core  # noqa: E402
from robo_comp.launch import start_robots, stop_all  # noqa: E402
from robo_comp.protocol.curve import create_keys  # noqa: E402
from robo_comp.protocol import unpack_walls  # noqa: E402
from robo_comp.robots.host import RobotHost  # noqa: E402
from robo_comp.robots.oneworld import merge_readings  # noqa: E402
from robo_comp.robots.ros2.bus import loopback_config  # noqa: E402
from robo_comp.world.overhead.binding import Bindings  # noqa: E402
from robo_comp.world.overhead.synth import floor_markers  # noqa: E402


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_merge_takes_the_nearer_echo_of_real_and_virtual():
    sim = {"front": 62.5, "left": None, "right": 120.0, "down": 5.0, "bump": False, "zone": None}
    own = {"front": 250.0, "left": 80.0, "right": None, "down": None}
    assert merge_readings(sim, own) == {"front": 62.5, "left": 80.0, "right": 120.0, "down": 5.0,
                                        "bump": False, "zone": None}


def segment(walls: np.ndarray, red: tuple[float, float], blue: tuple[float, float]) -> tuple[int, int]:
    """A cell (cx, cy) with cells cx-5..cx+1 of its row free, and its row's neighbours free too
    (so a slightly turned ray still meets what it should), far from where the blue robot starts
    and as near as can be to where the red (ROS 2) robot starts (it is the slower)."""
    h, w = walls.shape
    best = None
    for cy in range(1, h - 1):
        for cx in range(5, w - 2):
            if walls[cy - 1:cy + 2, cx - 5:cx + 2].any() or abs(cx - 2 - blue[0]) + abs(cy - blue[1]) <= 6:
                continue
            d = abs(cx + 1 - red[0]) + abs(cy - red[1])
            if best is None or d < best[0]:
                best = (d, cx, cy)
    assert best is not None, "no free row of 7 cells in the arena"
    return best[1], best[2]


@pytest.mark.heartbeat(1.0)  # a camera process drawing and detecting frames shares the two cores
def test_a_ros2_robot_and_a_simulated_robot_see_each_other(core, tmp_path, monkeypatch):
    monkeypatch.setenv("CYCLONEDDS_URI", loopback_config())
    domain = 101 + os.getpid() % 100
    fixes, truth_blue, truth_red = (f"tcp://127.0.0.1:{_port()}" for _ in range(3))
    walls_shape = None
    procs: list[subprocess.Popen] = []
    create_keys(core.state, ["red", "blue"])  # the camera speaks under the organiser's key; hosts pin it
    host = RobotHost(resolve_core(str(core.state)), core.host_token("red"), 1, driver="ros2", seed=2,
                     driver_options={"ros2_ns": ["tb1"], "ros2_domain": domain, "ros2_speed": 0.25},
                     positioning=fixes, camera_key=core.state / "keys" / "organiser.key")
    th = threading.Thread(target=host.run, kwargs={"duration": 120}, daemon=True)
    th.start()
    try:
        procs.append(start_robots(core.state, "blue", 1, "--seed", "1", "--positioning", f"camera:{fixes}",
                                  "--truth-pub", truth_blue))
        red, blue = core.client("red"), core.client("blue")
        r_row, b_row = wait_robots(red, 1)[0], wait_robots(blue, 1)[0]
        walls = unpack_walls(red.arena())
        walls_shape = walls.shape
        sim = subprocess.Popen([sys.executable, "-m", "robo_comp.robots.ros2.simrobot", "--ns", "tb1",
                                "--domain", str(domain), "--x", str(round(r_row["x"])), "--y", str(round(r_row["y"])),
                                "--robot-id", "red-1", "--truth-pub", truth_red],
                               stdout=subprocess.PIPE, text=True)
        procs.append(sim)
        assert sim.stdout is not None and sim.stdout.readline().strip() == "ready"
        h, w = walls_shape
        (tmp_path / "markers.toml").write_text(Bindings({10: "red-1", 11: "blue-1"}, floor_markers(w, h)).to_toml())
        procs.append(subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "camera", "run", "--markers",
                                       str(tmp_path / "markers.toml"), "--pub", fixes, "--key", str(core.state / "keys" / "organiser.key_secret"), "--synthetic",
                                       f"{truth_blue},{truth_red}", "--fps", "10"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        # the red host sees the blue robot through the camera: a body in its arena
        wait_for(lambda: host.camera_fixes > 0 and "blue-1" in host.foreign.seen, 60, "the camera's fixes")
        cx, cy = segment(walls, (r_row["x"], r_row["y"]), (b_row["x"], b_row["y"]))

        def follow(client, tag: int, path: list[list[int]]) -> None:
            tid = client.give(tag, "followPath", [path])["task_id"]
            done = wait_for(lambda: next((t for t in client.monitor(tag)["done"] if t["task_id"] == tid), None), 60,
                            f"followPath {path} to end")
            assert done["ok"], (path, done, client.monitor(tag))

        def place(client, tag: int, path: list[list[int]], heading: float) -> None:
            """Follow ``path``; again while, once the camera's fixes have settled, the robot believes
            it is not at its end facing ``heading`` (on a loaded machine the camera's frames lag, and
            a robot that plans from where it wrongly believes it is stops short)."""
            for _ in range(3):
                follow(client, tag, path)
                time.sleep(1.5)  # standing still: a few fresh frames
                m = client.monitor(tag)
                if math.hypot(m["x"] - path[-1][0], m["y"] - path[-1][1]) < 0.3 and \
                        abs((m["heading"] - heading + 180) % 360 - 180) < 8:
                    return
            raise AssertionError(f"robot {tag} did not get to {path[-1]} facing {heading}: {client.monitor(tag)}")

        place(red, r_row["tag"], [[cx + 1, cy], [cx, cy]], 180.0)  # the ROS 2 robot at (cx, cy) facing west
        place(blue, b_row["tag"], [[cx - 4, cy], [cx - 3, cy]], 0.0)  # the simulated one 3 cells west, facing east
        # each sees the other 2.5 cells (62.5 cm) away; with nothing there both would read 4.5 cells or more
        def front(client, tag: int) -> float:
            return float((client.monitor(tag).get("sensors") or {}).get("front") or 1e9)

        def where() -> str:
            m, n = blue.monitor(b_row["tag"]), red.monitor(r_row["tag"])
            return (f"segment {(cx, cy)}; blue at {m['x'], m['y'], m['heading']} sensing {m.get('sensors')}; "
                    f"red at {n['x'], n['y'], n['heading']} sensing {n.get('sensors')}")

        try:
            wait_for(lambda: 55 < front(blue, b_row["tag"]) < 72, 20, "the simulated robot to see the ROS 2 robot")
            wait_for(lambda: 55 < front(red, r_row["tag"]) < 72, 20, "the ROS 2 robot to see the virtual robot")
        except AssertionError as e:
            raise AssertionError(f"{e}: {where()}") from None
        own = getattr(host.robots["red-1"].driver, "readings")()  # its lidar alone does not see the virtual robot
        assert own["front"] is None or own["front"] > 100, own
    finally:
        host.stop()
        th.join(10)
        stop_all(procs)
