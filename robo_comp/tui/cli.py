"""``robo-comp team`` and ``robo-comp referee``: start the consoles.

``robo_comp.cli`` adds both with ``tui.cli.add_parsers(sub)``.
"""
from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from pathlib import Path

from robo_comp.client import add_connection_args


def _check(args: argparse.Namespace, role: str) -> tuple[str, str]:
    from robo_comp.client import read_token, resolve_core
    from robo_comp.protocol.curve import client_keys

    token = read_token(args.token, args.token_file)
    resolve_core(args.core)  # clear messages now for a wrong --core or key file, before the screen opens
    client_keys(args.core, token, args.curve_cert, args.core_key)
    # the full-screen console draws over the terminal: its log goes to a file it can name
    root = logging.getLogger()
    for h in list(root.handlers):
        root.removeHandler(h)
    log = Path(tempfile.gettempdir()) / f"robo-comp-{role}.log"
    handler = logging.FileHandler(log, encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    root.addHandler(handler)
    if not sys.stdout.isatty():
        print(f"robo-comp {role}: warning: this is not a terminal, the console may not show "
              "(over SSH use 'ssh -t')", file=sys.stderr)
    return args.core, token


def run_team(args: argparse.Namespace) -> int:
    """Run the team console until the user quits (ctrl+q)."""
    from robo_comp.tui.team_app import TeamApp

    core, token = _check(args, "team")
    TeamApp(core, token, upload_dir=Path(args.upload_dir) if args.upload_dir else None,
            curve_cert=args.curve_cert, core_key=args.core_key).run()
    return 0


def run_referee(args: argparse.Namespace) -> int:
    """Run the referee console until the user quits (ctrl+q)."""
    from robo_comp.tui.referee_app import RefereeApp

    core, token = _check(args, "referee")
    RefereeApp(core, token, curve_cert=args.curve_cert, core_key=args.core_key, league=args.league).run()
    return 0


def add_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``team`` and ``referee`` subcommands (each sets ``func``)."""
    t = sub.add_parser("team", help="the team console (Textual): robots, tasks, uploads, STOP",
                       description="A live console for one team: robots table, monitor, map, events, "
                                   "a give-task form, uploads, STOP on ctrl+s. Works from 80x24, also over SSH.")
    add_connection_args(t)
    t.add_argument("--upload-dir", help="folder the upload file picker opens in (default: the current one)")
    t.set_defaults(func=run_team)
    r = sub.add_parser("referee", help="the referee console (Textual): phases, scores, penalties",
                       description="The whole match: phase control with confirmations, scores, every robot, "
                                   "penalties, disqualification, broadcasts, upload approval, filtered events.")
    add_connection_args(r)
    r.add_argument("--league", metavar="LEAGUE", help="a league folder: key l shows its leaderboard (docs/league.md)")
    r.set_defaults(func=run_referee)


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry (``python -m robo_comp.tui.cli team --core … --token …``), the same as ``robo-comp team``."""
    from robo_comp.errors import RoboCompError

    parser = argparse.ArgumentParser(prog="robo-comp")
    add_parsers(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except RoboCompError as e:
        print(f"robo-comp {args.command}: {e.message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
