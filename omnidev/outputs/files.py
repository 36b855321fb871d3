"""``file:PATH`` (or a bare path): an image or a video file, written atomically.

An image path (.png, .jpg, .bmp, .tif, .webp, .pgm, .ppm) takes exactly one
frame (OpenCV writes it). A video path is encoded by FFmpeg's libraries through
PyAV (docs/outputs.md says why PyAV and not cv2.VideoWriter):

| suffix | codec (default) | quality options |
|---|---|---|
| ``.mp4``, ``.mkv``, ``.mov`` | H.264 (libx264), 4:2:0 | ``crf`` (20), ``preset`` (``veryfast``) |
| ``.avi`` | Motion JPEG, 4:2:0 | ``q`` (2..31, default 3) |

``?codec=NAME`` picks another FFmpeg encoder (``mpeg4`` takes ``q`` too;
``ffv1`` is lossless). Frames are stamped at the constant rate ``spec.fps`` in
the order written. Everything goes to a temporary file beside the target that
:meth:`FileOutput.close` renames into place; :meth:`FileOutput.abort` (or
leaving a ``with`` block by an exception) removes it and leaves the target
untouched.
"""

from __future__ import annotations

import contextlib
from fractions import Fraction
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from omnidev.atomic import check_output, commit_temporary, make_temporary
from omnidev.errors import OutputError
from omnidev.frame import Frame
from omnidev.outputs import OutputBase, OutputSpec, check_output_options, choose_layout
from omnidev.outputs.pixels import to_layout

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm"}
VIDEO_CONTAINERS = {".mp4": "mp4", ".mkv": "matroska", ".mov": "mov", ".avi": "avi"}
DEFAULT_CODEC = {".mp4": "libx264", ".mkv": "libx264", ".mov": "libx264", ".avi": "mjpeg"}
OPTIONS = {"codec", "crf", "preset", "q"}
X264_PRESETS = (
    "ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower",
    "veryslow", "placebo",
)  # fmt: skip


def is_image_path(path: Path) -> bool:
    return path.suffix.lower() in IMAGE_SUFFIXES


def rate_fraction(fps: float) -> Fraction:
    """A frame rate as the fraction containers store (NTSC's 29.97... -> 30000/1001).

    >>> rate_fraction(30000 / 1001), rate_fraction(25.0), rate_fraction(29.97)
    (Fraction(30000, 1001), Fraction(25, 1), Fraction(2997, 100))
    """
    return Fraction(fps).limit_denominator(1001)


