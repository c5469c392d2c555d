"""``robo-comp keys``: CurveZMQ key pairs for a networked match (``core --curve``)."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from robo_comp.protocol.curve import CORE_NAME, ENV_CERT, ENV_CORE_KEY, ORGANISER, REFEREE, create_keys, keys_dir


def default_teams(state: str | Path) -> list[str]:
    """The teams a key set is for when ``--teams`` is not given: those of ``STATE/core.json``,
    else those with a token in ``STATE/teams``, else the built-in scenario's."""
    state = Path(state)
    try:
        teams = json.loads((state / "core.json").read_text()).get("teams")
        if teams:
            return [str(t) for t in teams]
    except (OSError, ValueError, AttributeError):
        pass
    tokens = sorted(p.stem for p in (state / "teams").glob("*.token"))
    if tokens:
        return tokens
    from robo_comp.world.scenario import default_scenario  # the protocol knows no scenarios; this command does

    return [t.name for t in default_scenario().teams]



def run_keys(args: argparse.Namespace) -> int:
    """Create the key files and say which file goes to whom."""
    state = Path(args.state)
    teams = ([t.strip() for t in args.teams.split(",") if t.strip()] if args.teams
             else default_teams(state))
    created = create_keys(state, teams)
    kdir = keys_dir(state)
    for name, new in created.items():
        print(f"{'created' if new else 'kept   '} {kdir / name}.key_secret and {name}.key")
    print(f"\nCurveZMQ keys in {kdir}:")
    print(f"  {CORE_NAME}.key_secret stays on the core's machine (robo-comp core --state {state} --curve)")
    for team in teams:
        print(f"  team {team}: hand over {team}.key_secret (secret, to that team only) and {CORE_NAME}.key")
    print(f"  referee and walls: {REFEREE}.key_secret and {CORE_NAME}.key")
    print(f"  the organiser's robot hosts and overhead camera: {ORGANISER}.key_secret and {CORE_NAME}.key "
          "(never to a team)")
    print("Clients connect with --curve-cert NAME.key_secret --core-key core.key "
          f"(or ${ENV_CERT} / ${ENV_CORE_KEY}).")
    return 0


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``keys`` subcommand."""
    k = sub.add_parser("keys", help="create CurveZMQ keys for a networked match (core --curve)",
                       description="Create the core's, each team's and the referee's CurveZMQ key pairs "
                                   "in STATE/keys (secrets mode 0600). Existing keys are kept.")
    k.add_argument("--state", required=True, help="the core's state folder")
    k.add_argument("--teams", help="comma-separated team names (default: the core's teams)")
    k.set_defaults(func=run_keys)
