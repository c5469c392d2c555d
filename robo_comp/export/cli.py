"""``robo-comp export``: a match's event log in other tools' formats."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def _mcap(args: argparse.Namespace) -> int:
    from robo_comp.export.mcap import export_mcap

    s = export_mcap(Path(args.log), Path(args.out), Path(args.pictures) if args.pictures else None, args.view)
    print(f"export: view {s.view}: {s.records - s.withheld} of {s.records} records of {args.log} -> {s.out}: "
          + ", ".join(f"{t} {n}" for t, n in sorted(s.messages.items())))
    if s.missing_pictures:
        print(f"export: {len(s.missing_pictures)} pictures not found beside the log "
              f"(ids {', '.join(map(str, s.missing_pictures[:10]))}); their records are on /pictures/meta")
    return 0


def add_parser(sub: Any) -> None:
    """Add ``export`` and its formats to the ``robo-comp`` parser."""
    e = sub.add_parser("export", help="write a match's event log in another tool's format (MCAP)",
                       description="Export a match's event log for other tools.")
    formats = e.add_subparsers(dest="format", required=True, metavar="FORMAT")
    m = formats.add_parser("mcap", help="an MCAP file for Foxglove and ROS 2 tools (ros2 bag)",
                           description="Write the match as an MCAP file of ROS 2 messages (ros2 profile, CDR): "
                                       "the arena as nav_msgs/OccupancyGrid on /arena/map, each robot's pose "
                                       "on /robots/tagTAG/pose (e.g. /robots/tag101/pose), tasks on /tasks, finds on /finds and /finds/point, "
                                       "pictures on /pictures (PNG) and /pictures/meta, the scoreboard on /score, "
                                       "every record the view sees on /events. Needs pip install 'robo_comp[mcap]'.")
    m.add_argument("log", help="the event log (a core's STATE/events.log)")
    m.add_argument("out", help="the MCAP file to write")
    m.add_argument("--pictures", metavar="DIR", help="the match's pictures (default: pictures/ beside the log)")
    m.add_argument("--view", default="public", metavar="VIEW",
                   help="what of the match the file carries: public (default; a file to hand out: what the public "
                        "feeds carried, no private records, fields or picture images), team:NAME (what that team's "
                        "consoles were sent, its own pictures) or referee (everything)")
    m.set_defaults(func=_mcap)
