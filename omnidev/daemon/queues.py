"""Queue helpers shared by the daemon's pointer pipeline and its video streams."""

from __future__ import annotations

import queue
from typing import Any


def put_dropping_oldest(q: queue.Queue[Any], item: Any) -> int:
    """Queue ``item`` without waiting, dropping the oldest items to make room (a live
    source's frames); returns how many were dropped."""
    dropped = 0
    while True:
        try:
            q.put_nowait(item)
            return dropped
        except queue.Full:
            try:
                q.get_nowait()
                dropped += 1
            except queue.Empty:
                pass
