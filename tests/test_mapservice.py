"""The map service: snapshots, pieces with shared areas, deltas and per-team visibility."""
from __future__ import annotations

import msgpack
import numpy as np
import pytest

from robo_comp.errors import FieldError, NoSuchRobotError
from robo_comp.world.mapservice import MapService, MapView, pack_bits, unpack_bits
from robo_comp.world.scenario import default_scenario, parse_scenario

TEAMS = ["red", "blue", None]          # None = the referee


def service(shared: bool = False) -> MapService:
    sc = default_scenario()
    sc.shared_discoveries = shared
    return MapService.from_scenario(sc)


def test_snapshot_is_plain_msgpack_data() -> None:
    svc = service()
    svc.report_position("r1", "red", 2, 2, 90, 1.0)
    snap = svc.snapshot("red")
    back = msgpack.unpackb(msgpack.packb(snap), raw=False)
    assert back == snap
    walls = unpack_bits(snap["walls"])
    assert walls.shape == (20, 24) and np.array_equal(walls, default_scenario().walls)
    costs = np.frombuffer(snap["costs"]["data"], dtype="<f4").reshape(snap["costs"]["shape"])
    assert costs[1, 1] == 10.0 and costs[10, 4] == 1.0
    assert snap["robots"] == [{"tag": "r1", "team": "red", "x": 2.0, "y": 2.0, "heading": 90.0, "time": 1.0}]


def test_pack_bits_round_trip() -> None:
    rng = np.random.default_rng(1)
    for shape in [(1, 1), (3, 7), (16, 24), (5, 9)]:
        m = rng.random(shape) < 0.3
        assert np.array_equal(unpack_bits(pack_bits(m)), m)


def test_discoveries_private_per_team_unless_shared() -> None:
    svc = service()
    d = svc.add_discovery("r1", "red", 11, 9, 12.5, kind="victim", evidence=["pic-1"])
    assert d["id"] and d["evidence"] == ["pic-1"]
    assert [x["id"] for x in svc.snapshot("red")["discoveries"]] == [d["id"]]
    assert svc.snapshot("blue")["discoveries"] == []
    assert len(svc.snapshot(None)["discoveries"]) == 1          # the referee sees all
    assert svc.delta_since(1, "blue")["discoveries"] == []
    with pytest.raises(FieldError):
        svc.discovery(d["id"], "blue")
    svc.add_evidence(d["id"], "pic-2")
    assert svc.discovery(d["id"], "red")["evidence"] == ["pic-1", "pic-2"]
    shared = service(shared=True)
    shared.add_discovery("r1", "red", 11, 9, 1.0)
    assert len(shared.snapshot("blue")["discoveries"]) == 1


def test_piece_marks_cells_of_other_robots_pieces() -> None:
    svc = service()
    svc.report_position("a", "red", 2, 2)
    svc.report_position("b", "blue", 6, 4)
    svc.report_position("far", "blue", 20, 17)
    p = svc.piece("a", 3, "red")
    assert (p["x0"], p["y0"], p["width"], p["height"]) == (0, 0, 6, 6)   # clipped at the edge
    shared = unpack_bits(p["shared"])
    # b's piece spans x 3..9, y 1..7: inside a's window that is x 3..5, y 1..5.
    expect = np.zeros((6, 6), dtype=bool)
    expect[1:6, 3:6] = True
    assert np.array_equal(shared, expect)
    assert np.array_equal(unpack_bits(p["walls"]), default_scenario().walls[0:6, 0:6])
    assert [r["tag"] for r in p["robots"]] == ["a"]
    full = svc.piece("far", 2, "blue")
    assert unpack_bits(full["shared"]).sum() == 0
    with pytest.raises(NoSuchRobotError):
        svc.piece("nobody", 3)
    with pytest.raises(FieldError):
        svc.piece("a", -1)


def test_piece_shows_only_visible_discoveries() -> None:
    svc = service()
    svc.report_position("a", "red", 10, 9)
    svc.add_discovery("x", "blue", 11, 9, 1.0)
    assert svc.piece("a", 4, "red")["discoveries"] == []
    assert len(svc.piece("a", 4, None)["discoveries"]) == 1


