"""``robo-comp scenario generate``: write a procedurally generated scenario file."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from robo_comp.errors import FieldError


def add_parser(sub: Any) -> None:
    """Add ``scenario`` (with its ``generate`` subcommand) to the ``robo-comp`` parser."""
    p = sub.add_parser("scenario", help="scenario tools: generate a procedural scenario")
    ssub = p.add_subparsers(dest="scenario_command", required=True, metavar="COMMAND")
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


__all__ = ["add_parser", "run_generate"]
