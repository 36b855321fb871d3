"""``v4l2:/dev/videoN[?format=yuyv&pace=auto]``: a V4L2 video output device.

With v4l2loopback (docs/outputs.md has its setup) the frames written here
appear on the same node as a camera that a browser, OBS, ffmpeg, GStreamer or
a video call opens. The device is set to the view's size and the chosen pixel
format (``VIDIOC_S_FMT`` on the output side, frame rate by ``VIDIOC_S_PARM``)
and every frame is handed over in a memory-mapped buffer (``io=mmap``, the
default: ``VIDIOC_QBUF`` with the frame's capture time as the buffer timestamp,
``VIDIOC_STREAMOFF`` when closed) or by ``write()`` (``io=write``, for drivers
without streaming). Streaming matters for v4l2loopback with
``exclusive_caps=1`` (what browsers need): version 0.12 leaves the device neither
capture nor output after a ``write()`` producer closes, so the next one cannot
open it; after ``STREAMOFF`` it takes the next producer.

| ``format`` | V4L2 fourcc | bytes per frame | note |
|---|---|---|---|
| ``yuyv`` (default) | ``YUYV`` | 2 W H | what webcams send; every program reads it |
| ``yu12`` | ``YU12`` (I420) | 1.5 W H | 4:2:0, the cheapest for omnidev's video path |
| ``nv12`` | ``NV12`` | 1.5 W H | |
| ``bgr24`` / ``rgb24`` | ``BGR3`` / ``RGB3`` | 3 W H | exact: omnidev's pixels unchanged |
| ``gray`` | ``GREY`` | W H | |

YUV is BT.601, limited range. ``pace``: ``1`` holds each frame until its
time at ``fps`` (so that a file source plays at its own rate and readers see
every frame), ``0`` writes as fast as frames come, ``auto`` (default) paces
unless the source is live. This module is the only one that talks to the
kernel's V4L2 output API (the OS binding is ``fcntl.ioctl`` on the node).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import mmap
import os
import stat
import struct
import time
from pathlib import Path

import numpy as np

from omnidev.errors import OutputError
from omnidev.frame import Frame
from omnidev.outputs import Layout, OutputBase, OutputSpec, check_output_options
from omnidev.outputs.files import rate_fraction
from omnidev.outputs.pixels import bgr_to_yuyv, i420_planes, i420_to_yuyv, to_layout


def _iowr(nr: int, size: int) -> int:
    return (3 << 30) | (size << 16) | (ord("V") << 8) | nr


def _ior(nr: int, size: int) -> int:
    return (2 << 30) | (size << 16) | (ord("V") << 8) | nr


_CAPABILITY = struct.Struct("16s32s32sIII12x")  # struct v4l2_capability, 104 bytes
_FORMAT_SIZE = 208  # struct v4l2_format on 64-bit: u32 type, 4 bytes pad, 200-byte union
_PIX = struct.Struct("12I")  # struct v4l2_pix_format
_STREAMPARM_SIZE = 204
VIDIOC_QUERYCAP = _ior(0, _CAPABILITY.size)
VIDIOC_S_FMT = _iowr(5, _FORMAT_SIZE)
VIDIOC_S_PARM = _iowr(22, _STREAMPARM_SIZE)
_REQBUFS = struct.Struct("IIII4x")  # struct v4l2_requestbuffers, 20 bytes
# struct v4l2_buffer on 64-bit (88 bytes): index type bytesused flags field, pad,
# timeval (sec, usec), timecode (16 bytes), sequence memory, m (offset | pointer),
# length, reserved2, request_fd, pad.
_BUFFER = struct.Struct("IIIII4xqq16xII8sIIi4x")
VIDIOC_REQBUFS = _iowr(8, _REQBUFS.size)
VIDIOC_QUERYBUF = _iowr(9, _BUFFER.size)
VIDIOC_QBUF = _iowr(15, _BUFFER.size)
VIDIOC_DQBUF = _iowr(17, _BUFFER.size)
VIDIOC_STREAMON = (1 << 30) | (4 << 16) | (ord("V") << 8) | 18
VIDIOC_STREAMOFF = (1 << 30) | (4 << 16) | (ord("V") << 8) | 19
MEMORY_MMAP = 1
BUF_FLAG_TIMESTAMP_COPY = 0x4000
CAP_STREAMING = 0x04000000
BUFFERS = 4
BUF_TYPE_VIDEO_OUTPUT = 2
CAP_VIDEO_OUTPUT = 0x00000002
CAP_READWRITE = 0x01000000
CAP_DEVICE_CAPS = 0x80000000
FIELD_NONE = 1
COLORSPACE_SMPTE170M = 1  # BT.601
COLORSPACE_SRGB = 8
QUANTIZATION_LIM_RANGE = 2


def fourcc(code: str) -> int:
    """The V4L2 pixel format number of a four-character code.

    >>> hex(fourcc("YUYV"))
    '0x56595559'
    """
    a, b, c, d = (ord(x) for x in code)
    return a | (b << 8) | (c << 16) | (d << 24)


# format -> (fourcc, bytes per pixel x 2, layout write() takes)
FORMATS: dict[str, tuple[str, int, Layout]] = {
    "yuyv": ("YUYV", 4, "bgr"),
    "yu12": ("YU12", 3, "yuv420p"),
    "nv12": ("NV12", 3, "yuv420p"),
    "bgr24": ("BGR3", 6, "bgr"),
    "rgb24": ("RGB3", 6, "bgr"),
    "gray": ("GREY", 2, "gray"),
}


class V4L2Output(OutputBase):
    """A V4L2 output node (see the module docstring)."""

    def __init__(self, device: str, options: dict[str, str], spec: OutputSpec) -> None:
        self.name = f"v4l2:{device}"
        check_output_options(self.name, options, {"format", "pace", "io"})
        fmt = options.get("format", "gray" if spec.gray else "yuyv").lower()
        if fmt not in FORMATS:
            raise OutputError(f"{self.name}: format={fmt!r}; formats: {', '.join(FORMATS)}")
        pace = options.get("pace", "auto").lower()
        if pace not in ("auto", "0", "1"):
            raise OutputError(f"{self.name}: pace={pace!r} must be auto, 0 or 1")
        io = options.get("io", "auto").lower()
        if io not in ("auto", "mmap", "write"):
            raise OutputError(f"{self.name}: io={io!r} must be auto, mmap or write")
        w, h = spec.size
        code, bpp2, layout = FORMATS[fmt]
        if (fmt == "yuyv" and w % 2) or (fmt in ("yu12", "nv12") and (w % 2 or h % 2)):
            raise OutputError(f"{self.name}: a {w}x{h} picture: {fmt} needs an even width")
        if fmt == "yuyv" and spec.layouts[0] in ("yuv420p", "yuvj420p"):
            layout = "yuv420p"  # 4:2:0 frames become YUYV without a trip through BGR
        self.format = fmt
        self.layout = layout
        self.spec = spec
        self.frames = 0
        self.frame_bytes = w * h * bpp2 // 2
        self._period_ns = (
            0 if pace == "0" or (pace == "auto" and spec.live) else round(1e9 / spec.fps)
        )
        self._next_ns = 0
        node = Path(device)
        try:
            mode = node.stat().st_mode
        except FileNotFoundError:
            raise OutputError(
                f"{self.name}: no such device node (load v4l2loopback: "
                "sudo modprobe v4l2loopback video_nr=10 exclusive_caps=1; docs/outputs.md)"
            ) from None
        if not stat.S_ISCHR(mode):
            raise OutputError(f"{self.name}: not a character device (a V4L2 node is /dev/videoN)")
        try:
            self._fd = os.open(device, os.O_RDWR | os.O_CLOEXEC)
        except PermissionError:
            raise OutputError(
                f"{self.name}: permission denied; add the user to group 'video' "
                "(sudo usermod -aG video $USER) and log in again"
            ) from None
        except OSError as exc:
            raise OutputError(f"{self.name}: cannot open: {exc.strerror}") from None
        self._maps: list[mmap.mmap] = []
        self._queued = 0
        self._streaming = False
        try:
            self.card, caps = self._check_caps()
            self.io = io if io != "auto" else ("mmap" if caps & CAP_STREAMING else "write")
            if self.io == "write" and not caps & CAP_READWRITE:
                raise OutputError(f"{self.name}: the driver does not take frames by write()")
            if self.io == "mmap" and not caps & CAP_STREAMING:
                raise OutputError(f"{self.name}: the driver has no streaming I/O (use io=write)")
            self._set_format(code)
            self._set_rate()
            if self.io == "mmap":
                self._request_buffers()
        except BaseException:
            self._release()
            raise

    def _check_caps(self) -> tuple[str, int]:
        buf = bytearray(_CAPABILITY.size)
        try:
            fcntl.ioctl(self._fd, VIDIOC_QUERYCAP, buf)
        except OSError as exc:
            raise OutputError(f"{self.name}: not a V4L2 device ({exc.strerror})") from None
        _, card, _, _, caps, device_caps = _CAPABILITY.unpack(buf)
        have = device_caps if caps & CAP_DEVICE_CAPS else caps
        card_name = str(card.split(b"\0", 1)[0].decode(errors="replace"))
        if not have & CAP_VIDEO_OUTPUT:
            raise OutputError(
                f"{self.name}: {card_name!r} is not a video output device (a capture node?); "
                "with v4l2loopback write to the loopback node itself"
            )
        return card_name, int(have)

    def _set_format(self, code: str) -> None:
        w, h = self.spec.size
        bpl = {"YUYV": 2 * w, "BGR3": 3 * w, "RGB3": 3 * w, "GREY": w}.get(code, w)
        colorspace = COLORSPACE_SRGB if code in ("BGR3", "RGB3", "GREY") else COLORSPACE_SMPTE170M
        pix = _PIX.pack(
            w, h, fourcc(code), FIELD_NONE, bpl, self.frame_bytes, colorspace, 0, 0, 0,
            QUANTIZATION_LIM_RANGE if colorspace == COLORSPACE_SMPTE170M else 0, 0,
        )  # fmt: skip
        buf = bytearray(_FORMAT_SIZE)
        struct.pack_into("I", buf, 0, BUF_TYPE_VIDEO_OUTPUT)
        buf[8 : 8 + _PIX.size] = pix
        try:
            fcntl.ioctl(self._fd, VIDIOC_S_FMT, buf)
        except OSError as exc:
            hint = " (another program is writing to it?)" if exc.errno == errno.EBUSY else ""
            raise OutputError(
                f"{self.name}: the device refuses {w}x{h} {code}: {exc.strerror}{hint}"
            ) from None
        got = _PIX.unpack_from(buf, 8)
        if (got[0], got[1], got[2]) != (w, h, fourcc(code)):
            raise OutputError(
                f"{self.name}: asked for {w}x{h} {code}, the device set "
                f"{got[0]}x{got[1]} {struct.pack('<I', got[2]).decode(errors='replace')}"
            )
        # got[5] (sizeimage) may be rounded up to whole pages (v4l2loopback): a frame is
        # still written as its own bytes.

    def _set_rate(self) -> None:
        rate = rate_fraction(self.spec.fps)
        buf = bytearray(_STREAMPARM_SIZE)
        # v4l2_streamparm: type, then v4l2_outputparm: capability, outputmode,
        # timeperframe (numerator, denominator) = seconds per frame.
        struct.pack_into("IIIII", buf, 0, BUF_TYPE_VIDEO_OUTPUT, 0, 0, rate.denominator,
                         rate.numerator)  # fmt: skip
        with contextlib.suppress(OSError):  # a rate the driver ignores is no error
            fcntl.ioctl(self._fd, VIDIOC_S_PARM, buf)

    def _request_buffers(self) -> None:
        req = bytearray(_REQBUFS.pack(BUFFERS, BUF_TYPE_VIDEO_OUTPUT, MEMORY_MMAP, 0))
        try:
            fcntl.ioctl(self._fd, VIDIOC_REQBUFS, req)
        except OSError as exc:
            raise OutputError(f"{self.name}: cannot get buffers: {exc.strerror}") from None
        count = _REQBUFS.unpack(req)[0]
        if count < 1:
            raise OutputError(f"{self.name}: the driver gave no buffers")
        for i in range(count):
            buf = bytearray(_BUFFER.size)
            struct.pack_into("II", buf, 0, i, BUF_TYPE_VIDEO_OUTPUT)
            struct.pack_into("I", buf, 60, MEMORY_MMAP)
            fcntl.ioctl(self._fd, VIDIOC_QUERYBUF, buf)
            fields = _BUFFER.unpack(buf)
            offset, length = struct.unpack_from("I", fields[9])[0], fields[10]
            if length < self.frame_bytes:
                raise OutputError(
                    f"{self.name}: buffer {i} holds {length} bytes, a frame {self.frame_bytes}"
                )
            self._maps.append(mmap.mmap(self._fd, length, offset=offset))

    def _queue(self, data: np.ndarray, frame: Frame) -> None:
        """Fill a free buffer with the frame and queue it (stamped with its capture time)."""
        buf = bytearray(_BUFFER.size)
        if self._queued < len(self._maps):
            index = self._queued
        else:
            struct.pack_into("II", buf, 0, 0, BUF_TYPE_VIDEO_OUTPUT)
            struct.pack_into("I", buf, 60, MEMORY_MMAP)
            fcntl.ioctl(self._fd, VIDIOC_DQBUF, buf)  # a buffer the driver is done with
            index = struct.unpack_from("I", buf, 0)[0]
        view = data.data.cast("B")
        self._maps[index][: len(view)] = view
        sec, nsec = divmod(int(frame.timestamp_ns), 1_000_000_000)
        packed = _BUFFER.pack(
            index, BUF_TYPE_VIDEO_OUTPUT, len(view), BUF_FLAG_TIMESTAMP_COPY, FIELD_NONE,
            sec, nsec // 1000, 0, MEMORY_MMAP, bytes(8), len(self._maps[index]), 0, 0,
        )  # fmt: skip
        fcntl.ioctl(self._fd, VIDIOC_QBUF, bytearray(packed))
        self._queued += 1
        if not self._streaming:
            fcntl.ioctl(self._fd, VIDIOC_STREAMON, struct.pack("i", BUF_TYPE_VIDEO_OUTPUT))
            self._streaming = True

    def _pixels(self, frame: Frame) -> np.ndarray:
        image = frame.image
        fmt = self.format
        if fmt == "yuyv":
            return i420_to_yuyv(image) if self.layout == "yuv420p" else bgr_to_yuyv(image)
        if fmt == "nv12":
            y, u, v = i420_planes(image)
            return np.concatenate([y.reshape(-1), np.stack([u, v], -1).reshape(-1)])
        if fmt == "rgb24":
            return image[:, :, ::-1]
        if fmt == "gray" and self.layout != "gray":
            return to_layout(image, self.layout, "gray")
        return image

    def write(self, frame: Frame) -> None:
        data = np.ascontiguousarray(self._pixels(frame))
        if data.nbytes != self.frame_bytes:
            raise OutputError(
                f"{self.name}: frame {frame.index} has {data.nbytes} bytes, the device "
                f"takes {self.frame_bytes}"
            )
        if self._period_ns:
            now = time.monotonic_ns()
            if self._next_ns > now:
                time.sleep((self._next_ns - now) / 1e9)
            self._next_ns = max(self._next_ns + self._period_ns, time.monotonic_ns())
        try:
            if self.io == "mmap":
                self._queue(data, frame)
            else:
                view = data.data.cast("B")
                done = os.write(self._fd, view)
                while done < len(view):
                    done += os.write(self._fd, view[done:])
        except OSError as exc:
            raise OutputError(
                f"{self.name}: writing frame {frame.index} failed: {exc.strerror}"
            ) from None
        self.frames += 1

    def _release(self) -> None:
        if self._fd < 0:
            return
        if self._streaming:
            with contextlib.suppress(OSError):
                fcntl.ioctl(self._fd, VIDIOC_STREAMOFF, struct.pack("i", BUF_TYPE_VIDEO_OUTPUT))
            self._streaming = False
        for m in self._maps:
            with contextlib.suppress(Exception):
                m.close()
        self._maps = []
        os.close(self._fd)
        self._fd = -1

    def close(self) -> None:
        self._release()

    def abort(self) -> None:
        with contextlib.suppress(OSError):
            self._release()


def open_v4l2_output(rest: str, options: dict[str, str], spec: OutputSpec) -> V4L2Output:
    """Entry point of group ``omnidev.outputs``, name ``v4l2``."""
    if not rest.startswith("/"):
        raise OutputError(f"v4l2:{rest}: give the device node, e.g. v4l2:/dev/video10")
    return V4L2Output(rest, options, spec)
