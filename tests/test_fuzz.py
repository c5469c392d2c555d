"""Fuzzing (issue 9, part 4): the decoder, the scenario parser and a live core never fail
with anything but their own errors.

* :func:`robo_comp.protocol.decode` on arbitrary bytes and on msgpack maps with the right
  envelope but arbitrary (wrong) fields: a :class:`Message` or a ``RoboCompError`` subclass.
* :func:`robo_comp.world.scenario.parse_scenario` on arbitrary text and on mutations of
  ``demo_room.toml``: a scenario or a ``ScenarioError``.
* one live core (the ``core`` fixture) fed generated frames over a real DEALER socket: every
  frame gets exactly one reply (none for an accepted notification), never ``E_INTERNAL``, and
  the core keeps serving.

Examples are few (``max_examples``) so the file runs in well under 20 s; ``bench/fuzz_atheris.py``
fuzzes the decoder and the parser for as long as one wants. Crashes found by fuzzing are kept
here as plain tests with the reproducer inline (see docs/fuzzing.md).
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import msgpack
import pytest
import zmq
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robo_comp.client import Client
from robo_comp import protocol as P
from robo_comp.protocol.curve import secure_plain_client
from robo_comp.errors import RoboCompError, ScenarioError
from robo_comp.world.scenario import parse_scenario

DEMO = Path(__file__).resolve().parents[1] / "robo_comp" / "world" / "scenarios" / "demo_room.toml"
DEMO_TEXT = DEMO.read_text()
FAST = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# ---------------------------------------------------------------------------- strategies
#: Scalars msgpack can carry (ints within its 64-bit range).
scalars = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-(2**63), max_value=2**64 - 1),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=20), st.binary(max_size=20))
#: Arbitrary nested values (maps keyed by strings, as the decoder's strict_map_key wants, and
#: sometimes by other scalars, which it must refuse cleanly).
values = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4),
                            st.dictionaries(st.text(max_size=8), inner, max_size=4),
                            st.dictionaries(st.integers(-5, 5), inner, max_size=2)),
    max_leaves=12)
#: Known message types and a few unknown ones.
types = st.one_of(st.sampled_from(sorted(P.REQUESTS)), st.text(max_size=12), values)


@st.composite
def bodies(draw: st.DrawFn, type_: str) -> dict[str, Any]:
    """A body for ``type_`` using its real field names with arbitrary values, plus extras."""
    names = list(P.REQUESTS.get(type_, {})) + ["tag", "x", "task", "args", "token"]
    chosen = draw(st.lists(st.sampled_from(names), unique=True, max_size=len(names)))
    body = {n: draw(values) for n in chosen}
    body.update(draw(st.dictionaries(st.text(max_size=6), values, max_size=2)))
    return body


@st.composite
def envelopes(draw: st.DrawFn) -> dict[Any, Any]:
    """A map shaped like a request (``v``, ``type``, ``id``, ``body``) with arbitrary field values."""
    type_ = draw(types)
    env: dict[Any, Any] = {
        "v": draw(st.one_of(st.just(P.PROTOCOL_VERSION), values)),
        "type": type_,
        "id": draw(st.one_of(st.integers(0, 2**31), values)),
    }
    if draw(st.booleans()):
        env["body"] = draw(bodies(type_)) if isinstance(type_, str) else draw(values)
    elif draw(st.booleans()):
        env["body"] = draw(values)
    for k in draw(st.lists(st.sampled_from(["v", "type", "id"]), max_size=1)):
        del env[k]
    return env


def packed(obj: Any) -> bytes:
    """msgpack bytes of ``obj`` (as a client would send them)."""
    return msgpack.packb(obj, use_bin_type=True)


def decode_ok(frame: bytes) -> P.Message | RoboCompError:
    """Decode ``frame``; return the message or the RoboCompError (anything else propagates)."""
    try:
        return P.decode(frame)
    except RoboCompError as e:
        assert e.code.startswith("E_") and isinstance(e.message, str)
        return e


# ---------------------------------------------------------------------------- decoder
@FAST
@given(st.binary(max_size=200))
def test_decode_arbitrary_bytes(frame: bytes) -> None:
    """Garbage bytes: a message or a RoboCompError, nothing else."""
    decode_ok(frame)


@FAST
@given(values)
def test_decode_arbitrary_msgpack(value: Any) -> None:
    """Any msgpack value: only maps can be messages."""
    out = decode_ok(packed(value))
    if not isinstance(value, dict):
        assert isinstance(out, RoboCompError)


@settings(max_examples=400, deadline=None)
@given(envelopes())
def test_decode_envelopes_with_wrong_fields(env: dict[Any, Any]) -> None:
    """The right envelope with wrong fields: a valid Message has the declared field types."""
    out = decode_ok(packed(env))
    if isinstance(out, P.Message) and out.type != "reply":
        for name, (kind, _req) in P.REQUESTS[out.type].items():
            if name in out.body and kind in ("int", "str", "bool", "list", "map", "bytes"):
                want = {"int": int, "str": str, "bool": bool, "list": list, "map": dict, "bytes": bytes}[kind]
                assert type(out.body[name]) is want


@st.composite
def report_batches(draw: st.DrawFn) -> dict[str, Any]:
    """A ``reports`` body: lists of mostly good rows, sometimes a bad value or a short list."""
    n = draw(st.integers(0, 6))
    good = {"tags": st.integers(101, 200), "x": st.floats(0, 50), "y": st.floats(0, 50),
            "heading": st.floats(0, 360), "moving": st.booleans(),
            "sensors": st.one_of(st.none(), st.dictionaries(st.text(max_size=4), scalars, max_size=2))}
    body: dict[str, Any] = {}
    for name, good_value in good.items():
        if name in ("moving", "sensors") and draw(st.booleans()):
            continue
        length = n if draw(st.integers(0, 9)) else draw(st.integers(0, 7))
        body[name] = [draw(st.one_of(good_value, scalars) if draw(st.integers(0, 9)) == 0 else good_value)
                      for _ in range(length)]
    return body


@FAST
@given(report_batches())
def test_a_batch_of_reports_passes_whole_or_names_its_bad_row(body: dict[str, Any]) -> None:
    """``check_reports`` either accepts every row as the core will use it, or says which is wrong."""
    frame = packed({"v": P.PROTOCOL_VERSION, "type": "reports", "id": 0, "body": body})
    msg = decode_ok(frame)
    assert isinstance(msg, P.Message)
    try:
        n = P.check_reports(msg.body)
    except RoboCompError as e:
        assert e.code == "E_FIELD" and ("'reports'" in e.message)
        return
    assert n == len(body["tags"])
    for name in ("x", "y", "heading"):
        assert len(body[name]) == n and all(type(v) in (int, float) and math.isfinite(v) for v in body[name])
    assert all(type(t) is int for t in body["tags"])
    assert all(type(m) is bool for m in body.get("moving", ()))


def test_decode_oversized_and_deep_frames() -> None:
    """Edge frames: over the size limit, deeply nested, truncated, several maps."""
    deep: Any = 0
    for _ in range(5000):
        deep = [deep]
    for frame in (b"\x81" * (P.MAX_FRAME + 1), b"\x91" * 100_000, packed({"v": 2})[:-1],
                  packed({"v": 2}) + packed({"v": 2}), b"\xc1", b"\xdd\xff\xff\xff\xff"):
        assert isinstance(decode_ok(frame), RoboCompError)
    try:
        frame = packed({"v": P.PROTOCOL_VERSION, "type": "robots", "id": 1, "body": {"x": deep}})
    except (ValueError, RecursionError):
        return  # msgpack itself refuses to build it
    decode_ok(frame)


# ---------------------------------------------------------------------------- scenario parser
def parse_ok(text: str) -> None:
    """Parse ``text``; success or ScenarioError only."""
    try:
        parse_scenario(text, "fuzz.toml", base_dir=DEMO.parent)
    except ScenarioError as e:
        assert "fuzz.toml" in str(e)


@settings(max_examples=100, deadline=None)
@given(st.text(max_size=300))
def test_scenario_arbitrary_text(text: str) -> None:
    """Arbitrary text: a scenario or a ScenarioError."""
    parse_ok(text)


LINES = DEMO_TEXT.splitlines()
toml_values = st.one_of(
    st.integers(-(2**70), 2**70).map(str), st.floats().map(lambda f: repr(f).replace("inf", "inf")),
    st.sampled_from(["true", "false", '""', "[]", "{}", "[1, 2]", '"x"', "1979-05-27", "nan", "-inf",
                     "0", "-1", "1e400", '"""\n#\n"""', "[[1]]", "{a = 1}"]),
    st.text(max_size=10).map(lambda s: '"' + s.replace("\\", "").replace('"', "") + '"'))


