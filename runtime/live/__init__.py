"""Live in Foxglove: a running graph served over the Foxglove WebSocket protocol.

``umbra run GRAPH --foxglove`` serves every output of the run to Foxglove, Lichtblick or any client
of the protocol, with the same schemas, topics and frames as a recording (one encoding table:
``umbra.runtime.recording.encoders``) and a wall-clock time line.

Why a runtime service beside the recording tap, not a module: it must see *every* output (those
that feed nothing too) of every process without being wired into the graph, and a module's
inputs would make the scheduler wait for it, or change the graph a recording or a check sees.

- ``server.py``: one channel per recorded channel, fed from the run's ticks by a bounded hand-off
  (a tick never waits; nothing is encoded for a channel no viewer subscribes to);
- ``viewer_server.py``, ``protocol.py``: the address the run prints, the one socket that serves
  the Foxglove WebSocket protocol (``websockets``), with ``gate.py``'s checks on the upgrade
  request: the per-run token, ``Host`` and ``Origin`` with the operator pages' own rules
  (``umbra.connectors.access``); nothing else listens;
- ``parameters.py``: the module parameters a viewer sees and may change (those declared
  tunable; ``umbra.runtime.tuning`` applies them between steps), and ``param_link.py``: how a change
  reaches a module of another process (the run's tuner, on ``P/_params/<process>``);
- ``feed.py``: where samples come from: the outputs of the ``umbra`` process itself, and the
  other processes' outputs by subscribing on zenoh as an observer to what ``--publish-all``
  publishes.
"""
