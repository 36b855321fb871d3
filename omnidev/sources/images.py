"""``images:GLOB`` — still images (a glob, a folder or one file), in sorted order."""

from __future__ import annotations

import glob
import time
from collections.abc import Iterator
from pathlib import Path

from omnidev.errors import SourceError
from omnidev.frame import Frame
from omnidev.imagefile import read_image
from omnidev.sources import IMAGE_SUFFIXES, SourceBase, check_options


class ImageSource(SourceBase):
    """Images read one by one; an unreadable file is an error naming it."""

    def __init__(self, pattern: str) -> None:
        self.name = f"images:{pattern}"
        p = Path(pattern)
        if p.is_dir():
            files = sorted(f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES)
        elif glob.has_magic(pattern):
            files = sorted(Path(f) for f in glob.glob(pattern) if Path(f).is_file())
        elif p.is_file():
            files = [p]
        else:
            raise SourceError(f"{self.name}: file not found")
        if not files:
            raise SourceError(f"{self.name}: no images match")
        self.files = files
        self.frame_count = len(files)

    def __iter__(self) -> Iterator[Frame]:
        for index, f in enumerate(self.files):
            try:
                image = read_image(f, "image", error=SourceError)
            except SourceError as exc:
                raise SourceError(
                    f"{self.name}: cannot read image {f} (frame {index}): {exc}"
                ) from None
            yield Frame(image, time.monotonic_ns(), index)


def open_images(rest: str, options: dict[str, str]) -> ImageSource:
    check_options(f"images:{rest}", options, set())
    return ImageSource(rest)
