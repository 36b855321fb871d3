"""Reading images a user names: the header is checked before anything is decoded.

:func:`read_image` is what every command uses instead of a bare ``cv2.imread``:
it refuses a folder, a device or an unreadable file by name, reads the image's
size from its header (Pillow parses only the header), checks the decoded size
against the memory limit (:mod:`omnidev.budget`) and only then decodes with
OpenCV. A 30000 x 30000 PNG of a few kilobytes is a one-line error, not 2.5 GiB.
"""

from __future__ import annotations

import os
import stat
import warnings
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.budget import check_pixels
from omnidev.errors import OmnidevError

MAX_SIDE = 65500
"""Largest image side OpenCV's codecs handle; larger headers are refused as they are."""


def check_image_file(path: Path | str, what: str, error: type[OmnidevError]) -> None:
    """Refuse what cannot be an image file: missing, a folder, a device, unreadable."""
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise error(f"{path}: {what} not found") from None
    except OSError as exc:
        if exc.strerror and "loop" in exc.strerror.lower():
            raise error(f"{path}: {what} is a symlink loop") from None
        raise error(f"{path}: cannot read the {what}: {exc.strerror}") from None
    if stat.S_ISDIR(st.st_mode):
        raise error(f"{path}: is a folder, not an image file ({what})")
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{path}: is not a regular file; give the {what} as an image file")
    if not os.access(path, os.R_OK):
        raise error(f"{path}: permission denied reading the {what}")


def header_size(path: Path | str) -> tuple[int, int] | None:
    """(width, height) from the image file's header, or None if Pillow does not know it."""
    from PIL import Image

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Pillow's own decompression-bomb warning
        try:
            with Image.open(path) as im:
                return int(im.size[0]), int(im.size[1])
        except Image.DecompressionBombError as exc:
            # raised before the size is returned, for more than twice Pillow's limit
            return _bomb_size(str(exc))
        except Exception:
            return None


def _bomb_size(message: str) -> tuple[int, int]:
    import re

    m = re.search(r"\((\d+) pixels\)", message)
    n = int(m.group(1)) if m else 1 << 40
    side = int(n**0.5) + 1
    return side, side


def read_image(
    path: Path | str,
    what: str = "image",
    *,
    grey: bool = False,
    error: type[OmnidevError] = OmnidevError,
) -> NDArray[np.uint8]:
    """Decode an image file as 8-bit BGR (or grey) after checking its header and size.

    Raises ``error`` naming the file for anything that is not a readable image, and
    :class:`omnidev.budget.MemoryLimitError` for an image larger than the memory limit.
    """
    path = Path(path)
    check_image_file(path, what, error)
    size = header_size(path)
    if size is not None:
        w, h = size
        if w < 1 or h < 1 or w > MAX_SIDE or h > MAX_SIDE:
            raise error(
                f"{path}: the {what} is {w}x{h} pixels; the largest side read is {MAX_SIDE}"
            )
        # the decoder's buffer, the 8-bit result and one conversion
        check_pixels(w, h, 4 * (1 if grey else 3), f"{path}: decoding the {w}x{h} {what}")
    flags = cv2.IMREAD_GRAYSCALE if grey else cv2.IMREAD_COLOR
    try:
        image = cv2.imread(str(path), flags)
    except cv2.error as exc:
        msg = str(exc).strip().splitlines()[-1]
        raise error(f"{path}: cannot decode the {what} ({msg})") from None
    if image is None or image.size == 0:
        raise error(f"{path}: cannot read the {what} (not an image OpenCV decodes)")
    return np.asarray(image, np.uint8)
