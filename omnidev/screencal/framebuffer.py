"""Show images full-screen on a Linux framebuffer (/dev/fbN), no desktop needed.

The hardware adapter of screen calibration: reads the device's
``fb_var_screeninfo`` (resolution, bits per pixel, colour bit fields) and
``fb_fix_screeninfo`` (line length) with the FBIOGET_* ioctls and writes the
picture row by row at the visible offset. While it is open the active virtual
console is switched to graphics mode (KDSETMODE KD_GRAPHICS on /dev/tty0), so the
text console stops drawing over the picture (its blinking cursor would otherwise
land on the patterns); text mode is restored on close. ``fcntl`` is imported
only here, and only when a device is opened. :func:`pack_pixels` (the
pixel-format conversion) is pure numpy.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np
from numpy.typing import NDArray

from omnidev.errors import OutputError

KDSETMODE = 0x4B3A
KD_TEXT, KD_GRAPHICS = 0, 1
FBIOGET_VSCREENINFO = 0x4600
FBIOGET_FSCREENINFO = 0x4602
_VAR_SIZE = 160
_FIX_SIZE = 80


@dataclass(frozen=True)
class FbFormat:
    """A framebuffer's geometry and pixel format.

    xres, yres: visible pixels; xoffset, yoffset: the visible area in the virtual
    one; bits_per_pixel; line_length: bytes per row; red, green, blue, transp:
    (offset, length) bit fields; grayscale: non-zero for a grey framebuffer.
    """

    xres: int
    yres: int
    xoffset: int
    yoffset: int
    bits_per_pixel: int
    line_length: int
    red: tuple[int, int]
    green: tuple[int, int]
    blue: tuple[int, int]
    transp: tuple[int, int]
    grayscale: int = 0


def parse_screeninfo(var: bytes, fix: bytes) -> FbFormat:
    """An FbFormat from the raw fb_var_screeninfo and fb_fix_screeninfo structs."""
    v = struct.unpack_from("=8I12I", var)
    line_length = struct.unpack_from("@16sLIIIIHHHI", fix)[-1]
    return FbFormat(
        xres=v[0],
        yres=v[1],
        xoffset=v[4],
        yoffset=v[5],
        bits_per_pixel=v[6],
        line_length=line_length,
        red=(v[8], v[9]),
        green=(v[11], v[12]),
        blue=(v[14], v[15]),
        transp=(v[17], v[18]),
        grayscale=v[7],
    )


def pack_pixels(image: NDArray[np.uint8], fmt: FbFormat) -> bytes:
    """The framebuffer bytes of an H x W (grey) or H x W x 3 (BGR) uint8 image.

    Each channel value keeps its top ``length`` bits and moves to its ``offset``;
    pixels are little-endian words of bits_per_pixel / 8 bytes; rows are padded
    to ``line_length`` bytes. The image must be yres x xres.
    """
    img = np.asarray(image, np.uint8)
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    h, w = img.shape[:2]
    if (w, h) != (fmt.xres, fmt.yres):
        raise OutputError(f"image is {w}x{h}, framebuffer is {fmt.xres}x{fmt.yres}")
    bpp = fmt.bits_per_pixel
    if bpp not in (8, 16, 24, 32):
        raise OutputError(f"framebuffer with {bpp} bits per pixel is not supported")
    nbytes = bpp // 8
    if bpp == 8 or fmt.grayscale:
        grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.uint32)
        word = grey if bpp == 8 else grey * 0x010101
    else:
        word = np.zeros((h, w), np.uint32)
        for ch, (off, length) in ((2, fmt.red), (1, fmt.green), (0, fmt.blue)):
            if length:
                word |= (img[:, :, ch].astype(np.uint32) >> (8 - min(length, 8))) << off
        t_off, t_len = fmt.transp
        if t_len:
            word |= np.uint32((1 << t_len) - 1) << t_off
    raw = word.astype("<u4").view(np.uint8).reshape(h, w, 4)[:, :, :nbytes]
    rows = np.zeros((h, fmt.line_length), np.uint8)
    rows[:, : w * nbytes] = raw.reshape(h, w * nbytes)
    return rows.tobytes()


class Framebuffer:
    """An open /dev/fbN: ``show(image)`` fills the visible screen with an image."""

    def __init__(self, path: Path | str) -> None:
        import fcntl

        self.path = Path(path)
        try:
            self.fd = os.open(self.path, os.O_RDWR)
        except FileNotFoundError:
            raise OutputError(
                f"{self.path}: no such framebuffer (is a console framebuffer driver loaded? "
                "see /sys/class/graphics)"
            ) from None
        except PermissionError:
            raise OutputError(
                f"{self.path}: permission denied (add yourself to the 'video' group)"
            ) from None
        try:
            var = bytearray(_VAR_SIZE)
            fix = bytearray(_FIX_SIZE)
            fcntl.ioctl(self.fd, FBIOGET_VSCREENINFO, var, True)
            fcntl.ioctl(self.fd, FBIOGET_FSCREENINFO, fix, True)
        except OSError as exc:
            os.close(self.fd)
            raise OutputError(f"{self.path}: not a framebuffer ({exc.strerror})") from None
        self.format = parse_screeninfo(bytes(var), bytes(fix))
        self._tty = _console_graphics(True)

    @property
    def size(self) -> tuple[int, int]:
        """Visible (width, height) in pixels."""
        return self.format.xres, self.format.yres

    def show(self, image: NDArray[np.uint8]) -> None:
        """Write ``image`` (yres x xres, grey or BGR) to the visible area."""
        f = self.format
        data = pack_pixels(image, f)
        offset = f.yoffset * f.line_length + f.xoffset * f.bits_per_pixel // 8
        os.pwrite(self.fd, data, offset)

    def close(self) -> None:
        if self._tty is not None:
            _console_graphics(False, self._tty)
            self._tty = None
        os.close(self.fd)

    def __enter__(self) -> Framebuffer:
        return self

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def _console_graphics(on: bool, fd: int | None = None) -> int | None:
    """Switch the active virtual console to graphics (``on``) or back to text mode.

    Returns the open /dev/tty0 descriptor while in graphics mode, or None when
    there is no console to switch (no tty0, no permission: then the text console
    may draw its cursor over the picture).
    """
    import fcntl

    if on:
        try:
            fd = os.open("/dev/tty0", os.O_RDWR | os.O_NOCTTY)
        except OSError:
            return None
        try:
            fcntl.ioctl(fd, KDSETMODE, KD_GRAPHICS)
        except OSError:
            os.close(fd)
            return None
        return fd
    if fd is not None:
        try:
            fcntl.ioctl(fd, KDSETMODE, KD_TEXT)
        finally:
            os.close(fd)
    return None
