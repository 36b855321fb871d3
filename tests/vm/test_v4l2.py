"""omnidev's ``v4l2:`` source on vivid's virtual capture device (runs inside the VM)."""

from __future__ import annotations

import itertools
import os
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest
import vivid

from omnidev.sources import open_source

DISC_CENTER = (480, 120)  # x, y in pixels of the fed 640x480 frame
DISC_RADIUS = 30


def test_v4l2_source_delivers_frames() -> None:
    cap, _ = vivid.vivid_nodes()
    # vivid's webcam input (0) with its test pattern.
    subprocess.run(["v4l2-ctl", "-d", cap, "-i", "0"], check=True, capture_output=True)
    with open_source(f"v4l2:{cap}?width=640&height=480") as src:
        frames = []
        for frame in src:
            frames.append(frame)
            if len(frames) == 8:
                break
    for f in frames:
        assert f.image.shape == (480, 640, 3) and f.image.dtype == np.uint8
    assert [f.index for f in frames] == list(range(8))
    stamps = [f.timestamp_ns for f in frames]
    assert all(b > a for a, b in itertools.pairwise(stamps)), stamps
    assert float(frames[-1].image.std()) > 10, "vivid's test pattern should not be flat"


def bright_blob_center(image: np.ndarray) -> tuple[float, float, int]:
    """Centroid (x, y) and area in pixels of the pixels brighter than 200 (gray)."""
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    ys, xs = np.nonzero(gray > 200)
    if xs.size == 0:
        return float("nan"), float("nan"), 0
    return float(xs.mean()), float(ys.mean()), int(xs.size)


def test_video_loop_brings_back_a_bright_disc_in_place_and_colour(tmp_path: Path) -> None:
    fed = np.zeros((480, 640, 3), np.uint8)
    cv2.circle(fed, DISC_CENTER, DISC_RADIUS, (255, 255, 255), -1)
    fed[400:440, 50:150] = (0, 0, 255)  # red, green, blue boxes (BGR)
    fed[400:440, 200:300] = (0, 255, 0)
    fed[400:440, 350:450] = (255, 0, 0)
    raw = vivid.write_raw(tmp_path / "disc.raw", [fed])
    cap, proc = vivid.start_loop(raw)
    try:
        with open_source(f"v4l2:{cap}?width=640&height=480") as src:
            looped = None
            for frame in src:  # the first frames may predate the loop
                if frame.index >= 20:
                    break
                x, y, area = bright_blob_center(frame.image)
                if area and abs(x - DISC_CENTER[0]) < 2 and abs(y - DISC_CENTER[1]) < 2:
                    looped = frame
                    break
        assert looped is not None, "the fed disc never came back within 20 frames"
        x, y, area = bright_blob_center(looped.image)
        want_area = int(np.count_nonzero(fed[:, :, 0] > 200) - 40 * 100)  # minus the blue box
        assert (x, y) == pytest.approx(DISC_CENTER, abs=0.5)
        assert abs(area - want_area) <= 0.02 * want_area
        diff = np.abs(looped.image.astype(int) - fed.astype(int))
        if os.environ.get("OMNIDEV_VM_OUT"):  # for a look from the host
            out = Path(os.environ["OMNIDEV_VM_OUT"]).parent
            cv2.imwrite(str(out / "vivid-loop-captured.png"), looped.image)
        rows = np.nonzero(diff.max(axis=(1, 2)) > 8)[0]
        assert rows.size == 0, (
            f"rows {rows.min()}..{rows.max()} differ by more than 8 (vivid's OSD?)"
        )
        assert float(diff.mean()) < 1.0, f"mean abs difference {diff.mean():.2f}"
        for (bx, by), bgr in (((100, 420), (0, 0, 255)), ((250, 420), (0, 255, 0)),
                              ((400, 420), (255, 0, 0))):  # fmt: skip
            assert np.abs(looped.image[by, bx].astype(int) - bgr).max() <= 8, "colour lost"
    finally:
        vivid.stop(proc)