@st.composite
def mutated_scenarios(draw: st.DrawFn) -> str:
    """demo_room.toml with a few lines mutated: a value replaced, a key renamed, a line
    dropped, duplicated or swapped, or a map row edited."""
    lines = list(LINES)
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, len(lines) - 1))
        op = draw(st.sampled_from(["value", "key", "drop", "dup", "swap", "chars", "row"]))
        line = lines[i]
        if op == "value" and "=" in line:
            lines[i] = line.split("=", 1)[0] + "= " + draw(toml_values)
        elif op == "key" and "=" in line:
            lines[i] = draw(st.sampled_from(["name", "cell_size", "x", "y", "w", "h", "kind", "id", "zzz",
                                             "map", "duration", "radius", "teams"])) + " =" + line.split("=", 1)[1]
        elif op == "drop":
            del lines[i]
        elif op == "dup":
            lines.insert(i, line)
        elif op == "swap":
            j = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        elif op == "chars":
            lines[i] = draw(st.text(alphabet="#.=[]\"'{}, 0123456789abcxyz\t", max_size=30))
        elif op == "row" and line.startswith("#") and line.endswith("#"):
            k = draw(st.integers(0, len(line) - 1))
            lines[i] = line[:k] + draw(st.sampled_from(["#", ".", "", "..", "?", "V", "S"])) + line[k + 1:]
        if not lines:
            lines = [""]
    return "\n".join(lines) + "\n"


