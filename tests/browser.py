"""Debian's Chromium, driven by Playwright: the one place that says how the browser tests and
benchmarks start it. Never ``playwright install``: it downloads a browser of its own."""

from __future__ import annotations

from pathlib import Path

import pytest

from umbra.modules.world.trial_faults import CHROMIUM as CHROMIUM_PATH
from umbra.modules.world.trial_faults import CHROMIUM_FLAGS

#: Debian's package ``chromium`` (``apt-get install -y chromium``), headless and with no calls
#: home (this machine has no network but the package registries): the same flags the overload
#: trials open the operator's page with, declared once in ``umbra.modules.world.trial_faults``.
CHROMIUM = Path(CHROMIUM_PATH)
CHROMIUM_ARGS = list(CHROMIUM_FLAGS)

needs_chromium = pytest.mark.skipif(
    not CHROMIUM.exists(),
    reason=f"needs Debian's Chromium at {CHROMIUM} (apt-get install chromium)",
)


def launch(playwright: object) -> object:
    """A headless Chromium browser from a started ``sync_playwright()``."""
    return playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
