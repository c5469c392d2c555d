"""One world for real and virtual robots: a ROS 2 robot (the simulated ROS 2 robot process on a
loopback-only DDS bus) and a simulated robot of another team's host, both located by a synthetic
overhead camera (``robo-comp camera run --synthetic``), play one scored match in one arena: each
is given tasks, each sees the other in its range readings (the simulated robot's sensor sees the
ROS 2 robot's body, the ROS 2 robot's readings include the virtual robot its own lidar cannot see),
and the ROS 2 robot finds a virtual victim through the camera's pose, which the core scores."""
from __future__ import annotations

import json
import math
import os
import socket
import subprocess
import sys
import threading
import time

import pytest

pytest.importorskip("cyclonedds")

from conftest import wait_for, wait_robots  # noqa: E402
from robo_comp.client import resolve_core  # noqa: E402
from robo_comp.launch import start_core, stop_all  # noqa: E402
from robo_comp.protocol.curve import create_keys  # noqa: E402
from robo_comp.robots.host import RobotHost  # noqa: E402
from robo_comp.robots.oneworld import merge_readings  # noqa: E402
from robo_comp.robots.ros2.bus import loopback_config  # noqa: E402
from robo_comp.world.overhead.binding import Bindings  # noqa: E402
from robo_comp.testing import Match  # noqa: E402
from robo_comp.world.overhead.synth import floor_markers  # noqa: E402
from robo_comp.world.scenario import load_scenario  # noqa: E402


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_merge_takes_the_nearer_echo_of_real_and_virtual():
    sim = {"front": 62.5, "left": None, "right": 120.0, "down": 5.0, "bump": False, "zone": None}
    own = {"front": 250.0, "left": 80.0, "right": None, "down": None}
    assert merge_readings(sim, own) == {"front": 62.5, "left": 80.0, "right": 120.0, "down": 5.0,
                                        "bump": False, "zone": None}


#: A small arena for a short match: red's ROS 2 robot starts in (1, 1), blue's simulated robot in
#: (9, 1), both facing east along row 1; the victim is in the ROS 2 robot's camera view from (2, 1).
ARENA = """
name = "One world match"
cell_size = 25
duration = 120
seed = 1
map = \"\"\"
############
#..........#
#..........#
#..........#
#..........#
#..........#
############
\"\"\"

[[victims]]
id = "v1"
x = 5
y = 3
kind = "adult"

[[teams]]
name = "red"
start = { x = 1, y = 1, w = 1, h = 1 }
robots = 1

[[teams]]
name = "blue"
start = { x = 9, y = 1, w = 1, h = 1 }
robots = 1

[robot]
speed = 4.0

[camera]
fov = 90
range = 6
"""


