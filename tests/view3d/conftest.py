"""The 3-D view's browser tests share one Debian Chromium per test module."""

from __future__ import annotations

import pytest

from tests.view3d.browser_support import launch


@pytest.fixture(scope="module")
def browser():
    """A headless Chromium, started once for the module's tests."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        chromium = launch(p)
        yield chromium
        chromium.close()
