"""What a running recorder has put on disk so far: the sign that samples were recorded."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from umbra.connectors import UserError
from umbra.runtime.recording.reader import read_records


def messages_on_disk(path: Path) -> Counter[str]:
    """Messages per topic in the recording at ``path`` as it stands (a run that records flushes
    its chunks at least once a second); empty while there is no file."""
    topics: Counter[str] = Counter()
    try:
        for channel, _schema, _message in read_records(path):
            topics[channel.topic] += 1
    except (UserError, OSError):
        pass  # not there yet, or it ends inside a record being written: what came before counts
    return topics