def test_a_ros2_robot_and_a_simulated_robot_play_one_scored_match(tmp_path, monkeypatch):
    monkeypatch.setenv("CYCLONEDDS_URI", loopback_config())
    domain = 101 + os.getpid() % 100
    scenario_file = tmp_path / "oneworld.toml"
    scenario_file.write_text(ARENA)
    scenario = load_scenario(scenario_file)
    fixes, truth_blue, truth_red = (f"tcp://127.0.0.1:{_port()}" for _ in range(3))
    state = tmp_path / "state"
    # a match, not practice: a scenario file; the camera processes share the two cores (heartbeat 1 s)
    core = Match(state, scenario_file, start_core(state, "--heartbeat", "1", "--scenario", str(scenario_file)))
    procs: list[subprocess.Popen] = []
    create_keys(state, ["red", "blue"])  # the camera speaks under the organiser's key; hosts pin it
    host = RobotHost(resolve_core(str(state)), core.host_token("red"), 1, driver="ros2", seed=2, truth=scenario,
                     driver_options={"ros2_ns": ["tb1"], "ros2_domain": domain, "ros2_speed": 0.25},
                     positioning=fixes, camera_key=state / "keys" / "organiser.key")
    th = threading.Thread(target=host.run, kwargs={"duration": 120}, daemon=True)
    th.start()
    try:
        core.robots("blue", 1, "--seed", "1", "--positioning", f"camera:{fixes}",
                    "--truth-pub", truth_blue)  # the organiser's host (--scenario: victims in its pictures)
        red, blue, ref = core.client("red"), core.client("blue"), core.client("referee")
        r_tag, b_tag = wait_robots(red, 1)[0]["tag"], wait_robots(blue, 1)[0]["tag"]
        sim = subprocess.Popen([sys.executable, "-m", "robo_comp.robots.ros2.simrobot", "--ns", "tb1",
                                "--domain", str(domain), "--x", "1", "--y", "1", "--scenario", str(scenario_file),
                                "--robot-id", "red-1", "--truth-pub", truth_red], stdout=subprocess.PIPE, text=True)
        procs.append(sim)
        assert sim.stdout is not None and sim.stdout.readline().strip() == "ready"
        h, w = scenario.walls.shape
        (tmp_path / "markers.toml").write_text(Bindings({10: "red-1", 11: "blue-1"}, floor_markers(w, h)).to_toml())
        procs.append(subprocess.Popen([sys.executable, "-m", "robo_comp.cli", "camera", "run", "--markers",
                                       str(tmp_path / "markers.toml"), "--pub", fixes, "--key",
                                       str(state / "keys" / "organiser.key_secret"), "--synthetic",
                                       f"{truth_blue},{truth_red}", "--fps", "10"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        # the red host sees the blue robot through the camera: a body in its arena
        wait_for(lambda: host.camera_fixes > 0 and "blue-1" in host.foreign.seen, 60, "the camera's fixes")
        assert ref.request("match", action="start")["phase"] == "running"

        def done(client, tag: int, tid: int) -> dict:
            d = wait_for(lambda: next((t for t in client.monitor(tag)["done"] if t["task_id"] == tid), None), 60,
                         f"task {tid} of robot {tag} to end")
            assert d["ok"], (d, client.monitor(tag))
            return d

        def placed(client, tag: int, cell: tuple[int, int], heading: float) -> bool:
            """Whether the robot believes it stands in ``cell`` facing ``heading`` (once the camera's
            fixes settled: on a loaded machine the frames lag, and a robot may stop short)."""
            m = client.monitor(tag)
            return math.hypot(m["x"] - cell[0], m["y"] - cell[1]) < 0.3 and \
                abs((m["heading"] - heading + 180) % 360 - 180) < 8

        # both robots get tasks at once: the ROS 2 robot examines the area from (2, 1) (a cell east,
        # four quarter turns with a picture each, ending facing east); the simulated robot drives to
        # (5, 1), three cells east of it, arriving from the east: facing west, at the ROS 2 robot
        examine = red.give(r_tag, "examineArea", [2, 1])["task_id"]
        path = [[6, 1], [5, 1]]
        drive = blue.give(b_tag, "followPath", [path])["task_id"]
        pictures = done(red, r_tag, examine)["result"]["pictures"]
        assert len(pictures) == 4
        done(blue, b_tag, drive)
        for _ in range(3):  # the simulated robot stopped short while the camera lagged: again
            time.sleep(1.0)  # standing still: a few fresh frames
            if placed(blue, b_tag, (5, 1), 180.0):
                break
            done(blue, b_tag, blue.give(b_tag, "followPath", [path])["task_id"])
        assert placed(blue, b_tag, (5, 1), 180.0), blue.monitor(b_tag)
        assert placed(red, r_tag, (2, 1), 0.0), red.monitor(r_tag)

        # the ROS 2 robot found the victim through the camera's pose: its pictures are the evidence
        verdict = red.request("find", tag=r_tag, x=5, y=3, kind="adult", evidence=pictures)
        assert verdict["state"] == "confirmed", verdict

        # each sees the other 2.5 cells (62.5 cm) away; with nothing there blue would read the west wall
        # (100 cm) and red the east wall (200 cm)
        def front(client, tag: int) -> float:
            return float((client.monitor(tag).get("sensors") or {}).get("front") or 1e9)

        def where() -> str:
            m, n = blue.monitor(b_tag), red.monitor(r_tag)
            return (f"blue at {m['x'], m['y'], m['heading']} sensing {m.get('sensors')}; "
                    f"red at {n['x'], n['y'], n['heading']} sensing {n.get('sensors')}")

        try:
            wait_for(lambda: 55 < front(blue, b_tag) < 72, 20, "the simulated robot to see the ROS 2 robot")
            wait_for(lambda: 55 < front(red, r_tag) < 72, 20, "the ROS 2 robot to see the virtual robot")
        except AssertionError as e:
            raise AssertionError(f"{e}: {where()}") from None
        own = getattr(host.robots["red-1"].driver, "readings")()  # its lidar alone does not see the virtual robot
        assert own["front"] is None or own["front"] > 100, own

        # scored: red found the victim, blue nothing; the referee ends the match, red ranks first
        rows = {t["team"]: t for t in ref.request("score")["teams"]}
        assert rows["red"]["victims"] == 1 and rows["red"]["score"] > 0 and rows["blue"]["victims"] == 0, rows
        assert ref.request("match", action="finish")["phase"] == "finished"
        results = json.loads((state / "results.json").read_text())
        assert [r["team"] for r in results["ranking"]] == ["red", "blue"]
    finally:
        host.stop()
        th.join(10)
        stop_all(procs)
        core.close()
