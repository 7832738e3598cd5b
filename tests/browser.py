"""Debian's Chromium, driven by Playwright: the one place that says how the browser tests and
benchmarks start it. Never ``playwright install``: it downloads a browser of its own."""

from __future__ import annotations

from pathlib import Path

import pytest

#: Debian's package ``chromium`` (``apt-get install -y chromium``).
CHROMIUM = Path("/usr/bin/chromium")
#: Headless, and no calls home (this machine has no network but the package registries).
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]

needs_chromium = pytest.mark.skipif(
    not CHROMIUM.exists(),
    reason=f"needs Debian's Chromium at {CHROMIUM} (apt-get install chromium)",
)


def launch(playwright: object) -> object:
    """A headless Chromium browser from a started ``sync_playwright()``."""
    return playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
