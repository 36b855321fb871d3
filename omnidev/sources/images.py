"""``images:GLOB[?fps=F]`` — still images (a glob, a folder or one file), in sorted order.

An image set is a recorded source: every image is delivered (the pipeline waits
for the tracker), and image ``i`` is stamped ``i / fps`` seconds (``fps``
default 30), as if the images were the frames of a video at that rate.
"""

from __future__ import annotations

import glob
import math
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from omnidev.errors import FileSourceError, SourceError
from omnidev.frame import Frame
from omnidev.imagefile import read_image
from omnidev.sources import IMAGE_SUFFIXES, SourceBase, check_options

DEFAULT_FPS = 30.0
MIN_FPS, MAX_FPS = 0.01, 10_000.0


class ImageSource(SourceBase):
    """Images read one by one; an unreadable file is an error naming it.

    Args:
        pattern: a glob, a folder (its image files) or one image file.
        fps: the frame rate the images stand for (timestamps ``i / fps``).
    """

    def __init__(self, pattern: str, fps: float = DEFAULT_FPS) -> None:
        self.name = f"images:{pattern}"
        self.fps = fps
        self._period_ns = 1e9 / fps
        p = Path(pattern)
        if p.is_dir():
            files = sorted(f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES)
        elif glob.has_magic(pattern):
            files = sorted(Path(f) for f in glob.glob(pattern) if Path(f).is_file())
        elif p.is_file():
            files = [p]
        else:
            raise FileSourceError(f"{self.name}: file not found")
        if not files:
            raise FileSourceError(f"{self.name}: no images match")
        self.files = files
        self.frame_count = len(files)

    def __iter__(self) -> Iterator[Frame]:
        for index, f in enumerate(self.files):
            try:
                image = read_image(f, "image", error=FileSourceError)
            except FileSourceError as exc:
                last = f"last good frame {index - 1}" if index else "no frame read"
                why = str(exc).removeprefix(f"{f}: ")
                raise FileSourceError(
                    f"{self.name}: cannot read image {f} (frame {index}); {last}: {why}"
                ) from None
            stamp = round(index * self._period_ns)
            yield Frame(np.asarray(image, np.uint8), stamp, index, time.monotonic_ns())


def open_images(rest: str, options: dict[str, str]) -> ImageSource:
    uri = f"images:{rest}"
    check_options(uri, options, {"fps"})
    fps = DEFAULT_FPS
    if "fps" in options:
        try:
            fps = float(options["fps"])
        except ValueError:
            fps = math.nan
        if not (MIN_FPS <= fps <= MAX_FPS):
            raise SourceError(
                f"{uri}: option fps must be frames per second from {MIN_FPS:g} to "
                f"{MAX_FPS:g}, got {options['fps']!r}"
            )
    return ImageSource(rest, fps)
