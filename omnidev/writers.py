"""Output writers for unwarped frames: an image file or a video file, written atomically."""

from __future__ import annotations

import contextlib
import math
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.atomic import check_output, commit_temporary, make_temporary
from omnidev.errors import OutputError

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm"}
MAX_FPS = 1000.0
"""Highest output frame rate accepted (cv2.VideoWriter never returns for an infinite one)."""
VIDEO_FOURCC = {".mp4": "mp4v", ".avi": "MJPG", ".mkv": "MJPG"}


def is_image_path(path: Path) -> bool:
    return path.suffix.lower() in IMAGE_SUFFIXES


class FrameWriter:
    """Writes frames to ``path`` through a temporary file renamed by :meth:`commit`.

    An image path takes exactly one frame; a video path (.mp4, .avi, .mkv) any
    number. :meth:`abort` (or leaving a ``with`` block by an exception) removes
    the temporary file and leaves ``path`` untouched.
    """

    def __init__(self, path: Path, *, fps: float = 25.0, force: bool = False) -> None:
        self.path = Path(path)
        suffix = self.path.suffix.lower()
        if suffix not in IMAGE_SUFFIXES and suffix not in VIDEO_FOURCC:
            raise OutputError(
                f"{self.path}: unknown output type {suffix or '(none)'}; use an image "
                f"({', '.join(sorted(IMAGE_SUFFIXES))}) or a video ({', '.join(VIDEO_FOURCC)})"
            )
        check_output(self.path, force=force)
        if not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
            raise OutputError(f"{self.path}: frame rate {fps:g} must be in (0, {MAX_FPS}] fps")
        self.fps = fps
        self.force = force
        self.tmp = make_temporary(self.path)
        self.frames = 0
        self._video: cv2.VideoWriter | None = None

    @property
    def is_image(self) -> bool:
        return is_image_path(self.path)

    def write(self, image: NDArray[np.uint8]) -> None:
        if self.is_image:
            if self.frames:
                raise OutputError(
                    f"{self.path}: an image output takes one frame; the input has more "
                    "(write a video: .mp4 or .avi)"
                )
            if not cv2.imwrite(str(self.tmp), image):
                raise OutputError(f"{self.path}: cannot write image")
        else:
            if self._video is None:
                h, w = image.shape[:2]
                fourcc = cv2.VideoWriter.fourcc(*VIDEO_FOURCC[self.path.suffix.lower()])
                self._video = cv2.VideoWriter(
                    str(self.tmp), fourcc, self.fps, (w, h), image.ndim == 3
                )
                if not self._video.isOpened():
                    raise OutputError(f"{self.path}: cannot open a video writer")
            self._video.write(image)
        self.frames += 1

    def commit(self) -> None:
        if self._video is not None:
            self._video.release()
            self._video = None
        if self.frames == 0:
            self.abort()
            raise OutputError(f"{self.path}: no frames to write")
        commit_temporary(self.tmp, self.path, force=self.force)

    def abort(self) -> None:
        if self._video is not None:
            self._video.release()
            self._video = None
        with contextlib.suppress(FileNotFoundError):
            self.tmp.unlink()

    def __enter__(self) -> FrameWriter:
        return self

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.abort()
