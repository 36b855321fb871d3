"""Matching frames read back from v4l2loopback to the frames that were written."""

from __future__ import annotations

import numpy as np


def torn_runs(frame: np.ndarray, written: list[np.ndarray], min_run: int = 16) -> list[int] | None:
    """The written frames (in order) whose bytes ``frame`` is made of, run after run of
    at least ``min_run`` bytes, when it is more than one: a buffer read while it was
    being rewritten. v4l2loopback's buffers are shared by its writer and its readers,
    and a reader that falls behind, as one does under TCG on a busy host, or one that
    joins a running stream, can copy a buffer the writer is filling again (seen: bytes
    0-47 of frame 10, then frame 11 up to byte 27125, then frame 10). ``frame`` and
    ``written`` are in the same pixel format, byte for byte. None if it is not that."""
    flat = frame.reshape(-1)
    eq = np.stack([flat == o.reshape(-1) for o in written])  # written frame x byte
    runs: list[int] = []
    i, n = 0, flat.size
    while i < n:
        # the written frame that matches the longest run from byte i on
        ends = [i + int(np.argmin(row[i:])) if not row[i:].all() else n for row in eq]
        k = int(np.argmax(ends))
        if ends[k] - i < min(min_run, n - i):
            return None
        runs.append(k)
        i = ends[k]
    return runs if len(set(runs)) > 1 else None