@settings(max_examples=150, deadline=None)
@given(mutated_scenarios())
def test_scenario_mutations(text: str) -> None:
    """Mutated valid scenarios: a scenario or a ScenarioError."""
    parse_ok(text)


def test_demo_room_parses() -> None:
    """The seed of the mutations is itself valid."""
    parse_scenario(DEMO_TEXT, str(DEMO))


# ---------------------------------------------------------------------------- live core
class Raw:
    """A raw DEALER socket on a core: send frames, collect replies until a marker reply."""

    def __init__(self, url: str, token: str) -> None:
        self.sock = zmq.Context.instance().socket(zmq.DEALER)
        self.sock.setsockopt(zmq.LINGER, 0)
        self.sock.setsockopt(zmq.ROUTING_ID, P.new_routing_id())
        secure_plain_client(self.sock, token)  # the core lets in no connection without a token
        self.sock.connect(url)
        self.marker = 1_000_000
        self.session: str | None = None  # learnt from the hello/register reply

    def call(self, type_: str, body: dict[str, Any], id_: int = 1) -> dict[str, Any]:
        """Send a well-formed request (with the session secret, once there is one) and return its reply."""
        self.sock.send(P.request(type_, id_, body, self.session))
        reply = self.replies_until(id_)[-1]
        if reply.get("ok") and isinstance(reply.get("body"), dict) and "session" in reply["body"]:
            self.session = reply["body"]["session"]
        return reply

    def send(self, frame_map: dict[str, Any]) -> None:
        """Send a hand-made message map, with this connection's session secret added."""
        self.sock.send(packed(dict(frame_map, s=self.session) if self.session else frame_map))

    def replies_until(self, marker: int, timeout: float = 5.0) -> list[dict[str, Any]]:
        """Replies read until the one with id ``marker`` (included); pushes are skipped."""
        out = []
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            if not self.sock.poll(100):
                continue
            m = P.unpack(self.sock.recv())
            if m.get("type") != "reply":
                continue
            out.append(m)
            if m.get("id") == marker:
                return out
        raise AssertionError(f"no reply with id {marker} within {timeout} s (got {out!r:.300})")

    def fuzz(self, frames: list[bytes]) -> list[dict[str, Any]]:
        """Send ``frames`` as one message, then a marker ``robots`` request; return the replies
        that came before the marker's."""
        self.marker += 1
        if self.session and len(frames) == 1:  # a session's own frames carry its secret, so
            frames = [_with_session(frames[0], self.session)]  # the fuzz reaches the handlers
        self.sock.send_multipart(frames)
        self.sock.send(P.request("tasks", self.marker, {"tag": -1}, self.session))
        return self.replies_until(self.marker)[:-1]

    def close(self) -> None:
        """Close the socket."""
        self.sock.close(0)


