"""``y4m:-`` / ``-`` and ``raw:-``: frames on standard output (or into a FIFO or file) for
another program.

**Y4M** (YUV4MPEG2) carries its own size, rate and pixel format, so the reader
needs no options::

    omnidev unwarp cam.mp4 --camera cam.yml --view panorama:2048x512 -o - \\
        | ffmpeg -i - -c:v libx264 pano.mp4
    omnidev unwarp v4l2:/dev/video0 --camera cam.yml --view panorama:2048x512 -o - \\
        | gst-launch-1.0 fdsrc ! y4mdec ! videoconvert ! autovideosink

The stream is 4:2:0 (``C420jpeg``, BT.601 limited range) for colour frames and
``Cmono`` for gray frames; the width and height must be even for 4:2:0.
Option ``format=mono`` writes the luma alone.

**Raw** frames are the bare pixels one after another (``format``: ``bgr24``,
the default and exactly omnidev's pixels; ``rgb24``; ``gray``; ``yuv420p``).
The reader is told the size and format, which omnidev prints to standard error,
e.g. ``ffmpeg -f rawvideo -pix_fmt bgr24 -video_size 2048x512 -framerate 25 -i -``.

``REST`` is ``-`` (standard output), a FIFO (``mkfifo``; written as frames
come) or a file path (written to a temporary file and renamed when complete).
A reader that exits early is an :class:`OutputError` naming the frame.
"""

from __future__ import annotations

import contextlib
import stat
import sys
from pathlib import Path
from typing import BinaryIO

import numpy as np

from omnidev.atomic import check_output, commit_temporary, make_temporary
from omnidev.errors import OutputError
from omnidev.frame import Frame
from omnidev.outputs import Layout, OutputBase, OutputSpec, check_output_options, choose_layout
from omnidev.outputs.files import rate_fraction
from omnidev.outputs.pixels import to_layout

RAW_FORMATS = {"bgr24": "bgr", "rgb24": "bgr", "gray": "gray", "yuv420p": "yuv420p"}


class PipeOutput(OutputBase):
    """Bytes of each frame to a stream: standard output, a FIFO, or a file (atomically)."""

    def __init__(self, scheme: str, rest: str, spec: OutputSpec) -> None:
        self.name = f"{scheme}:{rest}"
        self.spec = spec
        self.frames = 0
        self._tmp: Path | None = None
        self._target: Path | None = None
        self._fh: BinaryIO
        if rest in ("", "-"):
            self._fh = sys.stdout.buffer
            self._owns = False
        else:
            path = Path(rest)
            if path.exists() and stat.S_ISFIFO(path.stat().st_mode):
                self._fh = path.open("wb")  # blocks until a reader opens the FIFO
            else:
                check_output(path, force=spec.force)
                tmp = make_temporary(path)
                self._fh = tmp.open("wb")
                self._tmp, self._target = tmp, path
            self._owns = True

    def _send(self, data: bytes | memoryview, frame: Frame) -> None:
        try:
            self._fh.write(data)
        except BrokenPipeError:
            raise OutputError(
                f"{self.name}: the reading program closed the pipe at frame {frame.index} "
                f"({self.frames} frames written)"
            ) from None
        except OSError as exc:
            raise OutputError(f"{self.name}: cannot write frame {frame.index}: {exc}") from None

    def close(self) -> None:
        try:
            self._fh.flush()
        except BrokenPipeError:
            raise OutputError(f"{self.name}: the reading program closed the pipe") from None
        finally:
            if self._owns:
                with contextlib.suppress(OSError):
                    self._fh.close()
        if self._tmp is not None and self._target is not None:
            if self.frames == 0:
                self._tmp.unlink(missing_ok=True)
                raise OutputError(f"{self.name}: no frames to write")
            tmp, self._tmp = self._tmp, None
            commit_temporary(tmp, self._target, force=self.spec.force)

    def abort(self) -> None:
        if self._owns:
            with contextlib.suppress(OSError):
                self._fh.close()
        else:
            with contextlib.suppress(OSError):
                self._fh.flush()
        if self._tmp is not None:
            self._tmp.unlink(missing_ok=True)
            self._tmp = None


