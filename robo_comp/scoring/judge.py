"""The find judge: pictures as evidence and reported finds, judged as the official match does.

One judge serves a live match (the core's :class:`~robo_comp.core.competition.Competition`)
and a bench or league match (:class:`~robo_comp.engine.bench.Bench`), so a find is judged by
the same code, against the same camera model, wherever the match is played.
"""
from __future__ import annotations

from typing import Any

from robo_comp.errors import FieldError, NotYoursError
from robo_comp.scoring.board import Scoreboard
from robo_comp.world.scenario import Scenario
from robo_comp.world.visibility import in_view

#: At most this many pictures may be cited by one find.
MAX_EVIDENCE = 32


class FindJudge:
    """The pictures every team took and the finds they reported, with the truth to judge them.

    ``pictures`` maps a picture id to its record (``id``, ``tag``, ``team``, pose, ``victims``
    seen); ``examined`` maps a team to the victims its pictures show (victim id → picture ids);
    ``finds`` holds every reported find with its verdict, in order.
    """

    def __init__(self, scenario: Scenario, teams: list[str], board: Scoreboard) -> None:
        self.scenario = scenario
        self.board = board
        self.victims = [v.to_dict() for v in scenario.victims]
        self.pictures: dict[int, dict[str, Any]] = {}
        self.examined: dict[str, dict[str, set[int]]] = {t: {} for t in teams}
        self.finds: list[dict[str, Any]] = []
        self.next_picture = 1

    def victims_seen(self, x: float, y: float, heading: float) -> list[str]:
        """Ids of the victims the scenario's camera sees from pose (x, y, heading)."""
        cam = self.scenario.camera
        pts = [(v["x"], v["y"]) for v in self.victims]
        flags = in_view(self.scenario.walls, pts, x, y, heading, cam.fov, cam.range)
        return [v["id"] for v, f in zip(self.victims, flags) if f]

    def describe(self, ids: list[str]) -> list[dict[str, Any]]:
        """What a camera shows of the victims ``ids``: their cell and kind (no id, no points)."""
        by_id = {v["id"]: v for v in self.victims}
        return [{"x": int(round(by_id[i]["x"])), "y": int(round(by_id[i]["y"])), "kind": by_id[i]["kind"]}
                for i in ids]

    def picture(self, team: str, tag: int, x: float, y: float, heading: float,
                **meta: Any) -> dict[str, Any]:
        """Record a picture taken at the true pose (x, y, heading); return its record with a
        new ``id`` and the ``victims`` in view, which now count as examined by ``team``."""
        pid = self.next_picture
        self.next_picture += 1
        seen = self.victims_seen(x, y, heading)
        for vid in seen:
            self.examined.setdefault(team, {}).setdefault(vid, set()).add(pid)
        record = {"id": pid, "tag": tag, "team": team, "x": x, "y": y, "heading": heading, **meta,
                  "victims": seen}
        self.pictures[pid] = record
        return record

    def restore_picture(self, record: dict[str, Any]) -> None:
        """Take back a picture recorded earlier (recovery from the event log)."""
        pid = int(record["id"])
        self.pictures[pid] = dict(record)
        self.next_picture = max(self.next_picture, pid + 1)
        for vid in record.get("victims", []):
            self.examined.setdefault(record["team"], {}).setdefault(vid, set()).add(pid)

    def check_evidence(self, team: str, evidence: Any) -> list[int]:
        """The cited picture ids, checked: a list of at most 32 ids of ``team``'s own pictures."""
        if type(evidence) is not list or not all(type(e) is int for e in evidence) or len(evidence) > MAX_EVIDENCE:
            raise FieldError(f"'evidence' must be a list of at most {MAX_EVIDENCE} picture ids")
        for pid in evidence:
            meta = self.pictures.get(pid)
            if meta is None or meta["team"] != team:
                raise NotYoursError(f"picture {pid} is not one of team {team}'s pictures")
        return evidence

    def find(self, team: str, tag: int, x: float, y: float, kind: Any, evidence: Any,
             t: float) -> tuple[dict[str, Any], str]:
        """Judge a reported find at match time ``t``: the installed scoring rules decide.

        Returns the find's record (``id``, ``verdict``, ...) and its state: ``confirmed``,
        ``rejected`` or ``duplicate``. Bad evidence raises before anything is recorded.
        """
        evidence = self.check_evidence(team, evidence)
        find: dict[str, Any] = {"team": team, "tag": tag, "x": float(x), "y": float(y),
                                "kind": str(kind or "")[:32], "evidence": evidence}
        verdict = self.board.judge(find, {"victims": self.victims, "examined": self.examined.setdefault(team, {})})
        record = dict(find, id=len(self.finds) + 1, verdict=verdict, t=t)
        self.finds.append(record)
        state = "confirmed" if verdict["valid"] else ("duplicate" if verdict.get("duplicate") else "rejected")
        return record, state


__all__ = ["FindJudge", "MAX_EVIDENCE"]
