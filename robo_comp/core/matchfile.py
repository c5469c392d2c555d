"""The match a state folder holds: ``STATE/match.json``, written when a core starts a match.

A core restarted on a state folder recovers the match of its event log; the teams, the scenario,
the rules, the port and the options come from here, so that a restart never silently changes the
match. A command-line value that contradicts the recorded one is refused with a sentence that says
what to do, unless ``--override`` is given (then it is applied and recorded).
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from robo_comp.errors import FieldError

MATCH_FILE = "match.json"
#: The recorded settings and what the organiser calls them on the command line.
OPTIONS = {"teams": "--teams", "scenario_sha256": "--scenario", "practice": "--practice",
           "approve_uploads": "--approve-uploads", "rules": "--rules", "curve": "--curve",
           "pose_hz": "--pose-hz", "heartbeat": "--heartbeat", "port": "--port", "robots": "--robots",
           "max_speed": "--max-speed", "debug_replay": "--debug-replay"}


def scenario_hash(path: str | None) -> str | None:
    """sha256 of a scenario file's bytes (None for the built-in arena)."""
    if path is None:
        return None
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError as e:
        raise FieldError(f"cannot read the scenario file {path}: {e.strerror}") from None


def recorded(state: Path) -> dict[str, Any] | None:
    """The settings of the match in ``state``, or None when it holds no match yet (no events)."""
    log = state / "events.log"
    path = state / MATCH_FILE
    if not log.exists() or log.stat().st_size == 0 or not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise FieldError(f"{path} is damaged ({e}); fix it, or move it away to start from the "
                         "command line's settings") from None
    return data if isinstance(data, dict) else None


def resolve(state: Path, given: dict[str, Any], override: bool = False) -> tuple[dict[str, Any], bool]:
    """The settings to run with: ``given`` (the options the command line named, None = not given)
    on a new match; the recorded ones on a restart, where a contradicting ``given`` value is refused
    unless ``override``. Returns ``(settings, recovering)``."""
    before = recorded(state)
    named = {k: v for k, v in given.items() if v is not None}
    if before is None:
        return named, False
    clash = []
    for key, value in named.items():
        if key == "scenario":
            continue  # compared by its hash
        if key == "port" and value == 0:
            continue  # "any free port" contradicts no port
        if key in before and before[key] != value:
            clash.append(key)
    if clash and not override:
        said = "; ".join(f"{OPTIONS.get(k, k)} {_show(named[k])} (the match has {_show(before[k])})" for k in clash)
        raise FieldError(
            f"{state} holds a match that this restart recovers, and the command line contradicts it: {said}. "
            "Leave these options out to go on with the recovered match, start a new match in an empty "
            "--state folder, or add --override to change them for the rest of this match")
    settings = dict(before)
    if override:
        settings.update(named)
    elif "scenario" not in before and "scenario" in named:
        settings["scenario"] = named["scenario"]
    return settings, True


def _show(value: Any) -> str:
    if isinstance(value, list):
        return ",".join(map(str, value))
    if isinstance(value, str) and len(value) == 64:
        return f"scenario {value[:12]}…"
    return str(value)


def write(state: Path, settings: dict[str, Any]) -> None:
    """Record the match's settings (atomically)."""
    tmp = state / (MATCH_FILE + ".tmp")
    tmp.write_text(json.dumps(settings, indent=2, sort_keys=True))
    os.replace(tmp, state / MATCH_FILE)