class Y4MOutput(PipeOutput):
    """A YUV4MPEG2 stream (see the module docstring)."""

    def __init__(self, rest: str, options: dict[str, str], spec: OutputSpec) -> None:
        name = f"y4m:{rest}"
        check_output_options(name, options, {"format"})
        fmt = options.get("format", "mono" if spec.gray else "420")
        if fmt not in ("420", "mono"):
            raise OutputError(f"{name}: format={fmt!r}; formats: 420, mono")
        w, h = spec.size
        if fmt == "420" and (w % 2 or h % 2):
            raise OutputError(
                f"{name}: a {w}x{h} picture: 4:2:0 needs an even width and height "
                "(or use format=mono, or raw:-)"
            )
        self.layout: Layout = "gray" if fmt == "mono" else choose_layout(name, spec, ("yuv420p",))
        super().__init__("y4m", rest, spec)
        rate = rate_fraction(spec.fps)
        colour = "Cmono" if fmt == "mono" else "C420jpeg XYSCSS=420JPEG"
        self._header = (
            f"YUV4MPEG2 W{w} H{h} F{rate.numerator}:{rate.denominator} Ip A1:1 {colour}\n"
        ).encode()

    def write(self, frame: Frame) -> None:
        image = frame.image
        target = "gray" if self.layout == "gray" else "yuv420p"
        if self.layout != target:
            image = to_layout(image, self.layout, target)
        if self.frames == 0:
            self._send(self._header, frame)
        self._send(b"FRAME\n", frame)
        self._send(np.ascontiguousarray(image).data.cast("B"), frame)
        self.frames += 1


class RawOutput(PipeOutput):
    """Bare frames (see the module docstring)."""

    def __init__(self, rest: str, options: dict[str, str], spec: OutputSpec) -> None:
        name = f"raw:{rest}"
        check_output_options(name, options, {"format"})
        fmt = options.get("format", "gray" if spec.gray else "bgr24")
        if fmt not in RAW_FORMATS:
            raise OutputError(f"{name}: format={fmt!r}; formats: {', '.join(RAW_FORMATS)}")
        w, h = spec.size
        if fmt == "yuv420p" and (w % 2 or h % 2):
            raise OutputError(f"{name}: a {w}x{h} picture: yuv420p needs an even width and height")
        self.format = fmt
        want: Layout = RAW_FORMATS[fmt]  # type: ignore[assignment]
        self.layout = want if want in spec.layouts else choose_layout(name, spec, ())
        super().__init__("raw", rest, spec)
        print(
            f"{name}: {w}x{h} {fmt} at {spec.fps:g} fps (read it with: ffmpeg -f rawvideo "
            f"-pix_fmt {fmt} -video_size {w}x{h} -framerate {spec.fps:g} -i -)",
            file=sys.stderr,
        )

    def write(self, frame: Frame) -> None:
        image = frame.image
        target = RAW_FORMATS[self.format]
        if self.layout != target:
            image = to_layout(image, self.layout, target)
        if self.format == "rgb24":
            image = image[:, :, ::-1]
        self._send(np.ascontiguousarray(image).data.cast("B"), frame)
        self.frames += 1


def open_y4m(rest: str, options: dict[str, str], spec: OutputSpec) -> Y4MOutput:
    """Entry point of group ``omnidev.outputs``, name ``y4m``."""
    return Y4MOutput(rest, options, spec)


def open_raw(rest: str, options: dict[str, str], spec: OutputSpec) -> RawOutput:
    """Entry point of group ``omnidev.outputs``, name ``raw``."""
    return RawOutput(rest, options, spec)
