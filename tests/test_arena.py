"""The simulated arena: motion, collisions, range sensors, surfaces and the camera."""
from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest

from robo_comp.errors import FieldError, NoSuchRobotError
from robo_comp.world.arena import Arena
from robo_comp.world.camera import decode_png_size
from robo_comp.world.scenario import parse_scenario
from robo_comp.world.sensors import cast_rays

ROOM = '''name = "room"
cell_size = 25
seed = 5
map = """
############
#..........#
#..........#
#..........#
#..........#
#..........#
############
"""
[[zones]]
kind = "rubble"
x = 1
y = 5
w = 10
h = 1
speed_factor = 0.5
[[zones]]
kind = "stairs"
x = 10
y = 1
w = 1
h = 1
[[victims]]
id = "v1"
x = 8
y = 3
[sensors]
noise = 0
[robot]
speed = 2
turn_rate = 90
drive = "{drive}"
'''


def arena(drive: str = "grid4", **kw: object) -> Arena:
    return Arena(parse_scenario(ROOM.replace("{drive}", drive), "room.toml"), **kw)


def run(a: Arena, seconds: float, dt: float = 0.1) -> list:
    events = []
    for _ in range(int(round(seconds / dt))):
        events += a.step(dt)
    return events


def test_add_remove_and_errors() -> None:
    a = arena()
    a.add_robot("r1", "red", 1, 1, 0)
    assert a.tags == ["r1"] and a.team_of("r1") == "red"
    with pytest.raises(FieldError):
        a.add_robot("r1", "red", 2, 2)
    with pytest.raises(FieldError):
        a.add_robot("r2", "red", 0, 0)          # wall
    with pytest.raises(FieldError):
        a.add_robot("r2", "red", 1, 1)          # occupied
    with pytest.raises(FieldError):
        a.add_robot("r2", "red", 99, 1)         # outside
    with pytest.raises(NoSuchRobotError):
        a.pose("nobody")
    with pytest.raises(FieldError):
        a.command("r1", "fly", 3)
    with pytest.raises(FieldError):
        a.command("r1", "forward", "far")
    a.remove_robot("r1")
    a.add_robot("r2", "red", 1, 1)              # the cell is free again
    with pytest.raises(NoSuchRobotError):
        a.remove_robot("r1")


def test_grid4_forward_turn_goto() -> None:
    a = arena()
    a.add_robot("r", "red", 1, 1, 0)
    a.command("r", "forward", 3)
    ev = run(a, 2.0)
    assert (a.pose("r").x, a.pose("r").y) == (4.0, 1.0)
    assert [e.kind for e in ev] == ["done"] and ev[0].data["command"] == "forward"
    a.command("r", "turn", 80)                 # rounds to 90° in grid4 mode
    run(a, 1.5)
    assert a.pose("r").heading == 90.0
    a.command("r", "goto", (2, 3))
    ev = run(a, 6.0)
    p = a.pose("r")
    assert (p.x, p.y) == (2.0, 3.0)
    assert any(e.kind == "done" and e.data["command"] == "goto" for e in ev)
    dist, turn = a.odometry("r")
    assert dist == pytest.approx(3 + 2 + 2)
    assert a.odometry("r") == (0.0, 0.0)


def test_turn_takes_time_at_turn_rate() -> None:
    a = arena()
    a.add_robot("r", "red", 3, 3, 0)
    a.command("r", "turn", 180)
    run(a, 1.0)
    assert a.pose("r").heading == pytest.approx(90.0)
    assert a.is_moving("r")
    run(a, 1.0)
    assert a.pose("r").heading == pytest.approx(180.0)
    assert not a.is_moving("r")


def test_collision_with_wall_stops_and_emits_bump() -> None:
    a = arena()
    a.add_robot("r", "red", 8, 2, 0)
    a.command("r", "forward", 10)
    ev = run(a, 5.0)
    bumps = [e for e in ev if e.kind == "bump"]
    assert len(bumps) == 1
    b = bumps[0]
    assert b.tag == "r" and b.data["what"] == "wall" and b.data["cell"] == [11, 2]
    assert (b.data["x"], b.data["y"]) == (10.0, 2.0)
    assert a.pose("r").x == 10.0 and not a.is_moving("r")
    assert a.sense("r")["bump"] is True
    # Still usable after the bump.
    a.command("r", "forward", -2)
    run(a, 2.0)
    assert a.pose("r").x == 8.0 and a.sense("r")["bump"] is False


def test_collision_between_robots() -> None:
    a = arena()
    a.add_robot("r", "red", 2, 3, 0)
    a.add_robot("b", "blue", 7, 3, 180)
    a.command("r", "forward", 8)
    a.command("b", "forward", 8)
    ev = run(a, 4.0)
    bumps = {e.tag: e for e in ev if e.kind == "bump"}
    assert set(bumps) == {"r", "b"}
    assert bumps["r"].data["what"] == "robot" and bumps["r"].data["other"] == "b"
    pr, pb = a.pose("r"), a.pose("b")
    assert pr.x < pb.x and pb.x - pr.x >= 1.0       # stopped apart, in different cells


