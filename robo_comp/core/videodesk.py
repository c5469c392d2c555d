"""The videos robots film (``examineArea``), at the core: kept like pictures, shown to their team.

What a video is to the match (its id, the pose it is judged at, the ``video`` event) is
:class:`robo_comp.match.videos.Videos`' (the engine has it too); this desk proves who sends
(only a robot's own host), checks the file (WebM, at most ``MAX_VIDEO`` bytes), keeps it in
``STATE/videos/ID.webm`` (the organiser's, 0600) and gives it to whoever may see it (the team
that filmed it, the referee).
"""
from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from robo_comp import protocol as P
from robo_comp.core.desk import Access, Outbox
from robo_comp.errors import FieldError, NotYoursError, TooLargeError
from robo_comp.match.videos import MAX_VIDEO
from robo_comp.private_files import private_dir, write_private
from robo_comp.teams.policy import check_owner
from robo_comp.world.video import WEBM_MAGIC


class VideoDesk:
    """The ``video`` (robot hosts) and ``video.get`` (consoles, walls, the web) handlers."""

    def __init__(self, access: Access, out: Outbox, state_dir: Path) -> None:
        self.access = access
        self.out = out
        self.folder = state_dir / "videos"

    def handlers(self) -> dict[str, Callable[[bytes, P.Message], dict[str, Any] | None]]:
        """Request handlers this module adds to the core."""
        return {"video": self._on_video, "video.get": self._on_get}

    def _on_video(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        b = msg.body
        r = self.access.hosted(ident, b["tag"])
        data = b["webm"]
        if len(data) > MAX_VIDEO:
            raise TooLargeError(f"a video may be at most {MAX_VIDEO // 1024} KiB")
        if not data.startswith(WEBM_MAGIC):
            raise FieldError("'webm' must be a WebM video")
        videos = self.access.match.videos
        write_private(private_dir(self.folder) / f"{videos.next_id}.webm", data)
        rec = self.access.match.video(r, b, seconds=float(b.get("seconds", 0.0)), frames=int(b.get("frames", 0)),
                                      label=str(b.get("label", ""))[:64], sha256=hashlib.sha256(data).hexdigest()[:16])
        return {"id": rec["id"]}

    def _on_get(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        rec = self.access.match.videos.records.get(msg.body["id"])
        if rec is None:
            raise NotYoursError(f"there is no video {msg.body['id']} of team {who.name}")
        check_owner(who, rec["tag"], rec["team"])
        return dict(rec, webm=(self.folder / f"{rec['id']}.webm").read_bytes())
