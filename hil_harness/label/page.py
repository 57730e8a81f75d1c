"""The labelling page: its body (``page.html``), style (``page.css``) and script (``page.js``),
package data, in the harness's page document (:func:`hil_harness.webpage.page_document`). The page
holds no data: it fetches the session (``data.json``) and each frame (``frames/<g>``) from its
server and posts every change (:mod:`.server`)."""
from __future__ import annotations

from importlib.resources import files

from hil_harness.webpage import page_document

__all__ = ["page_html", "page_js"]


def _resource(name: str) -> str:
    return files("hil_harness.label").joinpath(name).read_text(encoding="utf-8")


def page_js() -> str:
    """The page's script (``page.js``), as the page holds it."""
    return _resource("page.js")


def page_html() -> str:
    """The page."""
    return page_document("uvisi label", _resource("page.css"), _resource("page.html"), page_js())
