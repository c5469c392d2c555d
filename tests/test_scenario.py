"""Scenario files: bundled scenarios load, malformed ones are rejected naming the line at fault."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from robo_comp.errors import ScenarioError
from robo_comp.world.scenario import (
    Scenario, bundled_scenario_path, bundled_scenarios, default_scenario, load_scenario,
    parse_scenario,
)

BASE = '''name = "t"
map = { width = 24, height = 16 }
'''


def test_default_scenario() -> None:
    s = default_scenario()
    assert isinstance(s, Scenario)
    assert s.width >= 20 and s.height >= 20
    assert {t.name for t in s.teams} == {"red", "blue"}
    assert s.walls[0].all() and s.walls[:, 0].all()
    assert s.victims and all(not s.walls[v.y, v.x] for v in s.victims)
    for t in s.teams:
        assert len(s.start_cells(t.name)) >= t.robots


@pytest.mark.parametrize("name", ["demo_room", "office", "big_rooms"])
def test_bundled_scenarios_load(name: str) -> None:
    assert name in bundled_scenarios()
    s = load_scenario(bundled_scenario_path(name))
    assert s.teams and s.victims
    costs = s.cost_grid()
    assert costs.shape == s.walls.shape and costs.min() >= 1.0
    if name == "demo_room":
        assert (s.width, s.height) == (24, 16)
        assert s.kinematics.drive == "grid4"
        assert any(z.kind == "stairs" and z.drop for z in s.zones)
    if name == "big_rooms":
        assert (s.width, s.height) == (512, 512)


def test_big_map_file_is_small() -> None:
    p = bundled_scenario_path("big_rooms").parent / "rooms512.map"
    assert p.stat().st_size < 300_000


def test_costs_follow_appendix_a() -> None:
    s = parse_scenario(BASE + "[costs]\nnear_cost = 7\nradius = 2\n", "c.toml")
    c = s.cost_grid()
    assert c[8, 12] == 1.0          # open floor
    assert c[1, 5] == 7.0 and c[2, 5] == 7.0 and c[3, 5] == 1.0


def test_walls_zones_objects_victims_teams() -> None:
    text = BASE + '''
[[walls]]
x = 5
y = 5
w = 3
[[zones]]
kind = "water"
x = 10
y = 10
w = 2
h = 2
speed_factor = 0.5
[[objects]]
id = "door"
x = 3
y = 3
[[victims]]
id = "a"
x = 12
y = 4
kind = "child"
points = 20
[[teams]]
name = "red"
colour = "#FF0000"
start = { x = 1, y = 1, w = 2, h = 2 }
robots = 4
'''
    s = parse_scenario(text, "full.toml")
    assert s.walls[5, 5:8].all() and not s.walls[5, 8]
    assert s.zones[0].speed_factor == 0.5 and not s.zones[0].drop
    assert s.objects[0].id == "door"
    assert s.victims[0].points == 20 and s.victims[0].kind == "child"
    assert s.teams[0].colour == "#ff0000" and s.teams[0].rgb == (255, 0, 0)


def test_inline_grid_and_relative_map_file(tmp_path: Path) -> None:
    (tmp_path / "m.txt").write_text("#####\n#...#\n#####\n")
    (tmp_path / "s.toml").write_text('map = "m.txt"\n')
    s = load_scenario(tmp_path / "s.toml")
    assert s.walls.shape == (3, 5) and not s.walls[1, 2]
    s2 = parse_scenario('map = """\n###\n#.#\n###\n"""\n', "i.toml")
    assert s2.walls.shape == (3, 3)


