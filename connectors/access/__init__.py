"""Who may connect, and how much a client may send: the access rules every server of a run
shares (the operator's page servers in ``modules/webdoor``, the live server in ``runtime/live``).

- ``secret.py``: the per-run access token (printed in the address, as Jupyter does), compared in
  constant time; loopback is no exception;
- ``hosts.py``: the ``Host`` names a server was started for and the ``Origin`` of its own pages
  (DNS rebinding and other sites' pages get nothing);
- ``rate.py``: a socket's budget of incoming messages (rate, burst, malformed messages).

Pure rules, below both the runtime and the modules; every size and time limit is declared once,
in :mod:`umbra.connectors.limits`.
"""
