"""The document every page of the harness is built as (the event viewer's, ``uvisi view``; the
labelling page's, ``uvisi label``): one HTML file whose only script is its own inline one, run by
its SHA-256 under a content security policy that allows nothing else, its style inline, and nothing
loaded from anywhere but its own server.

The document is put together by concatenation: no value (a title, a body holding a recording's
texts) is ever searched for a placeholder or parsed as anything but what it is.
"""
from __future__ import annotations

import base64
import hashlib
import html

__all__ = ["content_security_policy", "page_document"]


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
