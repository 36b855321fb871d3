"""Shared by the daemon tests on the host and in the VM: configs and matching against truth."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from omnidev.sim.blob import BlobTruth

ROOT = Path(__file__).resolve().parents[1]
BLOB = ROOT / "fixtures" / "blob"


def blob_config(
    tmp: Path, source: str, sink: str, sink_options: str, *, filt: str = "none", extra: str = ""
) -> Path:
    """Write a daemon config for the blob fixture; returns its path."""
    path = tmp / "omnidev.toml"
    path.write_text(
        f"""
[source]
uri = "{source}"

[tracker]
name = "bright-blob"
[tracker.options]
press_area = 700

[filter]
kind = "{filt}"

[sink]
name = "{sink}"
[sink.options]
{sink_options}

[screen]
rect = "1920x1080+0+0"

[daemon]
socket = "{tmp / "control.sock"}"
retry_initial_s = 0.2
retry_max_s = 1.0
{extra}
"""
    )
    return path


def match_to_truth(
    positions: Sequence[tuple[float, float]],
    truth: Sequence[BlobTruth],
    window: int = 12,
    lost: float = 0.02,
) -> list[tuple[int, float]]:
    """Pair each reported position (normalized) with the frame it came from.

    Frames are reported in order, some may be dropped or repeated: each position
    is paired with the nearest truth among the previous pair's frame and the
    ``window`` frames after it (the path loops, so indices wrap); a position farther than
    ``lost`` (normalized) from all of those is placed afresh over the whole path.
    Returns (frame index, error in normalized units) per position.
    """
    out: list[tuple[int, float]] = []
    n = len(truth)

    def err(i: int, k: int) -> float:
        x, y = positions[k]
        return math.hypot(truth[i % n].x - x, truth[i % n].y - y)

    def place(k: int) -> int:
        # The path crosses itself: place position k by it and the next one together.
        if k + 1 < len(positions):
            return min(
                range(n), key=lambda i: err(i, k) + min(err(i + d, k + 1) for d in range(1, window))
            )
        return min(range(n), key=lambda i: err(i, k))

    j = place(0)
    out.append((j, err(j, 0)))
    for k in range(1, len(positions)):
        # d = 0: a camera may deliver the same picture twice
        j = min(((j + d) % n for d in range(0, window + 1)), key=lambda i: err(i, k))
        if err(j, k) > lost:
            # more than ``window`` frames dropped in a row (a loaded machine): place
            # this position afresh rather than pairing it with a wrong frame
            j = place(k)
        out.append((j, err(j, k)))
    return out