def test_set_wall_updates_costs_and_deltas() -> None:
    svc = service()
    v0 = svc.version
    n = svc.set_wall(5, 10)
    assert n == 9                                  # the wall and its 8 neighbours' costs
    d = svc.delta_since(v0, "red")
    cells = {(c[0], c[1]): (c[2], c[3]) for c in d["cells"]}
    assert cells[(5, 10)][0] is True and cells[(4, 10)] == (False, 10.0)
    assert svc.set_wall(5, 10) == 0
    with pytest.raises(FieldError):
        svc.set_wall(99, 0)


def test_delta_since_zero_or_unknown_is_full() -> None:
    svc = service()
    assert svc.delta_since(0, "red")["type"] == "full"
    assert svc.delta_since(svc.version + 5, "red")["type"] == "full"
    assert svc.delta_since(svc.version, "red")["type"] == "delta"


def test_view_rejects_gap() -> None:
    svc = service()
    v = MapView()
    svc.report_position("a", "red", 2, 2)
    with pytest.raises(FieldError):
        v.apply(svc.delta_since(2, "red"))


@pytest.mark.parametrize("shared", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_updates_deltas_keep_views_equal(shared: bool, seed: int) -> None:
    rng = np.random.default_rng(seed)
    svc = service(shared)
    views = {t: MapView() for t in TEAMS}
    for t, v in views.items():
        v.apply(svc.delta_since(0, t))
    robots: dict[str, str] = {}
    discoveries: list[str] = []
    for step in range(300):
        op = rng.integers(0, 8)
        if op <= 2:
            tag = f"r{rng.integers(0, 8)}"
            team = robots.setdefault(tag, str(rng.choice(["red", "blue"])))
            svc.report_position(tag, team, float(rng.uniform(1, 22)), float(rng.uniform(1, 18)),
                                float(rng.uniform(0, 360)), step * 0.1)
        elif op == 3 and robots:
            tag = str(rng.choice(sorted(robots)))
            try:
                svc.remove_robot(tag)
            except NoSuchRobotError:
                pass
        elif op == 4:
            team = str(rng.choice(["red", "blue"]))
            d = svc.add_discovery(f"r{rng.integers(0, 8)}", team, int(rng.integers(1, 23)),
                                  int(rng.integers(1, 19)), step * 0.1, evidence=[f"p{step}"])
            discoveries.append(d["id"])
        elif op == 5 and discoveries:
            svc.add_evidence(str(rng.choice(discoveries)), f"q{step}")
        elif op == 6:
            svc.set_wall(int(rng.integers(1, 23)), int(rng.integers(1, 19)), bool(rng.random() < 0.6))
        else:
            oid = f"o{rng.integers(0, 4)}"
            if rng.random() < 0.7:
                svc.add_object(oid, "box", int(rng.integers(0, 24)), int(rng.integers(0, 20)))
            else:
                try:
                    svc.remove_object(oid)
                except FieldError:
                    pass
        # Each client syncs at its own pace; deltas travel through msgpack.
        for t, v in views.items():
            if rng.random() < 0.4:
                wire = msgpack.packb(svc.delta_since(v.version, t))
                v.apply(msgpack.unpackb(wire, raw=False))
    for t, v in views.items():
        v.apply(svc.delta_since(v.version, t))
        assert v.snapshot() == svc.snapshot(t), t
    red_ids = {d["id"] for d in svc.snapshot("red")["discoveries"]}
    blue_ids = {d["id"] for d in svc.snapshot("blue")["discoveries"]}
    if shared:
        assert red_ids == blue_ids
    else:
        assert not red_ids & blue_ids
        assert all(d["team"] == "red" for d in svc.snapshot("red")["discoveries"])


def test_from_scenario_objects_and_zones() -> None:
    sc = parse_scenario('map = { width = 10, height = 8 }\n[[objects]]\nid = "t"\nkind = "table"\nx = 3\ny = 3\n'
                        '[[zones]]\nkind = "water"\nx = 2\ny = 2\nw = 2\nh = 2\n', "o.toml")
    svc = MapService.from_scenario(sc)
    snap = svc.snapshot("red")
    assert snap["objects"][0]["id"] == "t"
    assert snap["zones"][0]["kind"] == "water"