def test_free_mode_goto_and_wall_bump() -> None:
    a = arena("free")
    a.add_robot("r", "red", 1.2, 1.3, 10)
    a.command("r", "goto", (6.5, 4.0))
    run(a, 6.0)
    p = a.pose("r")
    assert p.x == pytest.approx(6.5) and p.y == pytest.approx(4.0)
    a.command("r", "face", 270)
    a.command("r", "forward", 20, append=True)
    ev = run(a, 6.0)
    assert any(e.kind == "bump" and e.data["what"] == "wall" for e in ev)
    assert 0.5 < a.pose("r").y < 1.5


def test_zone_slows_robot_and_emits_zone_event() -> None:
    a = arena()
    a.add_robot("fast", "red", 1, 4, 0)
    a.add_robot("slow", "red", 1, 5, 0)        # on rubble, speed factor 0.5
    a.command("fast", "forward", 8)
    a.command("slow", "forward", 8)
    ev = run(a, 2.0)
    assert a.pose("fast").x == pytest.approx(5.0)
    assert a.pose("slow").x == pytest.approx(3.0)
    a.command("fast", "turn", 90)
    a.command("fast", "forward", 1, append=True)
    ev = run(a, 2.0)
    z = [e for e in ev if e.kind == "zone"]
    assert z and z[0].tag == "fast" and z[0].data["kind"] == "rubble"
    assert a.surface(3, 5)["zone"] == "rubble" and a.surface(3, 5)["speed_factor"] == 0.5


def test_halt_stops_at_once() -> None:
    a = arena()
    a.add_robot("r", "red", 1, 1, 0)
    a.command("r", "forward", 9)
    run(a, 1.0)
    a.command("r", "halt")
    x = a.pose("r").x
    run(a, 1.0)
    assert a.pose("r").x == x and not a.is_moving("r")


def test_sensors_see_walls_at_the_right_distance() -> None:
    a = arena()
    a.add_robot("r", "red", 3, 2, 0)       # facing east; wall column 11, wall rows 0 and 6
    s = a.sense("r")
    assert s["front"] == pytest.approx((11 - 3 - 0.5) * 25)   # 187.5 cm
    assert s["left"] == pytest.approx((2 - 0.5) * 25)        # wall row 0 (north)
    assert s["right"] == pytest.approx((6 - 2 - 0.5) * 25)   # wall row 6 (south)
    assert s["down"] == pytest.approx(20.0)
    a.add_robot("b", "blue", 6, 2, 0)
    assert a.sense("r")["front"] == pytest.approx(2.5 * 25)  # another robot blocks
    a.add_robot("far", "red", 1, 4, 180)
    assert a.sense("far")["front"] == pytest.approx(12.5)    # clipped to >= min_range 10


def test_range_limits_and_down_sensor_sees_stairs() -> None:
    a = arena()
    a.add_robot("r", "red", 9, 1, 0)           # stairs at (10, 1) just ahead
    assert a.sense("r")["down"] == pytest.approx(80.0)
    big = parse_scenario('map = { width = 60, height = 5 }\n[sensors]\nnoise = 0\n', "big.toml")
    b = Arena(big)
    b.add_robot("r", "red", 1, 2, 0)
    assert b.sense("r")["front"] is None      # 57.5 cells = 1437 cm > 300 cm: no echo


def test_sensor_noise_is_seeded_and_has_sigma() -> None:
    text = ROOM.replace("{drive}", "grid4").replace("noise = 0", "noise = 2.0")
    readings = []
    for seed in (1, 1, 2):
        a = Arena(parse_scenario(text, "n.toml"), seed=seed)
        a.add_robot("r", "red", 3, 2, 0)
        readings.append([a.sense("r")["front"] for _ in range(400)])
    assert readings[0] == readings[1] and readings[0] != readings[2]
    r = np.array(readings[0])
    assert abs(r.mean() - 187.5) < 0.5 and 1.7 < r.std() < 2.3


def test_cast_rays_diagonal_and_axis() -> None:
    walls = np.zeros((10, 10), dtype=bool)
    walls[:, 9] = True
    d = cast_rays(walls, np.array([2.0, 2.0]), np.array([5.0, 1.2]), np.array([0.0, np.pi / 4]), 50)
    assert d[0] == pytest.approx(6.5)
    assert d[1] == pytest.approx(6.5 * np.sqrt(2))