class FileOutput(OutputBase):
    """An image or video file (see the module docstring)."""

    def __init__(self, path: Path, spec: OutputSpec, options: dict[str, str] | None = None):
        self.path = Path(path)
        self.name = str(self.path)
        self.spec = spec
        options = dict(options or {})
        suffix = self.path.suffix.lower()
        if suffix not in IMAGE_SUFFIXES and suffix not in VIDEO_CONTAINERS:
            raise OutputError(
                f"{self.path}: unknown output type {suffix or '(none)'}; use an image "
                f"({', '.join(sorted(IMAGE_SUFFIXES))}) or a video "
                f"({', '.join(VIDEO_CONTAINERS)}), or a pipe (-, y4m:-, raw:-) or v4l2:/dev/videoN"
            )
        check_output_options(self.name, options, OPTIONS if suffix in VIDEO_CONTAINERS else set())
        check_output(self.path, force=spec.force)
        self.frames = 0
        self._container: Any = None
        self._stream: Any = None
        if self.is_image:
            self.layout = choose_layout(self.name, spec, ())
            self._settings: dict[str, Any] = {}
        else:
            self._settings = _encoder_settings(self.name, suffix, options)
            self.layout = choose_layout(self.name, spec, ("yuv420p", "yuvj420p"))
            w, h = spec.size
            if w % 2 or h % 2:
                raise OutputError(
                    f"{self.path}: a {w}x{h} video: 4:2:0 video needs an even width and "
                    "height; make the view one pixel wider or taller"
                )
        self.tmp = make_temporary(self.path)

    @property
    def is_image(self) -> bool:
        return is_image_path(self.path)

    def write(self, frame: Frame) -> None:
        image = frame.image
        if self.is_image:
            if self.frames:
                raise OutputError(
                    f"{self.path}: an image output takes one frame; the input has more "
                    "(write a video: .mp4 or .avi)"
                )
            if not cv2.imwrite(str(self.tmp), image):
                raise OutputError(f"{self.path}: cannot write image")
            self.frames += 1
            return
        import av  # PyAV: FFmpeg's encoders and containers

        if self._container is None:
            self._open_video(av)
        pix_fmt = self._stream.pix_fmt
        if self.layout != pix_fmt:
            image = to_layout(image, self.layout, pix_fmt)
        vf = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format=pix_fmt)
        vf.pts = self.frames
        vf.time_base = self._time_base
        try:
            for packet in self._stream.encode(vf):
                self._container.mux(packet)
        except av.FFmpegError as exc:
            raise OutputError(f"{self.path}: encoding frame {frame.index} failed: {exc}") from None
        self.frames += 1

    def _open_video(self, av: Any) -> None:
        w, h = self.spec.size
        codec = self._settings["codec"]
        pix_fmt = "yuvj420p" if self.layout == "yuvj420p" or codec == "mjpeg" else "yuv420p"
        if codec == "ffv1":  # FFmpeg's ffv1 takes no yuvj420p: full range is converted
            pix_fmt = "yuv420p"
        try:
            self._container = av.open(
                str(self.tmp), mode="w", format=VIDEO_CONTAINERS[self.path.suffix.lower()]
            )
            rate = rate_fraction(self.spec.fps)
            self._time_base = 1 / rate
            stream = self._container.add_stream(codec, rate=rate)
            stream.width, stream.height = w, h
            stream.pix_fmt = pix_fmt
            stream.thread_count = max(1, self.spec.threads)
            if "options" in self._settings:
                stream.options = self._settings["options"]
            if "q" in self._settings:
                stream.codec_context.qscale = True
                stream.codec_context.global_quality = self._settings["q"] * 118  # FF_QP2LAMBDA
        except (av.FFmpegError, ValueError) as exc:
            self._release()
            raise OutputError(f"{self.path}: cannot open a {codec} video writer: {exc}") from None
        self._stream = stream

    def _release(self) -> None:
        if self._container is not None:
            with contextlib.suppress(Exception):
                self._container.close()
        self._container = None
        self._stream = None

    def close(self) -> None:
        if self._container is not None:
            import av

            try:
                for packet in self._stream.encode(None):
                    self._container.mux(packet)
                self._container.close()
            except av.FFmpegError as exc:
                self.abort()
                raise OutputError(f"{self.path}: finishing the video failed: {exc}") from None
            self._container = None
        if self.frames == 0:
            self.abort()
            raise OutputError(f"{self.path}: no frames to write")
        commit_temporary(self.tmp, self.path, force=self.spec.force)

    def abort(self) -> None:
        self._release()
        with contextlib.suppress(FileNotFoundError):
            self.tmp.unlink()


def _encoder_settings(name: str, suffix: str, options: dict[str, str]) -> dict[str, Any]:
    """Codec name and its quality settings from the URI options (checked)."""
    codec = options.get("codec", DEFAULT_CODEC[suffix])
    out: dict[str, Any] = {"codec": codec}
    if codec == "libx264":
        crf = options.get("crf", "20")
        try:
            crf_value = float(crf)
        except ValueError:
            crf_value = -1.0
        if not 0 <= crf_value <= 51:
            raise OutputError(f"{name}: crf={crf!r} must be a number in 0..51")
        preset = options.get("preset", "veryfast")
        if preset not in X264_PRESETS:
            raise OutputError(f"{name}: preset={preset!r}; x264 presets: {', '.join(X264_PRESETS)}")
        out["options"] = {"crf": f"{crf_value:g}", "preset": preset}
    elif "crf" in options or "preset" in options:
        raise OutputError(f"{name}: crf and preset are options of codec libx264, not {codec}")
    if codec in ("mjpeg", "mpeg4"):
        q = options.get("q", "3")
        try:
            q_value = int(q)
        except ValueError:
            q_value = 0
        if not 2 <= q_value <= 31:
            raise OutputError(f"{name}: q={q!r} must be an integer in 2..31 (2 is best)")
        out["q"] = q_value
    elif "q" in options:
        raise OutputError(f"{name}: q is an option of codecs mjpeg and mpeg4, not {codec}")
    return out


def open_file(rest: str, options: dict[str, str], spec: OutputSpec) -> FileOutput:
    """Entry point of group ``omnidev.outputs``, name ``file``."""
    if not rest:
        raise OutputError("file: give a path, e.g. file:out/pano.mp4")
    return FileOutput(Path(rest), spec, options)
