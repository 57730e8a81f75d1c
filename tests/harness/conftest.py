"""Fixtures of the harness tests: ``browser``, headless chromium for the pages' tests
(:mod:`browser_pages`; the test is skipped with one line without Playwright or the browser, and
fails instead under ``CI=true``)."""
from __future__ import annotations

import pytest

from browser_pages import playwright_or_skip


@pytest.fixture(scope="module")
def browser():
    """A headless chromium (Debian's, driven by Playwright), one per test module."""
    sync_playwright, exe = playwright_or_skip()
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=exe, args=["--no-sandbox"])
        yield b
        b.close()
