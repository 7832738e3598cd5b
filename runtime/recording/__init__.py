"""Recording a run to MCAP (viewer-ready encodings), reading it back, and replaying it into a graph.

The runtime owns this because recording a run is a feature of the run, like its summary: the
scheduler hands every output's samples (connected or not; an image nobody reads only when named)
to ``tap.RunRecorder``; the encoders map the
core message types (``umbra.connectors.messages``) to Foxglove's well-known schemas or to JSON with
a precise JSON schema derived from the type, so a message type added by a domain package is recorded
without a line of code here. Importing this package is cheap (the parser uses ``settings``).
"""
