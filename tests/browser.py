"""One way to start the system Chromium for the browser tests (Playwright's own downloads are
not reachable here): skipped where Playwright or the Debian ``chromium`` binary is missing."""

from __future__ import annotations

import shutil
from collections.abc import Iterator

import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
"""The system Chromium, or None."""

ARGS = ("--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
        "--disable-component-update", "--disable-sync")
"""Flags for a headless run in CI, with nothing fetched from the network."""


def chromium(*extra_args: str) -> Iterator:
    """Yield a launched Chromium (``ARGS`` plus ``extra_args``), closed afterwards: a fixture's body."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed (make install)")
    if CHROMIUM is None:
        pytest.skip("no chromium binary (Debian package 'chromium'; .ci/run installs it)")
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=[*ARGS, *extra_args])
        try:
            yield browser
        finally:
            browser.close()
