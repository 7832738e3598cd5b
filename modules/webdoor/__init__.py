"""The door of the operator's web pages: who gets in, and how much anyone can make them hold.

Every page server of a graph (the console's and the Active Sketch page's: one
:class:`~umbra.modules.operator.web_server.WebServer` per process) serves behind this door:

- the access rules it shares with the live server (:mod:`umbra.connectors.access`): the per-run
  access token, the ``Host`` names the server was started for and the ``Origin`` of its own
  pages, a page socket's message budget;
- ``gate.py``: the ASGI middleware in front of every route and socket: Host, Origin, token (the
  address's token exchanged for an HttpOnly, SameSite=Strict cookie, then a redirect to the
  address without it), POST only with the cookie and the page's own Origin (or the CSRF header),
  request bodies refused past their limit before they are read;
- ``transport.py``: uvicorn's protocols with a connection limit per server and per client address
  and a deadline on a request head that never completes;
- ``viewer.py``: the viewer cookie that makes one browser one operator.

Every size and time limit is declared once, in :mod:`umbra.connectors.limits`.
"""
