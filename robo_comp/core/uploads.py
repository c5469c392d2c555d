"""Uploads of team code through the core: ownership, phase, approval, forwarding, verdicts.

A team (or the referee) sends ``upload`` with the robots' tags, a file name and the module's
source. The core checks that every robot is the sender's and connected and that the phase
allows uploads, keeps a copy of the source under ``STATE/uploads/<team>/``, logs it (with the
source's SHA-256: the event log says which code ran when) and forwards it to each robot's host,
where the module is checked and loaded in the team's sandbox (``robo_comp/robots/teamcode.py``).
The reply comes when every host has answered: per robot ``ok`` or the checked error (file,
line, rule). With ``approve_uploads`` a team's upload during a running match waits for the
referee's ``approve``; its verdict then reaches the team as an ``upload.done`` event.

``unload`` takes a module away from robots; ``extensions`` lists a robot's modules.
"""
from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robo_comp import protocol as P
from robo_comp.core.desk import Access, Outbox
from robo_comp.match.registry import RobotRecord
from robo_comp.protocol.states import Phase, RobotStatus
from robo_comp.errors import (
    FieldError, ForbiddenError, NotYoursError, RoboCompError, UnavailableError, UploadError,
)
from robo_comp.sandbox import contract

#: Most robots one upload may go to.
MAX_TAGS = 64
#: How long the core waits for the robots' hosts to answer an upload.
HOST_TIMEOUT = 20.0


@dataclass(slots=True)
class HostAsk:
    """A request forwarded to one or more robot hosts; ``done`` runs once all have answered.
    ``waiting`` maps each forwarded request id to (the host asked, the robots it was asked about)."""

    waiting: dict[int, tuple[bytes, list[int]]]
    deadline: float
    results: list[dict[str, Any]]
    done: Callable[[list[dict[str, Any]]], None]


@dataclass(slots=True)
class PendingUpload:
    """An upload waiting for the referee's approval."""

    upload_id: int
    team: str
    by: str
    tags: list[int]
    body: dict[str, Any]
    t: float = field(default_factory=time.time)


