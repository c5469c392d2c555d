"""``robo-comp export mcap``: a real match's event log as MCAP, read back with the mcap reader and
the ROS 2 decoder (what Foxglove and ``ros2 bag`` use), checked against the log itself."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("mcap_ros2")

from mcap.reader import make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402

from conftest import HEARTBEAT, wait_for, wait_robots  # noqa: E402
from robo_comp.cli import main as cli_main  # noqa: E402
from robo_comp.errors import RoboCompError  # noqa: E402
from robo_comp.launch import start_core  # noqa: E402
from robo_comp.protocol import EVERYONE, PRIVATE_TOPICS, PUBLIC_TOPICS, public_event, unpack_walls  # noqa: E402
from robo_comp.protocol.logfile import read_log  # noqa: E402
from robo_comp.testing import Match  # noqa: E402


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


@dataclass
class Played:
    """A real match's event log (red: two robots, an examineArea, its picture, a find with it; blue:
    one robot; each team a refused command, a private record) and what it was played with."""

    log: Path
    rows: list[dict[str, Any]]
    blue: list[dict[str, Any]]
    tag: int
    pic: dict[str, Any]


@pytest.fixture(scope="module")
def played(tmp_path_factory: pytest.TempPathFactory) -> Played:
    state = tmp_path_factory.mktemp("export") / "state"
    core = Match(state, None, start_core(state, "--heartbeat", str(HEARTBEAT), "--teams", "red,blue"))
    try:
        core.robots("red", 2)
        core.robots("blue", 1)
        red, blue = core.client("red"), core.client("blue")
        rows, brows = wait_robots(red, 2), wait_robots(blue, 1)
        tag = rows[0]["tag"]
        red.give(tag, "examineArea", [round(rows[0]["x"]), round(rows[0]["y"])])

        def pictures() -> list:
            return [e for e in core.logged_events() if e["topic"] == "picture"]

        pic = wait_for(pictures, 20, "a picture in the log")[0]["data"]
        red.request("find", tag=tag, x=round(rows[0]["x"]), y=round(rows[0]["y"]), kind="victim", evidence=[pic["id"]])
        for mine, theirs in ((red, brows[0]["tag"]), (blue, tag)):  # each team: a refusal (a private record)
            with pytest.raises(RoboCompError):
                mine.give(theirs, "goTo", [1, 1])
        wait_for(lambda: any(e["topic"] == "robot.positions" and rows[1]["tag"] in e["data"]["tags"]
                             for e in core.logged_events()), 10, "positions in the log")
        wait_for(lambda: any(e["topic"] == "find.reported" for e in core.logged_events()), 10, "the find in the log")
        wait_for(lambda: {e["team"] for e in core.logged_events("refused")} == {"red", "blue"}, 10, "the refusals")
    finally:
        core.close()  # the log is complete
    return Played(state / "events.log", rows, brows, tag, pic)


def export(p: Played, out: Path, *view: str) -> tuple[dict[str, list], dict[str, str], Any]:
    """Export ``p``'s log (``--view`` if given) with the command and read it back."""
    assert cli_main(["export", "mcap", str(p.log), str(out), *(("--view", *view) if view else ())]) == 0
    return read_back(out)


def test_the_referee_view_exports_every_record_on_its_own_topic(played, tmp_path, capsys):
    core_state, rows, tag, pic, log = played.log.parent, played.rows, played.tag, played.pic, played.log
    out = tmp_path / "match.mcap"
    assert cli_main(["export", "mcap", str(log), str(out), "--view", "referee"]) == 0
    said = capsys.readouterr().out
    assert "/pictures 1" in said and "view referee" in said
    records = list(read_log(log))
    got, types, summary = read_back(out)
    assert types == {"/arena/map": "nav_msgs/OccupancyGrid", "/events": "std_msgs/String",
                     "/tasks": "std_msgs/String", "/finds": "std_msgs/String", "/finds/point": "geometry_msgs/PointStamped",
                     "/pictures": "sensor_msgs/CompressedImage", "/pictures/meta": "std_msgs/String",
                     "/score": "std_msgs/String", "/tf": "tf2_msgs/TFMessage",
                     **{f"/robots/tag{r['tag']}/pose": "geometry_msgs/PoseStamped" for r in rows + played.blue}}
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

    # the same poses as transforms arena -> robot_TAG on /tf, one message a record of poses (Foxglove's 3D panel)
    posed = [(rec.t, [rec.data["tag"]] if rec.topic == "robot.registered" else rec.data["tags"]) for rec in records
             if rec.topic in ("robot.registered", "robot.positions")]
    posed = [(t, tags) for t, tags in posed if tags]
    assert [(ns, [x.child_frame_id for x in m.transforms]) for ns, m in got["/tf"]] == \
        [(round(t * 1e9), [f"robot_{tag}" for tag in tags]) for t, tags in posed]
    for r in rows + played.blue:
        poses = [p.pose for _, p in got[f"/robots/tag{r['tag']}/pose"]]
        moved = [x.transform for _, m in got["/tf"] for x in m.transforms if x.child_frame_id == f"robot_{r['tag']}"]
        assert [(q.position.x, q.position.y, q.orientation.z, q.orientation.w) for q in poses] == \
            [(x.translation.x, x.translation.y, x.rotation.z, x.rotation.w) for x in moved]
        assert all(x.header.frame_id == "arena" for _, m in got["/tf"] for x in m.transforms)

    # tasks, the find and the picture on their own topics
    tasks = [json.loads(m.data) for _, m in got["/tasks"]]
    assert [(t["event"], t["name"]) for t in tasks if t["tag"] == tag][:2] == [("task.given", "examineArea"),
                                                                                ("task.started", "examineArea")]
    (_, find), = got["/finds"]
    assert json.loads(find.data) == next(r.data for r in records if r.topic == "find.reported")
    (_, point), = got["/finds/point"]
    assert math.isclose(point.point.x, round(rows[0]["x"]) * s) and math.isclose(point.point.y, -round(rows[0]["y"]) * s)
    (_, image), = got["/pictures"]
    assert image.format == "png" and bytes(image.data) == (core_state / "pictures" / f"{pic['id']}.png").read_bytes()
    assert image.header.frame_id == f"robot_{tag}"
    assert json.loads(got["/pictures/meta"][0][1].data)["id"] == pic["id"]
    assert summary.statistics.message_count == sum(len(v) for v in got.values())