# Each case: scenario text, expected line, a fragment of the message.
BAD = [
    ("syntax", 'name = "x\nmap = 3\n', 1, "syntax"),
    ("syntax-late", BASE + "seed = = 3\n", 3, "syntax"),
    ("unknown-top", BASE + "sede = 3\n", 3, "did you mean 'seed'"),
    ("unknown-in-table", BASE + "[robot]\nsped = 2\n", 4, "did you mean 'speed'"),
    ("no-map", 'name = "x"\n', None, "map is required"),
    ("map-type", "map = 3\n", 1, "map must be"),
    ("map-missing-file", 'map = "nope.map"\n', 1, "not found"),
    ("map-huge", "map = { width = 20000, height = 20000 }\n", 1, "<= 10000"),
    ("map-negative", "map = { width = -3, height = 5 }\n", 1, ">= 1"),
    ("map-bad-char", 'map = """\n###\n#x#\n###\n"""\n', 3, "unknown cell character"),
    ("cell-size-neg", BASE + "cell_size = -1\n", 3, "cell_size"),
    ("duration-str", BASE + 'duration = "long"\n', 3, "must be a number"),
    ("duration-inf", BASE + "duration = inf\n", 3, "finite"),
    ("seed-float", BASE + "seed = 1.5\n", 3, "whole number"),
    ("seed-huge", BASE + "seed = 99999999999999999999\n", 3, "seed"),
    ("bool-type", BASE + "shared_discoveries = 1\n", 3, "true or false"),
    ("victim-outside", BASE + "\n[[victims]]\nid = \"a\"\nx = 2\ny = 3\n[[victims]]\nid = \"b\"\nx = 2\ny = 3\n"
     "[[victims]]\nid = \"c\"\nx = 40\ny = 3\n", 14, "victims[2].x = 40 is outside the 24×16 map"),
    ("victim-in-wall", BASE + "[[victims]]\nx = 0\ny = 3\n", 3, "inside a wall"),
    ("victim-dup", BASE + "[[victims]]\nid = \"a\"\nx = 2\ny = 3\n[[victims]]\nid = \"a\"\nx = 4\ny = 3\n",
     8, "used twice"),
    ("victim-xtype", BASE + "[[victims]]\nx = \"2\"\ny = 3\n", 4, "must be a number"),
    ("victims-not-array", BASE + "victims = 3\n", 3, "array of tables"),
    ("wall-outside", BASE + "[[walls]]\nx = 20\ny = 3\nw = 10\n", 6, "runs outside"),
    ("zone-speed-zero", BASE + "[[zones]]\nkind = \"mud\"\nx = 2\ny = 2\nspeed_factor = 0\n", 7, "speed_factor"),
    ("zone-no-kind", BASE + "[[zones]]\nx = 2\ny = 2\n", 3, "kind is required"),
    ("zone-danger", BASE + "[[zones]]\nkind = \"mud\"\nx = 2\ny = 2\ndanger = 2\n", 7, "<= 1"),
    ("team-overlap", BASE + "[[teams]]\nname = \"a\"\nstart = { x = 1, y = 1, w = 3, h = 3 }\n"
     "[[teams]]\nname = \"b\"\nstart = { x = 2, y = 2, w = 3, h = 3 }\n", 8, "overlaps the start zone of team 'a'"),
    ("team-dup", BASE + "[[teams]]\nname = \"a\"\nstart = { x = 1, y = 1 }\n"
     "[[teams]]\nname = \"a\"\nstart = { x = 5, y = 5 }\n", 7, "used by two teams"),
    ("team-no-start", BASE + "[[teams]]\nname = \"a\"\n", 3, "start"),
    ("team-too-many-robots", BASE + "[[teams]]\nname = \"a\"\nstart = { x = 1, y = 1, w = 2, h = 2 }\nrobots = 9\n",
     6, "do not fit"),
    ("team-robots-huge", BASE + "[[teams]]\nname = \"a\"\nstart = { x = 1, y = 1 }\nrobots = 1e300\n",
     6, "whole number"),
    ("team-colour", BASE + "[[teams]]\nname = \"a\"\ncolour = \"plaid\"\nstart = { x = 1, y = 1 }\n", 5, "colour"),
    ("team-start-key", BASE + "[[teams]]\nname = \"a\"\nstart = { x = 1, y = 1, width = 2 }\n", 5, "unknown key"),
    ("positioning-dropout", BASE + "[positioning]\ndropout = 1.5\n", 4, "dropout"),
    ("positioning-rate0", BASE + "[positioning]\nrate = 0\n", 4, "rate"),
    ("positioning-table", BASE + "positioning = 3\n", 3, "must be a table"),
    ("drive-mode", BASE + "[robot]\ndrive = \"grid8\"\n", 4, "did you mean 'grid4'"),
    ("sensor-range", BASE + "[sensors]\nmin_range = 50\nmax_range = 20\n", 5, "greater than min_range"),
    ("drift-neg", BASE + "[drift]\ndistance = -0.1\n", 4, ">= 0"),
    ("costs-low", BASE + "[costs]\nnear_cost = 0.5\n", 4, ">= 1"),
    ("name-long", 'name = "' + "x" * 500 + '"\nmap = { width = 5, height = 5 }\n', 1, "too long"),
]


