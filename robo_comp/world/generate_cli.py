"""``robo-comp scenario generate``: write a procedurally generated scenario file."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from robo_comp.errors import FieldError


def add_parser(sub: Any) -> None:
    """Add ``scenario`` (with its ``generate`` subcommand) to the ``robo-comp`` parser."""
    p = sub.add_parser("scenario", help="scenario tools: copy a bundled one, check one, generate one")
    ssub = p.add_subparsers(dest="scenario_command", required=True, metavar="COMMAND")
    c = ssub.add_parser("copy", help="copy a bundled scenario (and its map file) to start your own",
                        description="Example: robo-comp scenario copy demo_room arenas/final.toml (folders are "
                                    "made; a map file the scenario names is copied beside it).")
    c.add_argument("name", help="a bundled scenario: demo_room, office, big_rooms")
    c.add_argument("dest", help="the new scenario file (.toml)")
    c.set_defaults(func=run_copy)
    k = ssub.add_parser("check", help="load a scenario and report every problem, or what it holds",
                        description="Loads the scenario as the core does (every problem with file, line and "
                                    "field, exit 2) and checks that every team's start zone reaches every "
                                    "victim (a free cell next to it) on the map. Exit 0 when it is playable.")
    k.add_argument("file", help="the scenario file (.toml) or a bundled scenario's name")
    k.set_defaults(func=run_check)
    g = ssub.add_parser("generate", help="write a generated scenario (rooms, corridors, rubble, victims; "
                        "always solvable) to a TOML file",
                        description="Rooms by recursive division, a corridor between the starts, rubble zones "
                                    "and victims, all from the seed: the same arguments give the same file. "
                                    "See docs/scenarios.md, 'Generated scenarios'.")
    g.add_argument("--seed", type=int, required=True, help="the seed (any integer)")
    g.add_argument("--difficulty", type=float, default=0.5,
                   help="0..1: smaller rooms, narrower doors, more rubble and victims further away (default 0.5)")
    g.add_argument("--size", default="64x48", help="WIDTHxHEIGHT in cells (default 64x48, at least 24x16)")
    g.add_argument("--teams", type=int, default=2, help="start zones (1..4, default 2)")
    g.add_argument("--robots", type=int, default=4, help="robots per team (default 4)")
    g.add_argument("-o", "--out", help="output file (default: generated-SEED.toml)")
    g.set_defaults(func=run_generate)


def run_generate(args: argparse.Namespace) -> int:
    """Write the scenario and print a one-line summary."""
    from robo_comp.world.generate import write_scenario
    from robo_comp.world.scenario import load_scenario

    try:
        w, h = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise FieldError(f"--size must look like 64x48, not {args.size!r}") from None
    out = Path(args.out or f"generated-{args.seed}.toml")
    write_scenario(out, args.seed, difficulty=args.difficulty, width=w, height=h, teams=args.teams,
                   robots=args.robots)
    sc = load_scenario(out)
    rubble = sum(z.rect.w * z.rect.h for z in sc.zones)
    print(f"{out}: {sc.name}, {w}x{h} cells, {int(sc.walls.sum())} wall cells, {len(sc.victims)} victims, "
          f"{len(sc.zones)} rubble zones{f' ({rubble} cells)' if rubble else ''}, {len(sc.teams)} teams")
    return 0


def run_copy(args: argparse.Namespace) -> int:
    """Copy a bundled scenario (and the map file it names) to ``dest``."""
    import shutil

    from robo_comp.world.scenario import bundled_scenario_path

    src = bundled_scenario_path(args.name)
    dest = Path(args.dest)
    if dest.suffix != ".toml":
        raise FieldError(f"the new scenario's file name must end in .toml, not {dest.name!r}")
    if dest.exists():
        raise FieldError(f"{dest} exists already; give another name")
    dest.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, dest)
    copied = [str(dest)]
    import tomllib

    m = tomllib.loads(src.read_text()).get("map")
    if isinstance(m, str) and "\n" not in m and (src.parent / m).is_file() and not (dest.parent / m).exists():
        shutil.copyfile(src.parent / m, dest.parent / m)  # map = "office.txt" is relative to the scenario
        copied.append(str(dest.parent / m))
    print(f"copied {args.name} to {', '.join(copied)}; edit it, then: robo-comp scenario check {dest}")
    return 0


def run_check(args: argparse.Namespace) -> int:
    """Load the scenario and check that each start zone reaches each victim; print a summary."""
    from robo_comp.world.scenario import resolve_scenario
    from robo_comp.world.planner import Planner
    from robo_comp.world.scenario import load_scenario

    sc = load_scenario(resolve_scenario(args.file))
    h, w = sc.walls.shape
    planner = Planner(sc.walls)
    problems = []
    for t in sc.teams:
        r = t.start
        starts = [(x, y) for y in range(r.y, r.y + r.h) for x in range(r.x, r.x + r.w)
                  if 0 <= x < w and 0 <= y < h and not sc.walls[y, x]]
        if len(starts) < t.robots:
            problems.append(f"team {t.name}: {len(starts)} free start cell(s) for {t.robots} robots")
        if not starts:
            continue
        for v in sc.victims:
            near = [(v.x + dx, v.y + dy) for dx, dy in ((0, 0), (0, 1), (0, -1), (1, 0), (-1, 0))
                    if 0 <= v.x + dx < w and 0 <= v.y + dy < h and not sc.walls[v.y + dy, v.x + dx]]
            if not any(planner.reachable(starts[0], p) for p in near):
                problems.append(f"team {t.name} cannot reach victim {v.id} at ({v.x}, {v.y})")
    print(f"{args.file}: {sc.name!r}, {w}x{h} cells, {int(sc.walls.sum())} wall cells, {len(sc.victims)} victims, "
          f"{sc.duration:g} s; teams: " + ", ".join(f"{t.name} ({t.robots} robots, start {t.start.x},{t.start.y} "
                                                   f"{t.start.w}x{t.start.h})" for t in sc.teams))
    for p in problems:
        print(f"problem: {p}")
    print("playable: every start zone reaches every victim" if not problems else f"{len(problems)} problem(s)")
    return 0 if not problems else 1


__all__ = ["add_parser", "run_check", "run_copy", "run_generate"]