def _with_session(frame: bytes, session: str) -> bytes:
    """``frame`` with the session secret added, when it is a msgpack map without one."""
    try:
        obj = msgpack.unpackb(frame, raw=False, strict_map_key=False)
    except Exception:
        return frame
    if not isinstance(obj, dict) or "s" in obj:
        return frame
    obj["s"] = session
    return packed(obj)


#: Types that, when valid, get no reply (notifications and host replies).
SILENT = P.NOTIFICATIONS | {"reply"}


def _may_be_silent(frames: list[bytes]) -> bool:
    """True when a frame could be a valid notification (which gets no reply)."""
    if len(frames) != 1:
        return False
    try:
        msg = P.decode(frames[0])
    except RoboCompError:
        return False
    return msg.type in SILENT


def _is_bye(frames: list[bytes]) -> bool:
    """A valid ``bye``: accepted from a connection without a session (it ends nothing)."""
    if len(frames) != 1:
        return False
    try:
        return P.decode(frames[0]).type == "bye"
    except RoboCompError:
        return False


frames_st = st.one_of(
    st.binary(max_size=64).map(lambda b: [b]),
    envelopes().map(lambda e: [packed(e)]),
    st.lists(st.binary(max_size=16), min_size=2, max_size=3),
)


@pytest.mark.heartbeat(1.0)
def test_live_core_answers_every_fuzzed_frame(core: Any) -> None:
    """One core, many sessions' worth of generated frames: one error reply each (no reply for
    an accepted notification), never E_INTERNAL, and the core still serves a real client."""
    url = Client(str(core.state), core.token("referee")).url
    anon, team, host = Raw(url, core.token("red")), Raw(url, core.token("red")), Raw(url, core.host_token("red"))
    assert team.call("hello", {"token": core.token("red")})["ok"]
    reg = host.call("register", {"token": core.host_token("red"), "robot_id": "fz-1", "tasks": []}, 2)
    assert reg["ok"]
    seen: dict[str, int] = {}

    @settings(max_examples=120, deadline=None, suppress_health_check=list(HealthCheck))
    @given(frames_st, st.booleans())
    def check(frames: list[bytes], as_team: bool) -> None:
        raw = team if as_team else anon
        replies = raw.fuzz(frames)
        codes = [r["error"]["code"] for r in replies if not r.get("ok")]
        for c in codes:
            seen[c] = seen.get(c, 0) + 1
        assert "E_INTERNAL" not in codes, (frames, replies)
        if not as_team and not _is_bye(frames):  # an unauthenticated connection can do nothing right
            assert all(not r.get("ok") for r in replies), (frames, replies)
        if _may_be_silent(frames):
            assert len(replies) <= 1, (frames, replies)
        else:
            assert len(replies) == 1, (frames, replies)

    try:
        check()
    finally:
        anon.close()
        team.close()
        host.close()
    ref = core.client("referee")
    assert ref.request("stats")["received"] > 120
    assert any(r["robot_id"] == "fz-1" for r in ref.robots())
    assert seen.get("E_MALFORMED", 0) > 0


