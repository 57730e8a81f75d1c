"""The labelling page's server: 127.0.0.1 only, one :class:`.session.LabelSession`.

Routes::

    GET  /              the page (:func:`.page.page_html`)
    GET  /data.json     the session: files, frames with their shapes, labels, counts
    GET  /frames/<g>    frame g (global, 0-based): float32 little-endian, row-major, its shape in
                        data.json (NaN where the file has no value)
    POST /label         {"frame": g, "kind": "point", "row": r, "col": c} | {"frame": g, "kind":
                        "absent" | "clear"} -> {"frame", "label", "counts"}; the file is
                        rewritten before the answer
    POST /done          -> {"summary"}; the server stops after answering

The server answers only requests whose ``Host`` is ``127.0.0.1:PORT`` or ``localhost:PORT`` (a
site that a DNS rebinding points here sends its own name), and a POST only with a JSON body from
its own page (``Origin`` of one of those two, ``Content-Type: application/json``: a form on
another site can send neither): others get 403 with one line. A bad POST gets 400 with
``{"error": one line}``. Answers carry the page's content security policy and ``nosniff``.
"""
from __future__ import annotations

import json
import re
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from hil_harness.console import debug
from hil_harness.webpage import HOST, allowed_hosts, content_security_policy, send_reply

from .page import page_html, page_js
from .session import LabelSession

__all__ = ["LabelServer", "make_server", "page_data", "label_json", "HOST", "MAX_POST_BYTES"]

#: the largest POST body read (a label is ~60 bytes)
MAX_POST_BYTES = 4096
_FRAME = re.compile(r"^/frames/(\d+)$")


def page_data(session: LabelSession) -> dict:
    """What the page is given: ``files`` ([{name, sha256, frames}]), ``frames`` ([[file index,
    frame in file, rows, cols]] by global frame), ``labels`` (by global frame: [row, col],
    ``"absent"`` or null for unlabelled), ``counts``, ``out`` and ``labeller``."""
    inputs = session.inputs
    frames = [[i, k, *inputs.files[i].shapes[k]] for i, k in inputs.index]
    return {"files": [{"name": f.name, "sha256": f.sha256, "frames": len(f.shapes)}
                      for f in inputs.files],
            "frames": frames, "labels": [label_json(session.label(g)) for g in range(len(inputs))],
            "counts": session.counts(), "out": str(session.out), "labeller": session.labeller}


def label_json(label):
    """A label as the page takes it: ``[row, col]``, ``"absent"``, or None (unlabelled)."""
    if label == "unlabelled":
        return None
    return "absent" if label is None else [label[0], label[1]]


class LabelServer(ThreadingHTTPServer):
    """A threading HTTP server of one labelling session (``url``; ``done`` is set by the page's
    Done button, after which the server stops)."""

    daemon_threads = True

    def __init__(self, session: LabelSession, port: int):
        self.session = session
        self.csp = content_security_policy(page_js()) + "; frame-ancestors 'none'"
        self.page = page_html().encode("utf-8")
        self.done = threading.Event()
        super().__init__((HOST, int(port)), LabelHandler)

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.server_address[1]}/"

    def finish_soon(self) -> None:
        """Stop serving once the answer in progress is sent (from a thread of its own:
        ``shutdown`` waits for ``serve_forever``'s loop)."""
        self.done.set()
        threading.Thread(target=self.shutdown, daemon=True).start()


class LabelHandler(BaseHTTPRequestHandler):
    server: LabelServer

    def _reply(self, code: int, body: bytes, ctype: str) -> None:
        send_reply(self, code, body, ctype, self.server.csp, "uvisi label")

    def _json(self, code: int, obj) -> None:
        self._reply(code, json.dumps(obj, allow_nan=False).encode("utf-8"), "application/json")

    def _refused(self, post: bool) -> str | None:
        """Why a request is refused (403), or None."""
        hosts = allowed_hosts(self.server.server_address[1])
        host = (self.headers.get("Host") or "").strip().lower()
        if host not in hosts:
            return "this server answers only requests for 127.0.0.1:PORT or localhost:PORT"
        if post:
            origin = (self.headers.get("Origin") or "").strip().lower()
            ctype = (self.headers.get("Content-Type") or "").split(";")[0].strip().lower()
            if origin not in {"http://" + h for h in hosts} or ctype != "application/json":
                return "a change is taken only as JSON from the labelling page itself"
        return None

    def do_GET(self) -> None:                                   # noqa: N802 (http.server's name)
        why = self._refused(post=False)
        if why:
            return self._reply(403, why.encode() + b"\n", "text/plain")
        path, srv = self.path.split("?", 1)[0], self.server
        if path in ("/", "/index.html"):
            return self._reply(200, srv.page, "text/html; charset=utf-8")
        if path == "/data.json":
            return self._json(200, page_data(srv.session))
        m = _FRAME.match(path)
        if m is None:
            return self._reply(404, f"{path}: not found\n".encode(), "text/plain")
        g, n = int(m.group(1)), len(srv.session.inputs)
        if g >= n:
            return self._reply(404, f"frame {g}: the session holds frames 0-{n - 1}\n".encode(),
                               "text/plain")
        try:
            data = srv.session.inputs.frame(g).astype("<f4", copy=False).tobytes()
        except ValueError as exc:                   # the file was changed or removed meanwhile
            return self._reply(500, str(exc).splitlines()[0].encode() + b"\n", "text/plain")
        return self._reply(200, data, "application/octet-stream")

    def do_POST(self) -> None:                                  # noqa: N802
        why = self._refused(post=True)
        if why:
            return self._reply(403, why.encode() + b"\n", "text/plain")
        path, srv = self.path.split("?", 1)[0], self.server
        if path not in ("/label", "/done"):
            return self._reply(404, f"{path}: not found\n".encode(), "text/plain")
        try:
            body = self._body()
            if path == "/done":
                self._json(200, {"summary": srv.session.summary()})
                return srv.finish_soon()
            g = body.get("frame")
            label = srv.session.set_label(g, body.get("kind"), body.get("row"), body.get("col"))
        except ValueError as exc:
            return self._json(400, {"error": str(exc).splitlines()[0]})
        except OSError as exc:
            return self._json(500, {"error": f"{srv.session.out}: not written ("
                                             f"{exc.strerror or exc}); the label is not kept"})
        return self._json(200, {"frame": g, "label": label_json(label),
                                "counts": srv.session.counts()})

    def _body(self) -> dict:
        n = int(self.headers.get("Content-Length") or 0)
        if not 0 <= n <= MAX_POST_BYTES:
            raise ValueError(f"a body of {n} bytes: at most {MAX_POST_BYTES}")
        try:
            body = json.loads(self.rfile.read(n) or b"{}")
        except (UnicodeDecodeError, json.JSONDecodeError):
            raise ValueError("the body is not JSON") from None
        if not isinstance(body, dict):
            raise ValueError("the body must be a JSON object")
        return body

    def log_message(self, fmt, *args) -> None:
        debug("uvisi label: " + fmt % args)


def make_server(session: LabelSession, port: int) -> LabelServer:
    """A :class:`LabelServer` of ``session`` bound to 127.0.0.1:``port`` (0: a free port); call
    ``serve_forever()`` and, when it returns or is interrupted, ``server_close()``. ``OSError``
    when the port cannot be had."""
    if not 0 <= int(port) <= 65535:
        raise ValueError(f"--port {port}: must be 0..65535")
    return LabelServer(session, port)
