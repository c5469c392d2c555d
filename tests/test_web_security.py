"""The web gateway against other sites and hostile messages (docs/security.md, "The web gateway").

A page served from another origin, in Debian's Chromium, tries to open the gateway's WebSocket
and join a team's view offered with ``--view-token-file``; raw HTTP and WebSocket clients send
forged ``Origin``/``Host`` headers and messages nested too deep to read.
"""
from __future__ import annotations

import asyncio
import http.server
import json
import socket
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("starlette", reason="the web extra is not installed (pip install -e '.[web]')")

from test_web import browser, in_thread, live, start_web, stop  # noqa: F401  -- fixtures shared with test_web

#: The other site's page: it opens the gateway's WebSocket, tries to join red's offered view
#: (which needed no secret before) and then the public one, and reports what it got.
HOSTILE_PAGE = """<!doctype html><meta charset="utf-8"><title>another site</title><script>
window.result = new Promise(done => {
  const out = {opened: false, messages: [], closed: null};
  const ws = new WebSocket(%(ws)s);
  ws.onopen = () => {
    out.opened = true;
    ws.send(JSON.stringify({op: "join", view: "red"}));
    ws.send(JSON.stringify({op: "join", view: "red", key: ""}));
  };
  ws.onmessage = e => out.messages.push(JSON.parse(e.data));
  ws.onclose = e => { out.closed = e.code; done(out); };
  setTimeout(() => { ws.close(); done(out); }, 30000);  // a loaded machine: the close event decides
});
</script>"""


@pytest.fixture()
def other_site() -> Iterator[tuple[str, list[str]]]:
    """An HTTP server on another port of 127.0.0.1 (another origin) serving :data:`HOSTILE_PAGE`
    for the gateway URL given in the path: yields its origin and a list to put that URL in."""
    target: list[str] = []

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802  -- the standard library's name
            body = (HOSTILE_PAGE % {"ws": json.dumps(target[0])}).encode()
            self.send_response(200)
            self.send_header("Content-Type", "text/html; charset=utf-8")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: Any) -> None:
            pass

    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    t = threading.Thread(target=srv.serve_forever, daemon=True)
    t.start()
    try:
        yield f"http://127.0.0.1:{srv.server_address[1]}", target
    finally:
        srv.shutdown()
        srv.server_close()


def hostile_visit(browser: Any, origin: str) -> dict[str, Any]:
    """Chromium opens the other site's page and waits for what it got from the gateway."""
    page = browser.new_page()
    try:
        page.goto(origin + "/")
        return page.evaluate("() => window.result")  # type: ignore[no-any-return]
    finally:
        page.close()


def test_a_page_of_another_site_cannot_join(browser, live, other_site) -> None:  # noqa: F811
    """Cross-site WebSocket hijacking: a page of another origin in a real Chromium cannot open
    ``/ws`` at all, so it reads neither red's offered view nor the public one through a visitor."""
    m, url = live
    origin, target = other_site
    target.append(url.replace("http", "ws") + "ws")
    got = hostile_visit(browser, origin)
    assert not got["opened"] and got["messages"] == [], got
    assert got["closed"] == 1006  # refused in the handshake (HTTP 403), before any message


def test_an_allowed_origin_still_needs_the_view_key(browser, live, other_site) -> None:  # noqa: F811
    """With ``--allow-origin`` the other site's page may connect, and still gets no private view
    without its key: only the public view."""
    m, _ = live
    origin, target = other_site
    web, url = start_web("--core", str(m.state), "--view-token-file", str(m.token_file("red")),
                         "--allow-origin", origin + "/")
    try:
        target.append(url.replace("http", "ws") + "ws")
        got = hostile_visit(browser, origin)
    finally:
        stop(web)
    assert got["opened"], got
    kinds = [(x.get("type"), x.get("view", {}).get("kind") if isinstance(x.get("view"), dict) else None)
             for x in got["messages"]]
    assert ("state", "private") not in kinds
    refusals = [x for x in got["messages"] if x.get("type") == "error"]
    assert len(refusals) == 2 and all("opens with its link" in x["message"] for x in refusals)


