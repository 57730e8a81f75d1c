"""Shared helpers of the headless-browser tests (the event viewer's, the labelling page's): Debian's
chromium driven by Playwright, nothing downloaded.

:func:`playwright_or_skip` skips the test with one line when Playwright or the browser is missing,
except under ``CI=true``, where it fails instead (``.ci/run`` installs both).
"""
from __future__ import annotations

import os

import pytest

from bench.bench_viewer import chromium_path


def playwright_or_skip():
    """``(sync_playwright, chromium executable)``, or the test skipped (failed on CI)."""
    on_ci = os.environ.get("CI", "").lower() == "true"
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        if on_ci:
            pytest.fail("CI=true but playwright is not installed (.ci/run installs it)")
        pytest.skip("playwright not installed (pip install -e '.[view]')")
    exe = chromium_path()
    if exe is None or not os.path.exists(exe):
        if on_ci:
            pytest.fail("CI=true but no chromium browser (apt-get install -y chromium)")
        pytest.skip("no chromium browser (apt-get install chromium)")
    return sync_playwright, exe


def open_page(browser, url, viewport=None):
    """A new page at ``url`` and the list its console errors and page errors are appended to."""
    page = browser.new_page(viewport=viewport or {"width": 1400, "height": 1000})
    errors = []
    page.on("console", lambda m: errors.append(f"console {m.type}: {m.text}")
            if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
    page.goto(url)
    return page, errors


def wait_until(page, condition: str, timeout_ms: int = 15000):
    """Wait until the JavaScript ``condition`` holds in the page. (Not ``wait_for_function``: it
    evaluates its predicate with ``eval``, which the pages' content security policy forbids.)"""
    page.evaluate("""([t]) => new Promise((ok, bad) => {
      const t0 = performance.now();
      (function poll() {
        if (%s) ok(true);
        else if (performance.now() - t0 > t) bad(new Error("timed out: " + %r));
        else setTimeout(poll, 10);
      })();
    })""" % (condition, condition), [timeout_ms])
