"""``robo-comp export mcap``: a real match's event log as MCAP, read back with the mcap reader and
the ROS 2 decoder (what Foxglove and ``ros2 bag`` use), checked against the log itself."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("mcap_ros2")

from mcap.reader import make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402

from conftest import wait_for, wait_robots  # noqa: E402
from robo_comp.cli import main as cli_main  # noqa: E402
from robo_comp.protocol import unpack_walls  # noqa: E402
from robo_comp.protocol.logfile import read_log  # noqa: E402


def read_back(path: Path) -> tuple[dict[str, list], dict[str, str], Any]:
    """Every decoded message by topic, the schema (type) of each topic, and the summary."""
    by_topic: dict[str, list] = {}
    types: dict[str, str] = {}
    with open(path, "rb") as f:
        r = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = r.get_summary()
        assert r.get_header().profile == "ros2"
        for schema, channel, message, decoded in r.iter_decoded_messages(log_time_order=False):
            assert schema is not None and channel.message_encoding == "cdr" and schema.encoding == "ros2msg"
            by_topic.setdefault(channel.topic, []).append((message.log_time, decoded))
            types[channel.topic] = schema.name
    return by_topic, types, summary


def test_a_real_match_log_exports_to_mcap_with_its_own_topics(core, tmp_path, capsys):
    core.robots("red", 2)
    red = core.client("red")
    rows = wait_robots(red, 2)
    tag = rows[0]["tag"]
    red.give(tag, "examineArea", [round(rows[0]["x"]), round(rows[0]["y"])])

    def pictures() -> list:
        return [e for e in core.logged_events() if e["topic"] == "picture"]

    pic = wait_for(pictures, 20, "a picture in the log")[0]["data"]
    red.request("find", tag=tag, x=round(rows[0]["x"]), y=round(rows[0]["y"]), kind="victim", evidence=[pic["id"]])
    wait_for(lambda: any(e["topic"] == "robot.positions" and rows[1]["tag"] in e["data"]["tags"]
                         for e in core.logged_events()), 10, "positions in the log")
    wait_for(lambda: any(e["topic"] == "find.reported" for e in core.logged_events()), 10, "the find in the log")
    core.close()  # the log is complete
    log = core.state / "events.log"
    out = tmp_path / "match.mcap"
    assert cli_main(["export", "mcap", str(log), str(out)]) == 0
    assert "/pictures 1" in capsys.readouterr().out

    records = list(read_log(log))
    got, types, summary = read_back(out)
    assert types == {"/arena/map": "nav_msgs/OccupancyGrid", "/events": "std_msgs/String",
                     "/tasks": "std_msgs/String", "/finds": "std_msgs/String", "/finds/point": "geometry_msgs/PointStamped",
                     "/pictures": "sensor_msgs/CompressedImage", "/pictures/meta": "std_msgs/String",
                     "/score": "std_msgs/String",
                     **{f"/robots/tag{r['tag']}/pose": "geometry_msgs/PoseStamped" for r in rows}}
    assert len(got["/events"]) == len(records)  # every record, in order
    assert [json.loads(m.data)["seq"] for _, m in got["/events"]] == [r.seq for r in records]

    # the map: walls at 100, y flipped (the grid's first row is the arena's last)
    started = next(r.data for r in records if r.topic == "core.started")
    walls = unpack_walls(started["arena"])
    (_, grid), = got["/arena/map"]
    s = started["arena"]["cell_cm"] / 100
    assert (grid.info.width, grid.info.height, round(grid.info.resolution, 6)) == (walls.shape[1], walls.shape[0], s)
    cells = list(grid.data)
    h, w = walls.shape
    assert all((cells[(h - 1 - y) * w + x] == 100) == bool(walls[y, x]) for y in range(h) for x in range(w))

    # each robot's poses: one per row of the log's positions (and its registration), in metres
    for r in rows:
        expect = [(rec.t, x, y, hd) for rec in records if rec.topic == "robot.positions"
                  for t_, x, y, hd in zip(rec.data["tags"], rec.data["x"], rec.data["y"], rec.data["heading"])
                  if t_ == r["tag"]]
        poses = got[f"/robots/tag{r['tag']}/pose"][1:]  # the first is the registration
        assert len(poses) == len(expect) > 0
        for (ns, p), (t, x, y, hd) in zip(poses, expect):
            assert ns == round(t * 1e9) and p.header.frame_id == "arena"
            assert math.isclose(p.pose.position.x, x * s) and math.isclose(p.pose.position.y, -y * s)
            yaw = 2 * math.atan2(p.pose.orientation.z, p.pose.orientation.w)
            assert abs((math.degrees(-yaw) - hd + 180) % 360 - 180) < 1e-6

    # tasks, the find and the picture on their own topics
    tasks = [json.loads(m.data) for _, m in got["/tasks"]]
    assert [(t["event"], t["name"]) for t in tasks if t["tag"] == tag][:2] == [("task.given", "examineArea"),
                                                                                ("task.started", "examineArea")]
    (_, find), = got["/finds"]
    assert json.loads(find.data) == next(r.data for r in records if r.topic == "find.reported")
    (_, point), = got["/finds/point"]
    assert math.isclose(point.point.x, round(rows[0]["x"]) * s) and math.isclose(point.point.y, -round(rows[0]["y"]) * s)
    (_, image), = got["/pictures"]
    assert image.format == "png" and bytes(image.data) == (core.state / "pictures" / f"{pic['id']}.png").read_bytes()
    assert image.header.frame_id == f"robot_{tag}"
    assert json.loads(got["/pictures/meta"][0][1].data)["id"] == pic["id"]
    assert summary.statistics.message_count == sum(len(v) for v in got.values())


def test_bad_input_gets_a_clear_error(tmp_path, capsys):
    assert cli_main(["export", "mcap", str(tmp_path / "nope.log"), str(tmp_path / "o.mcap")]) == 2
    assert "no such event log" in capsys.readouterr().err
    junk = tmp_path / "junk.log"
    junk.write_bytes(b"this is not an event log at all")
    assert cli_main(["export", "mcap", str(junk), str(tmp_path / "o.mcap")]) == 2
    assert "is this a robo_comp event log?" in capsys.readouterr().err


def test_a_stamp_rounds_into_the_next_second() -> None:
    from robo_comp.export.mcap import _stamp

    assert _stamp(1.9999999999) == {"sec": 2, "nanosec": 0}  # rounds up into the next second, not back to 1 s
    assert _stamp(1764072000.25) == {"sec": 1764072000, "nanosec": 250_000_000}
    assert _stamp(0.0) == {"sec": 0, "nanosec": 0} and _stamp(12.5) == {"sec": 12, "nanosec": 500_000_000}