@pytest.mark.parametrize("case,text,line,fragment", BAD, ids=[b[0] for b in BAD])
def test_malformed_scenarios_name_the_line(case: str, text: str, line: int | None, fragment: str) -> None:
    with pytest.raises(ScenarioError) as ei:
        parse_scenario(text, "demo.toml")
    msg = str(ei.value)
    assert msg.startswith("demo.toml"), msg
    if line is not None:
        m = re.match(r"demo\.toml line (\d+):", msg)
        assert m, msg
        assert int(m.group(1)) == line, msg
    assert fragment in msg, msg


def test_load_errors(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(tmp_path / "missing.toml")
    p = tmp_path / "bin.toml"
    p.write_bytes(b"\xff\xfe\x00name")
    with pytest.raises(ScenarioError, match="UTF-8"):
        load_scenario(p)
    q = tmp_path / "bad_map.toml"
    (tmp_path / "bad.map").write_text("type octile\nheight 2\nwidth 2\nmap\n..\n")
    q.write_text('map = "bad.map"\n')
    with pytest.raises(ScenarioError, match=r"bad_map\.toml line 1"):
        load_scenario(q)


@pytest.mark.parametrize("value", ["[]", "{}", "true", "1979-05-27", "[[1, 2], [3]]", '"\\u0000"', "-0"])
def test_hostile_values_never_traceback(value: str) -> None:
    for key in ("duration", "seed", "cell_size", "name", "map", "shared_discoveries"):
        text = BASE.replace("map = { width = 24, height = 16 }\n", "") if key == "map" else BASE
        text += f"{key} = {value}\n" if key != "map" else f"map = {value}\n"
        try:
            parse_scenario(text, "h.toml")
        except ScenarioError:
            pass


def test_fuzz_random_bytes_only_scenario_errors() -> None:
    rng = np.random.default_rng(3)
    src = bundled_scenario_path("demo_room").read_text()
    for _ in range(200):
        b = bytearray(src.encode())
        for _ in range(rng.integers(1, 6)):
            i = int(rng.integers(0, len(b)))
            b[i] = int(rng.choice(list(b"0123456789=[]{}\"#.-xye \n")))
        try:
            parse_scenario(b.decode("utf-8", "replace"), "fuzz.toml")
        except ScenarioError:
            pass


@pytest.mark.parametrize("name", ["demo_room", "office", "big_rooms"])
def test_bundled_victims_reachable_from_every_start_zone(name: str) -> None:
    from robo_comp.world.planner import find_path
    s = load_scenario(bundled_scenario_path(name))
    for team in s.teams:
        start = s.start_cells(team.name)[0]
        for v in s.victims:
            assert find_path(s.walls, start, (v.x, v.y)) is not None, (team.name, v.id)


def test_scoring_and_match_tables_configure_the_rules() -> None:
    from robo_comp.scoring.config import ScoringConfig

    text = 'name = "s"\nmap = """\n....\n"""\n[scoring]\nfirst_bonus = 7\nvictim_points = { adult = 3 }\n' \
           '[match]\napprove_uploads = true\n'
    sc = parse_scenario(text, "s.toml")
    cfg = ScoringConfig.from_table(sc.scoring)
    assert cfg.first_bonus == 7 and cfg.victim_points["adult"] == 3 and cfg.victim_points["child"] == 15
    assert sc.approve_uploads is True
    with pytest.raises(ScenarioError, match=r"s.toml line 6: unknown key scoring.first_bonnus .did you mean 'first_bonus'"):
        parse_scenario(text.replace("first_bonus", "first_bonnus"), "s.toml")
    with pytest.raises(ScenarioError, match=r"line 7: scoring.victim_points.adult must be a number"):
        parse_scenario(text.replace("adult = 3", 'adult = "x"'), "s.toml")
