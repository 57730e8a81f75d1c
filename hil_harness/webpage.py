"""The document every page of the harness is built as (the event viewer's, ``uvisi view``; the
labelling page's, ``uvisi label``): one HTML file whose only script is its own inline one, run by
its SHA-256 under a content security policy that allows nothing else, its style inline, and nothing
loaded from anywhere but its own server.

The document is put together by concatenation: no value (a title, a body holding a recording's
texts) is ever searched for a placeholder or parsed as anything but what it is. The servers that
serve such pages (``uvisi view --serve``, ``uvisi label``) listen on :data:`HOST` only, answer only
the ``Host`` values of :func:`allowed_hosts` and send every answer through :func:`send_reply`.
"""
from __future__ import annotations

import base64
import hashlib
import html

from hil_harness.console import debug

__all__ = ["content_security_policy", "page_document", "allowed_hosts", "send_reply", "HOST"]

#: the only address the pages' servers listen on
HOST = "127.0.0.1"


def content_security_policy(js: str) -> str:
    """The policy of a page whose script is ``js``: only that script runs (by its SHA-256, as
    :func:`page_document` places it, between two newlines), no inline event handler, no other
    source; styles inline; images only from ``data:`` (the empty icon); requests to the page's own
    server only; no form, no base. A server adds ``frame-ancestors 'none'`` in its header."""
    digest = base64.b64encode(hashlib.sha256(f"\n{js}\n".encode("utf-8")).digest()).decode()
    return (f"default-src 'none'; script-src 'sha256-{digest}'; style-src 'unsafe-inline'; "
            f"img-src data:; connect-src 'self'; base-uri 'none'; form-action 'none'")


def page_document(title: str, css: str, body: str, js: str) -> str:
    """The page: ``title`` (plain text: escaped here), ``css``, ``body`` (the HTML between the
    body tags, as given) and ``js`` (its one script, last in the body), with the policy of
    :func:`content_security_policy` in a ``meta`` element."""
    policy = html.escape(content_security_policy(js))
    return "".join((
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n',
        f'<meta http-equiv="Content-Security-Policy" content="{policy}">\n',
        '<link rel="icon" href="data:,">\n',
        f"<title>{html.escape(title)}</title>\n<style>\n{css}\n</style>\n</head>\n<body>\n",
        body, f"\n<script>\n{js}\n</script>\n</body>\n</html>\n"))


def allowed_hosts(port: int) -> frozenset:
    """The ``Host`` header values (lower case) a page's server answers: its own address by IP and
    by ``localhost``, with its port (a page of another site that a DNS rebinding points at
    127.0.0.1 sends its own name)."""
    return frozenset({f"{HOST}:{int(port)}", f"localhost:{int(port)}"})


def send_reply(handler, code: int, body: bytes, ctype: str, csp: str, tool: str) -> None:
    """Answer ``handler``'s request (an ``http.server.BaseHTTPRequestHandler``) with ``body`` of
    type ``ctype``, never cached, ``nosniff``, under the policy ``csp``; a browser that went away
    before the answer is one debug line naming ``tool`` and the path."""
    handler.send_response(code)
    for name, value in (("Content-Type", ctype), ("Content-Length", str(len(body))),
                        ("Cache-Control", "no-store"), ("X-Content-Type-Options", "nosniff"),
                        ("Content-Security-Policy", csp)):
        handler.send_header(name, value)
    handler.end_headers()
    try:
        handler.wfile.write(body)
    except (BrokenPipeError, ConnectionResetError):
        debug(f"{tool}: {handler.path}: the browser went away before the answer")