def _png_chunks(data: bytes) -> dict[bytes, bytes]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    i, chunks = 8, {}
    while i < len(data):
        (n,) = struct.unpack(">I", data[i:i + 4])
        kind, body = data[i + 4:i + 8], data[i + 8:i + 8 + n]
        (crc,) = struct.unpack(">I", data[i + 8 + n:i + 12 + n])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF
        chunks[kind] = chunks.get(kind, b"") + body
        i += 12 + n
    return chunks


def test_camera_png_decodes_and_shows_victim() -> None:
    a = arena()
    a.add_robot("r", "red", 4, 3, 0)
    png = a.camera("r")
    assert decode_png_size(png) == (96, 64)
    ch = _png_chunks(png)
    w, h, depth, ctype = struct.unpack(">IIBB", ch[b"IHDR"][:10])
    assert (w, h, depth, ctype) == (96, 64, 8, 2)
    raw = zlib.decompress(ch[b"IDAT"])
    assert len(raw) == 64 * (1 + 96 * 3)
    img = a.camera_image("r")
    assert (np.all(img == (255, 120, 0), axis=-1)).any()        # the victim is in view
    assert [v.id for v in a.victims_in_view("r")] == ["v1"]
    a.command("r", "turn", 180)
    run(a, 2.5)
    assert a.victims_in_view("r") == []
    assert not (np.all(a.camera_image("r") == (255, 120, 0), axis=-1)).any()


def test_camera_png_loads_in_pygame(tmp_path) -> None:
    pygame = pytest.importorskip("pygame")
    a = arena()
    a.add_robot("r", "red", 4, 3, 0)
    p = tmp_path / "cam.png"
    p.write_bytes(a.camera("r"))
    surf = pygame.image.load(str(p))
    assert surf.get_size() == (96, 64)


def test_victim_behind_wall_is_not_in_view() -> None:
    sc = parse_scenario(ROOM.replace("{drive}", "grid4") + "[[walls]]\nx = 6\ny = 3\n", "v.toml")
    a = Arena(sc)
    a.add_robot("r", "red", 4, 3, 0)
    assert a.victims_in_view("r") == []


def test_many_robots_never_share_a_cell() -> None:
    sc = parse_scenario('map = { width = 30, height = 30 }\nseed = 3\n[robot]\ndrive = "free"\n', "m.toml")
    a = Arena(sc)
    rng = np.random.default_rng(0)
    cells = rng.permutation([(x, y) for x in range(1, 29) for y in range(1, 29)])[:200]
    for i, (x, y) in enumerate(cells):
        a.add_robot(f"r{i}", "red", x, y, float(rng.uniform(0, 360)))
    for step in range(100):
        for t in a.tags:
            if not a.is_moving(t):
                a.command(t, "turn", float(rng.uniform(-180, 180)))
                a.command(t, "forward", float(rng.uniform(1, 5)), append=True)
        a.step(0.1)
        poses = a.poses().values()
        occupied = {(int(np.floor(p.x + 0.5)), int(np.floor(p.y + 0.5))) for p in poses}
        assert len(occupied) == 200
        assert all(not sc.walls[cy, cx] for cx, cy in occupied)


def test_compiled_and_numpy_ray_casters_agree() -> None:
    pytest.importorskip("numba")
    rng = np.random.default_rng(4)
    walls = rng.random((60, 80)) < 0.15
    n = 3000
    x, y = rng.uniform(-0.5, 79.4, n), rng.uniform(-0.5, 59.4, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    ang[:300] = rng.choice([0, np.pi / 2, np.pi, 3 * np.pi / 2, np.pi / 4], 300)
    x[:150] = np.round(x[:150])
    a = cast_rays(walls, x, y, ang, 20.0, compiled=False)
    b = cast_rays(walls, x, y, ang, 20.0, compiled=True)
    assert np.array_equal(a, b)


def test_spawn_fills_start_zone() -> None:
    from robo_comp.world.scenario import default_scenario
    a = Arena(default_scenario())
    red = a.scenario.team("red")
    poses = [a.spawn(f"r{i}", "red") for i in range(red.start.w * red.start.h)]
    assert len({(p.x, p.y) for p in poses}) == len(poses)
    assert all(red.start.contains(p.x, p.y) for p in poses)
    with pytest.raises(FieldError, match="full"):
        a.spawn("extra", "red")
    with pytest.raises(FieldError, match="no team"):
        a.spawn("x", "green")


def test_outputs_are_msgpack_plain_data() -> None:
    msgpack = pytest.importorskip("msgpack")
    a = arena()
    a.add_robot("r", "red", 8, 2, 0)
    a.command("r", "forward", 10)
    ev = run(a, 3.0)
    payload = {"events": [e.to_dict() for e in ev], "sense": a.sense("r"), "truth": a.truth(),
               "camera": a.camera("r"), "surface": a.surface(1, 5)}
    assert msgpack.unpackb(msgpack.packb(payload), raw=False) == payload
