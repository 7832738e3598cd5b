"""How long a page waits on a silent run: one declaration (``PAGE_SILENT_S``), told to the page
in the console's welcome, and the console's state rate bounded by it."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from tests.operator.helpers import Page
from umbra.modules.operator.console import OperatorConsole
from umbra.modules.operator.console_params import PAGE_SILENT_S, ConsoleParams
from umbra.runtime.harness import ModuleHarness


def test_the_page_is_told_how_long_to_wait_on_a_silent_run() -> None:
    with ModuleHarness(OperatorConsole, {}, frames={"tool->camera": np.eye(4)}) as h:
        page = Page(h.module.url)
        try:
            assert page.welcome["silent_s"] == PAGE_SILENT_S
        finally:
            page.ws.close()


def test_a_state_rate_that_would_leave_a_page_silent_is_refused() -> None:
    """Two page updates at least in the time a page waits: slower, every page would drop its
    socket as half-open between two updates."""
    assert ConsoleParams(state_rate_hz=2.0 / PAGE_SILENT_S).state_rate_hz == 0.4
    with pytest.raises(ValidationError, match="state_rate_hz"):
        ConsoleParams(state_rate_hz=0.39)
