"""The operator's station (Umbra side): a live console in the browser with the operator in the loop.

``OperatorConsole`` (``console.py``) serves the page; the web server it runs on can host other
modules' pages too (``web_server.py``). Everything the page decides is pure logic in small files
(``control.py``, ``protocol.py``, ``jog.py``, ``actions.py``, ``view_state.py``) that tests use
without a browser.
"""