def test_the_own_page_under_its_csp_and_the_view_link(browser, live) -> None:  # noqa: F811
    """The gateway's own page works under its Content-Security-Policy (no violation reported), and
    the link the gateway printed for red's view opens red's private view in Chromium."""
    from robo_comp.web.server import view_key

    m, url = live

    def visit() -> tuple[str, list[str], list[str]]:
        page = browser.new_page()
        violations: list[str] = []
        errors: list[str] = []
        page.on("console", lambda msg: violations.append(msg.text) if "Content Security Policy" in msg.text else None)
        page.on("pageerror", lambda e: errors.append(str(e)))
        try:
            page.goto(f"{url}#view=red&key={view_key(m.token('red'))}")
            page.wait_for_function("() => window.robo && robo.S.view.kind === 'private' "
                                   "&& robo.model.robots.size >= 2", timeout=15000)
            page.wait_for_function("() => document.querySelectorAll('#score-table .swatch').length > 0",
                                   timeout=15000)
            colour = page.evaluate("() => document.querySelector('#score-table .swatch').style.background")
            return page.evaluate("() => robo.S.view.name") + "|" + colour, violations, errors
        finally:
            page.close()

    got, violations, errors = visit()
    name, colour = got.split("|")
    assert name == "red" and colour  # the swatch's colour is set through the DOM, allowed by the CSP
    assert not violations and not errors


def http_get(url: str) -> tuple[int, dict[str, str]]:
    import urllib.request

    with urllib.request.urlopen(url, timeout=10) as r:
        return r.status, {k.lower(): v for k, v in r.headers.items()}


def test_every_response_carries_the_security_headers(live) -> None:
    _, url = live
    for path in ("", "info", "static/app.js", "favicon.ico"):
        status, h = http_get(url + path)
        assert status in (200, 204)
        assert "default-src 'none'" in h["content-security-policy"]
        assert "frame-ancestors 'none'" in h["content-security-policy"]
        assert h["referrer-policy"] == "no-referrer"
        assert h["x-frame-options"] == "DENY"


def raw_upgrade(url: str, host: str, origin: str | None) -> str:
    """A WebSocket handshake by hand (any Host and Origin): the status line of the answer."""
    port = int(url.rstrip("/").rsplit(":", 1)[1])
    lines = ["GET /ws HTTP/1.1", f"Host: {host}", "Upgrade: websocket", "Connection: Upgrade",
             "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==", "Sec-WebSocket-Version: 13"]
    if origin is not None:
        lines.append(f"Origin: {origin}")
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        return s.recv(4096).decode(errors="replace").split("\r\n", 1)[0]


def test_forged_origins_and_dns_rebinding_are_refused(live) -> None:
    """Below the browser: the handshake with another site's Origin, a mismatched Host, or a name of
    another site that resolves here (DNS rebinding: Origin and Host agree) gets HTTP 403; the own
    origin and a client with no Origin (a script, no visitor's session) get in."""
    _, url = live
    hostport = url.split("//", 1)[1].rstrip("/")
    port = hostport.rsplit(":", 1)[1]
    for host, origin in ((hostport, "http://evil.example"), (hostport, "null"),
                         (hostport, f"http://localhost:{port}"),
                         (f"evil.example:{port}", f"http://evil.example:{port}")):
        assert " 403 " in raw_upgrade(url, host, origin) + " ", (host, origin)
    for host, origin in ((hostport, f"http://{hostport}"), (f"localhost:{port}", f"http://localhost:{port}"),
                         (hostport, None)):
        assert " 101 " in raw_upgrade(url, host, origin), (host, origin)


def test_bad_messages_are_answered_not_logged(tmp_path: Path) -> None:
    """Deeply nested JSON (RecursionError), a non-object, and junk fields each get an error reply;
    the connection goes on and the gateway logs no traceback."""
    import websockets

    from test_web import write_log

    log = tmp_path / "m" / "events.log"
    write_log(log, seconds=10)
    web, url = start_web("--replay", str(log))

    async def talk() -> list[dict[str, Any]]:
        out = []
        async with websockets.connect(url.replace("http", "ws") + "ws", max_size=None) as ws:
            await ws.recv()  # hello
            for text in ("[" * 200_000, '{"op": "join", "token": ' + "[" * 100_000 + "]" * 100_000 + "}",
                         "[1, 2]", json.dumps({"op": [[[[1]]]], "req": {"a": 1}}), "{\"a\": " * 100_000):
                await ws.send(text)
                out.append(json.loads(await ws.recv()))
            await ws.send(json.dumps({"op": "join"}))  # the connection still serves
            while True:
                msg = json.loads(await ws.recv())
                if msg.get("type") == "state":
                    out.append(msg)
                    break
        return out

    try:
        got = in_thread(lambda: asyncio.run(talk()))
    finally:
        stop(web)
    output = web.stdout.read() if web.stdout else ""
    deep, deep_token, not_object, junk, braces, state = got
    for m in (deep, deep_token, braces):
        assert m["type"] == "error" and "nested too deeply" in m["message"]
    assert not_object["type"] == "error" and "JSON object" in not_object["message"]
    assert junk["type"] == "error" and junk["error"]["code"] == "E_FIELD" and junk["message"]
    assert state["type"] == "state"
    assert "Traceback" not in output and "RecursionError" not in output, output[-3000:]
