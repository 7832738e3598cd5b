"""What the 3-D view costs its page, in Debian's Chromium: a page busy for seconds (what a loaded
machine does to a page drawing with software WebGL) gets no backlog of updates, and gets
updates again at the sender's rate once it is free; a moving arm costs the page no new shader
program per update."""

from __future__ import annotations

import numpy as np
import pytest

from tests.poll import wait_for
from tests.view3d.browser_support import needs_chromium
from tests.view3d.view_page import LEFT_MODEL, MAGENTA, View
from umbra.connectors.limits import MAX_PAGE_IN_FLIGHT, PAGE_ACK_TIMEOUT_S
from umbra.connectors.messages import Image, JointState

pytestmark = [pytest.mark.browser, needs_chromium]

MAX_FPS = 20.0
BUSY_S = 3 * PAGE_ACK_TIMEOUT_S  #: how long the page's main thread is kept busy [s]
#: the most updates a page busy for BUSY_S may be sent: those on their way, one per answer that
#: came PAGE_ACK_TIMEOUT_S late, one racing in
MOST_WHILE_BUSY = MAX_PAGE_IN_FLIGHT + int(BUSY_S / PAGE_ACK_TIMEOUT_S) + 1
#: counts the shader programs the page links: ``window.__linked``
COUNT_LINKS = """window.__linked = 0;
for (const Context of [WebGL2RenderingContext, WebGLRenderingContext]) {
  const link = Context.prototype.linkProgram;
  Context.prototype.linkProgram = function (...args) {
    window.__linked += 1;
    return link.apply(this, args);
  };
}"""
#: wraps the page's websocket worker: ``window.__batches`` holds the wall time [ms] at which the
#: page took each batch of messages
COUNT_BATCHES = """window.__batches = [];
const PageWorker = window.Worker;
window.Worker = function (url, options) {
  const worker = new PageWorker(url, options);
  worker.addEventListener('message', (e) => {
    if (e.data && e.data.type === 'message_batch') window.__batches.push(Date.now());
  });
  return worker;
};"""
BUSY = """(busy_ms) => {
  const from = Date.now();
  while (Date.now() - from < busy_ms) {}
  return [from, Date.now()];
}"""


class CountingBrowser:
    """The browser whose new pages count the batches they take and the programs they link."""

    def __init__(self, browser) -> None:
        self.browser = browser

    def new_page(self, **options):
        page = self.browser.new_page(**options)
        page.add_init_script(COUNT_BATCHES)
        page.add_init_script(COUNT_LINKS)
        return page


def test_a_busy_page_gets_no_backlog_and_then_the_full_rate(browser, tmp_path) -> None:
    view = View(CountingBrowser(browser), {"port": 0, "max_fps": MAX_FPS}, tmp_path)
    try:
        image = np.zeros((480, 640, 3), np.uint8)
        image[:] = MAGENTA[::-1]
        view.feed("left_model", LEFT_MODEL)
        view.feed("left_image", Image(pixels=image))
        push, pace = view.module.push, view.module.page.pace
        wait_for(lambda: push.updates > 20, 30.0, "the page to take updates", interval_s=0.05)

        sent_before, late_before = push.updates, pace.late
        busy_from_ms, busy_to_ms = view.page.evaluate(BUSY, BUSY_S * 1e3)
        sent_while_busy = push.updates - sent_before
        # at the sender's rate: BUSY_S * MAX_FPS = 60 updates
        assert sent_while_busy <= MOST_WHILE_BUSY, sent_while_busy
        assert pace.late > late_before  # the busy page answered after the timeout: went on
        # the page took what had come while it was busy at once: an update and a question each,
        # not a backlog
        batches = np.array(view.page.evaluate("window.__batches"))
        backlog = int(np.sum((batches >= busy_to_ms) & (batches < busy_to_ms + 200)))
        assert backlog <= 2 * MOST_WHILE_BUSY, backlog

        # free again: updates at the sender's rate, each answered
        sent_after, answered_after = push.updates, pace.answers
        wait_for(
            lambda: push.updates - sent_after >= 20,
            20.0,
            "updates again once the page is free",
            interval_s=0.05,
        )
        assert pace.answers - answered_after >= 15
        assert busy_to_ms - busy_from_ms >= BUSY_S * 1e3
    finally:
        view.close()


def test_a_moving_arm_links_no_shader_program_per_update(browser, tmp_path) -> None:
    view = View(CountingBrowser(browser), {"port": 0, "max_fps": MAX_FPS}, tmp_path)
    try:
        names = view.module.params.joint_names
        q0 = np.radians([0.0, 45.6, -182.7, 0.0, -42.9, 0.0])
        view.feed("joint_state", JointState(names=names, position=q0))
        push, page = view.module.push, view.module.page
        wait_for(lambda: page._arm is not None, 20.0, "the arm drawn", interval_s=0.05)
        wait_for(lambda: push.updates > 5, 20.0, "updates to the page", interval_s=0.05)
        view.page.wait_for_timeout(500)  # the page's first frames link what it draws
        linked_before, labels_before = view.page.evaluate("window.__linked"), page.labels_sent
        for k in range(20):  # the arm moves 20 times, each shown by an update
            q = q0 + np.radians(2.0 * (k + 1))
            shown = push.updates
            view.feed("joint_state", JointState(names=names, position=q))
            wait_for(lambda s=shown: push.updates > s + 1, 20.0, "an update", interval_s=0.01)
        T_tool = view.module._T_world_base @ view.module.params.table.fk(q)
        T_tool = T_tool @ view.module._T_flange_tool
        # the page shows the arm where it is now: the tool's frame and its label moved there
        assert np.allclose(page._arm_tool.position, T_tool[:3, 3])
        assert np.allclose(page.labels["tool"][1], T_tool[:3, 3])
        assert page.labels_sent - labels_before >= 20
        answered = view.module.page.pace.answers
        wait_for(
            lambda: view.module.page.pace.answers > answered + 1,
            20.0,
            "the page to apply the last updates",
            interval_s=0.05,
        )
        assert view.page.evaluate("window.__linked") == linked_before
    finally:
        view.close()