# ---------------------------------------------------------------------------- crashes found
STOP_WAIT = 4.0  # the core's own stop timeout is 2 s


def _host_with_robot(core: Any) -> tuple[Raw, int, str]:
    """A raw robot host of team red with one registered robot: (socket, tag, url)."""
    url = Client(str(core.state), core.token("referee")).url
    host = Raw(url, core.host_token("red"))
    assert host.call("hello", {"token": core.host_token("red")})["ok"]
    reg = host.call("register", {"token": core.host_token("red"), "robot_id": "h-1", "tasks": []}, 2)
    return host, reg["body"]["tag"], url


def _stop_request_id(host: Raw, timeout: float = 3.0) -> int:
    """Wait for the core's ``stop`` request on a raw host; return its id."""
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if host.sock.poll(100):
            m = P.unpack(host.sock.recv())
            if m.get("type") == "stop":
                return m["id"]
    raise AssertionError("the host got no stop request")


@pytest.mark.heartbeat(1.0)
@pytest.mark.parametrize("reply", [
    {"v": 2, "type": "reply", "ok": False, "error": "boom"},
    {"v": 2, "type": "reply", "ok": True, "body": [1, 2]},
])
def test_malformed_stop_confirmation_still_answers_the_requester(core: Any, reply: dict[str, Any]) -> None:
    """Reproducer found by fuzzing host replies: a host confirms a stop with a malformed reply
    (``error`` a string, or ``body`` a list). The core must answer the host with E_FIELD (not
    E_INTERNAL) and still answer the referee who asked for the stop."""
    host, tag, url = _host_with_robot(core)
    ref = Raw(url, core.token("referee"))
    try:
        assert ref.call("hello", {"token": core.token("referee")})["ok"]
        ref.sock.send(P.request("stop", 77, {"tag": tag}, ref.session))
        cid = _stop_request_id(host)
        host.send(dict(reply, id=cid))  # e.g. b'\x85\xa1v\x02\xa4type\xa5reply...'
        host.sock.send(P.request("tasks", 5, {"tag": tag}, host.session))
        host_replies = host.replies_until(5)[:-1]
        assert all(r["error"]["code"] != "E_INTERNAL" for r in host_replies), host_replies
        answer = ref.replies_until(77, timeout=STOP_WAIT)[-1]  # ok or error, but an answer
        assert answer["id"] == 77
    finally:
        host.close()
        ref.close()


@pytest.mark.heartbeat(1.0)
def test_other_team_cannot_confirm_a_stop(core: Any) -> None:
    """Team blue answers the core's stop request for red's robot (the core's request ids are
    small sequential integers, easy to guess) with a made-up position: the core must ignore
    it, and the robot must not be moved to (-999, -999)."""
    host, tag, url = _host_with_robot(core)
    blue, ref = Raw(url, core.token("blue")), Raw(url, core.token("referee"))
    try:
        assert blue.call("hello", {"token": core.token("blue")})["ok"]
        assert ref.call("hello", {"token": core.token("referee")})["ok"]
        ref.sock.send(P.request("stop", 77, {"tag": tag}, ref.session))
        cid = _stop_request_id(host)  # blue would guess it: 1, 2, 3, ...
        blue.send({"v": 2, "type": "reply", "id": cid, "ok": True,
                   "body": {"x": -999.0, "y": -999.0, "heading": 0.0}})
        time.sleep(0.2)
        mon = ref.call("monitor", {"tag": tag}, 78)
        assert (mon["body"]["x"], mon["body"]["y"]) != (-999.0, -999.0)
    finally:
        host.close()
        blue.close()
        ref.close()