def test_a_public_export_carries_nothing_private(played, tmp_path, capsys):
    """The default view, for a file handed out: exactly what the public feeds carry, field by field
    against the one visibility table (protocol/topics.py)."""
    records = list(read_log(played.log))
    # the log holds private records and private fields: a test that can fail
    assert "refused" in {r.topic for r in records} & PRIVATE_TOPICS
    assert any(r.data.keys() - set(PUBLIC_TOPICS[r.topic]) for r in records if r.topic in PUBLIC_TOPICS)
    assert any(r.topic == "picture" and "victims" in r.data for r in records)
    got, types, _ = export(played, tmp_path / "public.mcap")
    assert "view public" in capsys.readouterr().out
    assert "/pictures" not in types  # a picture's image is its team's
    assert types["/tf"] == "tf2_msgs/TFMessage"  # positions are public
    shown = [json.loads(m.data) for _, m in got["/events"]]
    assert [e["seq"] for e in shown] == [r.seq for r in records if r.topic in PUBLIC_TOPICS]
    by_seq = {r.seq: r for r in records}
    for e in shown:
        fields, data = PUBLIC_TOPICS[e["topic"]], e["data"]
        assert data.keys() <= set(fields), e
        rec = by_seq[e["seq"]]
        assert data.keys() == public_event(rec.topic, rec.data).keys()
    # the topics made from records carry the same public view
    for topic, record_topic in (("/finds", "find.reported"), ("/pictures/meta", "picture")):
        (_, m), = got[topic]
        assert json.loads(m.data) == public_event(record_topic, next(r.data for r in records if r.topic == record_topic))
    for _, m in got["/tasks"]:
        task = json.loads(m.data)  # a task record: the event's public fields, its topic and team
        assert task.keys() <= set(PUBLIC_TOPICS[task["event"]]) | {"event", "team"}, task


def test_a_team_export_carries_that_team_s_records_only(played, tmp_path):
    records = list(read_log(played.log))
    got, types, _ = export(played, tmp_path / "red.mcap", "team:red")
    shown = [json.loads(m.data) for _, m in got["/events"]]
    assert {e["team"] for e in shown} <= {"red", EVERYONE, None}
    refused = [e for e in shown if e["topic"] == "refused"]
    assert [e["team"] for e in refused] == ["red"]  # its own private record, whole
    assert refused[0]["data"] == next(r.data for r in records if r.topic == "refused" and r.team == "red")
    red_tags = {r["tag"] for r in played.rows}
    assert all(set(e["data"]["tags"]) <= red_tags for e in shown if e["topic"] == "robot.positions")
    assert not any(f"/robots/tag{r['tag']}/pose" in types for r in played.blue)
    (_, image), = got["/pictures"]  # its own picture's image
    assert bytes(image.data) == (played.log.parent / "pictures" / f"{played.pic['id']}.png").read_bytes()
    blue = {e["seq"] for e in (json.loads(m.data) for _, m in export(played, tmp_path / "blue.mcap", "team:blue")[0]["/events"])}
    assert not blue & {r.seq for r in records if r.team == "red"}


def test_bad_input_gets_a_clear_error(tmp_path, capsys):
    assert cli_main(["export", "mcap", str(tmp_path / "nope.log"), str(tmp_path / "o.mcap")]) == 2
    assert "no such event log" in capsys.readouterr().err
    junk = tmp_path / "junk.log"
    junk.write_bytes(b"this is not an event log at all")
    assert cli_main(["export", "mcap", str(junk), str(tmp_path / "o.mcap")]) == 2
    assert "is this a robo_comp event log?" in capsys.readouterr().err


def test_an_unknown_view_is_refused_with_the_views_there_are(played, tmp_path, capsys):
    assert cli_main(["export", "mcap", str(played.log), str(tmp_path / "o.mcap"), "--view", "team:green"]) == 2
    err = capsys.readouterr().err
    assert "--view 'team:green'" in err and "team:red, team:blue" in err and not (tmp_path / "o.mcap").exists()


def test_a_stamp_rounds_into_the_next_second() -> None:
    from robo_comp.export.mcap import _stamp

    assert _stamp(1.9999999999) == {"sec": 2, "nanosec": 0}  # rounds up into the next second, not back to 1 s
    assert _stamp(1764072000.25) == {"sec": 1764072000, "nanosec": 250_000_000}
    assert _stamp(0.0) == {"sec": 0, "nanosec": 0} and _stamp(12.5) == {"sec": 12, "nanosec": 500_000_000}
