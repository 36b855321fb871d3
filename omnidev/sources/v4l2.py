"""``v4l2:/dev/videoN?width=&height=&fps=&fourcc=&buffers=`` — a V4L2 capture device (OpenCV).

``buffers`` sets how many frames the driver may queue (OpenCV's default is 4):
a pointing device wants 1 or 2, so that a slow consumer gets a fresh frame
rather than one captured several frame periods ago.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from omnidev.errors import SourceError
from omnidev.frame import Frame
from omnidev.sources import SourceBase, check_options

V4L2_MAJOR = 81
"""The character-device major number of video4linux nodes."""
OPTIONS = {"width", "height", "fps", "fourcc", "buffers"}


def parse_v4l2_options(uri: str, options: dict[str, str]) -> dict[str, int | float | str]:
    """Validate the URI options: positive integers for width/height/buffers, a number for fps,
    four characters for fourcc.

    >>> parse_v4l2_options("v4l2:/dev/video0", {"width": "640", "fourcc": "MJPG"})
    {'width': 640, 'fourcc': 'MJPG'}
    >>> parse_v4l2_options("v4l2:/dev/video0", {"buffers": "1"})
    {'buffers': 1}
    """
    check_options(uri, options, OPTIONS)
    out: dict[str, int | float | str] = {}
    for key in ("width", "height", "buffers"):
        if key in options:
            try:
                value = int(options[key])
            except ValueError:
                value = 0
            limit = 64 if key == "buffers" else 16384
            if not 0 < value <= limit:
                raise SourceError(
                    f"{uri}: {key}={options[key]!r} must be a positive integer up to {limit}"
                )
            out[key] = value
    if "fps" in options:
        try:
            fps = float(options["fps"])
        except ValueError:
            fps = 0.0
        if not 0 < fps <= 1000:
            raise SourceError(
                f"{uri}: fps={options['fps']!r} must be a positive number, at most 1000"
            )
        out["fps"] = fps
    if "fourcc" in options:
        if len(options["fourcc"]) != 4:
            raise SourceError(f"{uri}: fourcc={options['fourcc']!r} must be 4 characters")
        out["fourcc"] = options["fourcc"]
    return out


class V4L2Source(SourceBase):
    """A live V4L2 camera; a failed read raises :class:`SourceError` naming the last good frame."""

    live = True

    def __init__(self, device: str, settings: dict[str, int | float | str]) -> None:
        self.name = f"v4l2:{device}"
        node = Path(device)
        if not node.exists():
            raise SourceError(f"{self.name}: no such device node (is the camera plugged in?)")
        if not os.access(node, os.R_OK | os.W_OK):
            raise SourceError(
                f"{self.name}: permission denied; add the user to group 'video' "
                f"(sudo usermod -aG video $USER) and log in again"
            )
        self._cap = cv2.VideoCapture(str(node), cv2.CAP_V4L2)
        if not self._cap.isOpened():
            raise SourceError(f"{self.name}: OpenCV's V4L2 backend cannot open it")
        if "fourcc" in settings:
            self._cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*str(settings["fourcc"])))
        if "buffers" in settings:
            self._cap.set(cv2.CAP_PROP_BUFFERSIZE, float(settings["buffers"]))
        props = {
            "width": cv2.CAP_PROP_FRAME_WIDTH,
            "height": cv2.CAP_PROP_FRAME_HEIGHT,
            "fps": cv2.CAP_PROP_FPS,
        }
        for key, prop in props.items():
            if key in settings:
                self._cap.set(prop, float(settings[key]))
                got = self._cap.get(prop)
                if abs(got - float(settings[key])) > 1e-3:
                    print(
                        f"{self.name}: asked for {key}={settings[key]}, the driver gave {got:g}",
                        file=sys.stderr,
                    )
        fps = float(self._cap.get(cv2.CAP_PROP_FPS))
        self.fps = fps if fps > 0 else None

    def __iter__(self) -> Iterator[Frame]:
        index = 0
        while True:
            ok, image = self._cap.read()
            t = time.monotonic_ns()
            if not ok or image is None:
                last = f"last good frame {index - 1}" if index else "no frame received"
                raise SourceError(f"{self.name}: stopped delivering frames ({last})")
            yield Frame(np.asarray(image, np.uint8), t, index, t)
            index += 1

    def close(self) -> None:
        self._cap.release()


def open_v4l2(rest: str, options: dict[str, str]) -> V4L2Source:
    uri = f"v4l2:{rest}"
    return V4L2Source(rest, parse_v4l2_options(uri, options))


def check_v4l2(rest: str, options: dict[str, str]) -> str:
    """What ``omnidev daemon --check`` checks: the options; the node, if present, is a
    character device this user may open (an absent camera is only reported)."""
    uri = f"v4l2:{rest}"
    parse_v4l2_options(uri, options)
    node = Path(rest)
    if not node.exists():
        return f"{uri}: not present now (the daemon waits for the camera)"
    if not node.is_char_device() or os.major(node.stat().st_rdev) != V4L2_MAJOR:
        raise SourceError(f"{uri}: {rest} is not a V4L2 device node")
    if not os.access(node, os.R_OK | os.W_OK):
        raise SourceError(f"{uri}: permission denied; add the user to group 'video'")
    return f"{uri}: device present"


open_v4l2.check = check_v4l2  # type: ignore[attr-defined]
