"""``uvisi view --serve``: the page of a recording too large to inline, served from 127.0.0.1.

The page carries the per-frame data (tables, candidates, TP state: ~2 kB a frame) and fetches each
frame's image, stages and stars when it is shown, never all of them up front. Routes (GET)::

    /                the page (no images inside)
    /data.json       the page's data (:func:`.data.extract`)
    /frames/<k>      frame k packed (:func:`.codec.pack`: deflated byte planes of uint16[244, 256])
    /stars/<k>       frame k's catalogued stars, JSON ``[[row, col, mag]...]`` (null: not recorded)
    /stages/<k>      frame k's stage images, JSON ``{"stages": [{"name", "shape", "dtype", "data"}],
                     "mismatch": first frame the replay did not reproduce or null, "error": why
                     the replay could not run or null}``, replayed in frame order on demand
                     (:class:`.stages.StageReplay`) and ahead of the requests in a thread

Anything else is 404; a frame number outside the recording is 404 with a one-line reason. The
server listens on 127.0.0.1 only and answers only requests whose ``Host`` header is
``127.0.0.1:PORT`` or ``localhost:PORT`` (a page of another site that a DNS rebinding points at
127.0.0.1 sends its own name): others get 403 with one line. It reads nothing but its recording
(no route names a file), and its answers carry the page's content security policy and
``nosniff``.
"""
from __future__ import annotations

import re
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

from hil_harness.console import debug
from hil_harness.webpage import HOST, allowed_hosts, content_security_policy, send_reply

from .data import FrameStars, extract, open_recording
from .page import frame_bytes, page_html, page_js, script_json
from .stages import StageReplay, stage_note

#: frames whose stage images the server keeps (~40-250 kB each): memory bounded whatever the
#: event's length; a frame evicted is replayed again on request
STAGE_CACHE_FRAMES = 256
_ROUTE = re.compile(r"^/(frames|stages|stars)/(\d+)$")


class ViewServer(ThreadingHTTPServer):
    """A threading HTTP server holding one open recording (``url``, ``close()``)."""

    daemon_threads = True

    def __init__(self, recording, port: int, checksums: str = "verify"):
        self.rec = open_recording(recording, checksums)
        try:
            self.data = extract(self.rec, with_stars=False)        # stars fetched per frame
            self.stars = FrameStars(self.rec)
            self.stage_replay = StageReplay(self.rec, capacity=STAGE_CACHE_FRAMES)
            self._last_request = 0                    # the viewer's frame: replay ahead of it
            self.data["stage_mismatch"] = None
            self.data["stage_note"] = stage_note(self.data, replayed=True)
            self.page = page_html(self.data, {"mode": "serve"}).encode("utf-8")
            self.csp = content_security_policy(page_js())
            self.data_json = script_json(self.data).encode("utf-8")
            self.lock = threading.Lock()
            self._closing = threading.Event()
            self._waiting = 0                         # requests waiting for the lock
            self._count_lock = threading.Lock()
            super().__init__((HOST, int(port)), ViewHandler)
        except BaseException:
            self.rec.close()
            raise
        self._ahead = threading.Thread(target=self._replay_ahead, daemon=True)
        self._ahead.start()

    def _replay_ahead(self) -> None:
        """Replay the stages of the frames ahead of the last one asked for, in the background, one
        frame per lock and at most half the cache (:data:`STAGE_CACHE_FRAMES`) ahead, so that
        stepping on finds them ready and memory stays bounded (a request for a later frame replays
        up to it, one for an evicted frame again from the start). A request waiting for the lock
        goes first (Python's lock is not fair)."""
        while not self._closing.is_set():
            if self._waiting:
                time.sleep(0.002)
                continue
            sr = self.stage_replay
            if sr.next_k >= self._last_request + STAGE_CACHE_FRAMES // 2:
                time.sleep(0.02)                      # far enough ahead of the viewer
                continue
            with self.lock:
                if self._closing.is_set() or not sr.advance():
                    return

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.server_address[1]}/"

    def frame(self, k: int) -> bytes:
        return frame_bytes(self.rec, k)             # h5py serialises its own calls

    def stages(self, k: int) -> bytes:
        with self._count_lock:
            self._waiting += 1
        self.lock.acquire()
        with self._count_lock:
            self._waiting -= 1
        try:
            self._last_request = k
            st = self.stage_replay.get(k)
            return script_json({"stages": st, "mismatch": self.stage_replay.mismatch,
                                "error": self.stage_replay.error}).encode("utf-8")
        finally:
            self.lock.release()

    def server_close(self) -> None:
        self._closing.set()
        super().server_close()
        with self.lock:
            self.rec.close()


class ViewHandler(BaseHTTPRequestHandler):
    server: ViewServer

    def _send(self, code: int, body: bytes, ctype: str) -> None:
        send_reply(self, code, body, ctype, self.server.csp + "; frame-ancestors 'none'",
                   "uvisi view")

    def do_GET(self) -> None:                                   # noqa: N802 (http.server's name)
        srv, path = self.server, self.path.split("?", 1)[0]
        host = (self.headers.get("Host") or "").strip().lower()
        if host not in allowed_hosts(srv.server_address[1]):
            return self._send(403, b"this server answers only requests for 127.0.0.1:PORT or "
                                   b"localhost:PORT (the Host header)\n", "text/plain")
        if path in ("/", "/index.html"):
            return self._send(200, srv.page, "text/html; charset=utf-8")
        if path == "/data.json":
            return self._send(200, srv.data_json, "application/json")
        m = _ROUTE.match(path)
        if m is None:
            return self._send(404, f"{path}: not found\n".encode(), "text/plain")
        kind, k = m.group(1), int(m.group(2))
        n = srv.data["recording"]["frames_held"]
        if k >= n:
            return self._send(404, f"frame {k}: the recording holds frames 0-{n - 1}\n".encode(),
                              "text/plain")
        if kind == "frames":
            if not srv.data["recording"]["has_frames"]:
                return self._send(404, b"recorded with --no-frames: no images\n", "text/plain")
            return self._send(200, srv.frame(k), "application/octet-stream")
        if kind == "stars":
            st = srv.stars.get(k)
            return self._send(200, script_json(st).encode("utf-8"), "application/json")
        return self._send(200, srv.stages(k), "application/json")

    def log_message(self, fmt, *args) -> None:
        debug("uvisi view: " + fmt % args)


def make_server(recording, port: int = 8765, checksums: str = "verify") -> ViewServer:
    """A :class:`ViewServer` of ``recording`` bound to 127.0.0.1:``port`` (0: a free port);
    call ``serve_forever()`` and, when done, ``server_close()``. ``checksums``: as
    :class:`hil_harness.event.recording.Recording` takes it."""
    if not 0 <= int(port) <= 65535:
        raise ValueError(f"--port {port}: must be 0..65535")
    return ViewServer(Path(recording), port, checksums)
