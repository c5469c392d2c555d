"""The match in a browser: a web gateway that streams a core's feed (or a recorded match) to pages.

``robo-comp web --core URL`` joins a core through the public client and serves a page (plain ES
modules and a canvas, no build step) over HTTP and WebSocket; ``robo-comp web --replay LOG``
serves a recorded match with play, pause, speed and seeking. See ``docs/web.md``.
"""