class UploadDesk:
    """The core's upload service: handlers, the forwarding to hosts and their answers."""

    def __init__(self, access: Access, out: Outbox, state_dir: Path, approve_uploads: bool = False) -> None:
        self.access = access
        self.out = out
        self.contest = access.match.contest
        self.approve_uploads = approve_uploads
        self.asks: dict[int, HostAsk] = {}  # by forwarded request id (an ask spanning hosts: several)
        self.pending: dict[int, PendingUpload] = {}
        self.next_upload = 1
        self.folder = state_dir / "uploads"

    def handlers(self) -> dict[str, Callable[[bytes, P.Message], dict[str, Any] | None]]:
        """Request handlers this module adds to the core."""
        return {"upload": self._on_upload, "unload": self._on_unload, "extensions": self._on_extensions,
                "approve": self._on_approve, "advertise": self._on_advertise, "log": self._on_log, "draw": self._on_draw,
                "sandbox.reset": self._on_sandbox_reset}

    # ------------------------------------------------------------------ checks
    def _robots(self, ident: bytes, tags: Any) -> list[RobotRecord]:
        if not tags or not all(type(t) is int for t in tags):
            raise FieldError("'tags' must be a non-empty list of robot tags, e.g. [101, 102]")
        if len(tags) > MAX_TAGS:
            raise FieldError(f"one upload may go to at most {MAX_TAGS} robots")
        robots = [self.access.robot_for(ident, t) for t in dict.fromkeys(tags)]
        for r in robots:
            if r.status != RobotStatus.CONNECTED or r.session is None:
                raise UnavailableError(f"robot {r.tag} is {r.status}; uploads reach connected robots only")
        return robots

    @staticmethod
    def _source(body: dict[str, Any]) -> tuple[str, str]:
        """The file name and source, checked by the contract's own first rules (the robots'
        sandboxes check everything again): a refusal names the file and the rule."""
        filename = body["filename"]
        try:
            return contract.check_filename(filename), contract.check_source(body["source"])
        except contract.ContractError as e:
            raise contract.upload_error(str(filename)[:80], e.rule, e.detail) from None

    # ------------------------------------------------------------------ requests
    def _on_upload(self, ident: bytes, msg: P.Message) -> dict[str, Any] | None:
        s = self.access.session(ident)
        robots = self._robots(ident, msg.body["tags"])
        self.contest.check_phase("upload")
        filename, source = self._source(msg.body)
        sha = contract.source_hash(source)
        team = robots[0].team
        if any(r.team != team for r in robots):
            raise FieldError("one upload goes to robots of one team; send one per team")
        self._keep(team, filename, sha, source)
        body = {"filename": filename, "source": source, "sha256": sha, "run": bool(msg.body.get("run"))}
        tags = [r.tag for r in robots]
        if (self.approve_uploads and s.who.role == "team"
                and self.contest.phase is Phase.RUNNING):
            uid = self.next_upload
            self.next_upload += 1
            self.pending[uid] = PendingUpload(uid, team, s.who.name, tags, body)
            self.out.emit("upload.pending", team, {"upload_id": uid, "team": team, "tags": tags,
                                                    "filename": filename, "sha256": sha, "by": s.who.name})
            return {"pending": uid, "results": [],
                    "message": f"{filename} waits for the referee's approval (upload {uid})"}
        self._forward(robots, body, s.who.name, lambda results: self._reply(ident, msg.id, filename, results))
        return None  # the reply goes out when the hosts have answered

    def _on_approve(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        s = self.access.session(ident)
        if s.who.role != "referee":
            raise ForbiddenError("only the referee approves or blocks uploads")
        uid = msg.body["upload_id"]
        p = self.pending.pop(uid, None)
        if p is None:
            raise FieldError(f"no upload {uid} waits for approval")
        ok = bool(msg.body.get("ok", True))
        if not ok:
            self.out.emit("upload.done", p.team, {"upload_id": uid, "team": p.team, "tags": p.tags,
                                                   "filename": p.body["filename"], "ok": False,
                                                   "message": f"{p.body['filename']}: blocked by the referee"})
            return {"upload_id": uid, "ok": False}
        robots = [self.access.registry.robots[t] for t in p.tags if t in self.access.registry.robots]
        robots = [r for r in robots if r.status == RobotStatus.CONNECTED and r.session is not None]
        if not robots:
            raise UnavailableError(f"none of upload {uid}'s robots is connected now")
        self._forward(robots, p.body, p.by, lambda results: None, upload_id=uid)
        return {"upload_id": uid, "ok": True}

    def _on_unload(self, ident: bytes, msg: P.Message) -> dict[str, Any] | None:
        robots = self._robots(ident, msg.body["tags"])
        name = msg.body["name"]
        self._ask(robots, "unload", {"name": name}, lambda results: self._unloaded(ident, msg.id, name, results))
        return None

    def _on_extensions(self, ident: bytes, msg: P.Message) -> dict[str, Any] | None:
        robots = self._robots(ident, [msg.body["tag"]])

        def done(results: list[dict[str, Any]]) -> None:
            row = results[0] if results else {"ok": False, "message": "no answer"}
            if row.get("ok"):
                self.out.send(ident, P.ok_reply(msg.id, {"tag": robots[0].tag, "modules": row.get("modules", [])}))
            else:
                self.out.send(ident, P.error_reply(msg.id, UnavailableError(str(row.get("message")))))
        self._ask(robots, "extensions", {}, done)
        return None

    def _on_sandbox_reset(self, ident: bytes, msg: P.Message) -> dict[str, Any] | None:
        """Referee: restart the team-code sandbox of these robots' hosts now (ends a cool-down)."""
        s = self.access.session(ident)
        if s.who.role != "referee":
            raise ForbiddenError("only the referee restarts a team's sandbox (it ends a cool-down early)")
        robots = self._robots(ident, msg.body["tags"])

        def done(results: list[dict[str, Any]]) -> None:
            self.out.emit("sandbox.reset", robots[0].team, {"tags": [r.tag for r in robots], "by": s.who.name,
                                                             "results": results})
            self.out.send(ident, P.ok_reply(msg.id, {"results": results}))
        self._ask(robots, "sandbox.reset", {}, done)
        return None

    # ------------------------------------------------------------------ from robot hosts
    def _on_advertise(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        self._set_tasks(self.access.hosted(ident, msg.body["tag"]), msg.body["tasks"])
        return {}

    def _set_tasks(self, r: RobotRecord, adverts: list[Any]) -> None:
        """What robot ``r`` advertises from now on (checked like at registration)."""
        self.access.match.advertise(r, adverts)

    def _on_log(self, ident: bytes, msg: P.Message) -> None:
        tag = msg.body.get("tag")
        s = self.access.session(ident)
        if tag is not None:
            self.access.hosted(ident, tag)
        self.out.emit("robot.log", s.who.team, {"tag": tag, "stream": msg.body["stream"][:16],
                                                 "text": msg.body["text"][:2000]})
        return None

    def _on_draw(self, ident: bytes, msg: P.Message) -> None:
        """A host's new frames of debug drawing: checked again here (robo_comp/protocol/drawing.py),
        logged as ``debug.draw`` for the team's own views and the referee only."""
        from robo_comp.protocol.drawing import clean_frame

        s = self.access.session(ident)
        tags, frames = msg.body["tags"], msg.body["frames"]
        if len(tags) != len(frames) or len(tags) > P.MAX_REPORTS:
            raise FieldError("draw: 'tags' and 'frames' must be lists of the same length")
        for tag in tags:
            self.access.hosted(ident, tag)  # only the host's own robots draw
        self.out.emit("debug.draw", s.who.team,
                      {"team": s.who.team, "tags": list(tags), "frames": [clean_frame(f) for f in frames]})
        return None

    def host_reply(self, ident: bytes, cid: int, raw: dict[str, Any]) -> bool:
        """Host ``ident`` answered request ``cid``; True when it was one of ours (from that host)."""
        ask = self.asks.get(cid)
        if ask is None:
            return False
        host, tags = ask.waiting[cid]
        if host != ident:
            raise NotYoursError("this connection was not asked; only the robots' host answers")
        del self.asks[cid], ask.waiting[cid]
        body, err = raw.get("body"), raw.get("error")
        if not isinstance(body, (dict, type(None))) or not isinstance(err, (dict, type(None))):
            raw, err = {"ok": False}, {"message": "the robot's host sent a malformed answer"}
        if raw.get("ok"):
            rows = (body or {}).get("results")
            if isinstance(rows, list):
                ask.results.extend(r for r in rows if isinstance(r, dict))
            else:
                ask.results.append(dict(body or {}, ok=True))
        else:
            ask.results.extend({"tag": t, "ok": False, "message": str((err or {}).get("message"))} for t in tags)
        if not ask.waiting:
            ask.done(ask.results)
        return True

    def expire(self, now: float) -> None:
        """Answer for hosts that did not answer in time."""
        for ask in {id(a): a for a in self.asks.values()}.values():
            if now < ask.deadline:
                continue
            for cid, (_, tags) in ask.waiting.items():
                del self.asks[cid]
                ask.results.extend({"tag": t, "ok": False,
                                    "message": f"robot {t}'s host did not answer within {HOST_TIMEOUT:.0f} s"}
                                   for t in tags)
            ask.waiting.clear()
            ask.done(ask.results)

    @property
    def busy(self) -> bool:
        """True while an answer from a host is awaited (the core polls more often)."""
        return bool(self.asks)

    # ------------------------------------------------------------------ internals
    def _ask(self, robots: list[RobotRecord], type_: str, body: dict[str, Any],
             done: Callable[[list[dict[str, Any]]], None]) -> None:
        by_host: dict[bytes, list[int]] = {}
        for r in robots:
            if r.session is not None:  # the callers pass connected robots: all have a host
                by_host.setdefault(r.session, []).append(r.tag)
        ask = HostAsk({}, time.monotonic() + HOST_TIMEOUT, [], done)
        for host, tags in by_host.items():
            cid = self.out.new_request_id()
            ask.waiting[cid] = (host, tags)
            self.asks[cid] = ask
            self.out.send(host, P.request(type_, cid, dict(body, tags=tags)))

    def _forward(self, robots: list[RobotRecord], body: dict[str, Any], by: str,
                 reply: Callable[[list[dict[str, Any]]], None], upload_id: int | None = None) -> None:
        team = robots[0].team
        self.out.emit("upload.sent", team, {"tags": [r.tag for r in robots], "filename": body["filename"],
                                             "sha256": body["sha256"], "by": by, "upload_id": upload_id})

        def done(results: list[dict[str, Any]]) -> None:
            results.sort(key=lambda row: row.get("tag", 0))
            self._advertised(results)
            ok = bool(results) and all(row.get("ok") for row in results)
            first_error = next((row for row in results if not row.get("ok")), None)
            good = [row for row in results if row.get("ok")]
            self.out.emit("upload.done", team, {
                "upload_id": upload_id, "team": team, "tags": [row.get("tag") for row in results],
                "filename": body["filename"], "sha256": body["sha256"], "ok": ok, "by": by,
                "module": good[0].get("name") if good else None, "version": good[0].get("version") if good else None,
                "message": (first_error or {}).get("message") or f"{body['filename']} loaded on "
                                                                 f"{len(good)} robot(s)"})
            if body.get("run"):
                self._run_now(good, by)
            reply(results)
        self._ask(robots, "upload", {"filename": body["filename"], "source": body["source"]}, done)

    def _advertised(self, results: list[dict[str, Any]]) -> None:
        """Robots that took a module advertise its tasks from now on (before anyone is answered)."""
        for row in results:
            r = self.access.registry.robots.get(row.get("tag", -1))
            adverts = row.pop("advertised", None)
            if r is None or not row.get("ok") or not isinstance(adverts, list):
                continue
            try:
                self._set_tasks(r, adverts)
            except RoboCompError as e:
                row.update(ok=False, message=f"robot {r.tag} advertised tasks the core refuses: {e.message}")

    def _run_now(self, rows: list[dict[str, Any]], by: str) -> None:
        """``run``: give each robot the module's first task now (code that "runs now")."""
        for row in rows:
            first = next(iter(row.get("tasks") or ()), None)  # the manifest's first task
            r = self.access.registry.robots.get(row.get("tag", -1))
            if first is None or r is None:
                continue
            try:
                self.access.match.give(r, first, [], queue=False, by=by)
            except RoboCompError as e:
                self.out.emit("refused", r.team, {"by": by, "type": "upload", "code": e.code,
                                                   "message": f"could not run {first} on robot {r.tag}: "
                                                              f"{e.message}"})

    def _reply(self, ident: bytes, req_id: int, filename: str, results: list[dict[str, Any]]) -> None:
        bad = [row for row in results if not row.get("ok")]
        if bad and len(bad) == len(results):
            first = bad[0]
            err = UploadError(str(first.get("message") or f"{filename}: refused"),
                              file=first.get("file", filename), line=first.get("line"),
                              rule=first.get("rule") or "upload", results=results)
            self.out.send(ident, P.error_reply(req_id, err))
            return
        self.out.send(ident, P.ok_reply(req_id, {"results": results, "ok": not bad}))

    def _unloaded(self, ident: bytes, req_id: int, name: str, results: list[dict[str, Any]]) -> None:
        tags = sorted(t for row in results if row.get("ok") for t in row.get("unloaded", []))
        if not tags:
            self.out.send(ident, P.error_reply(req_id, NotYoursError(
                f"no robot of these has a module called {name!r} (see 'extensions TAG')")))
            return
        self.out.emit("upload.unloaded", self.access.registry.robots[tags[0]].team, {"tags": tags, "name": name})
        self.out.send(ident, P.ok_reply(req_id, {"name": name, "tags": tags}))

    def _keep(self, team: str, filename: str, sha: str, source: str) -> None:
        """A copy of every uploaded source, by hash, for the organisers and recovery."""
        folder = self.folder / team
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        for d in (self.folder, folder):  # a team's code is its own: private, like the tokens
            os.chmod(d, 0o700)
        path = folder / f"{sha[:16]}-{filename}"
        if not path.exists():
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            with os.fdopen(fd, "w", encoding="utf-8", errors="surrogatepass") as f:
                f.write(source)
