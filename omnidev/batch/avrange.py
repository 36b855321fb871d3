"""Video files cut into frame ranges at keyframes, read range by range, and joined again (PyAV).

Three steps, each usable on its own:

1. :func:`index_video` reads every packet header of a file (no decoding) and
   cuts its frames into ranges of about ``target`` frames, each starting at a
   keyframe (:func:`plan_ranges`, pure). Frames are counted in presentation
   order, as a decoder hands them out and ``omnidev unwarp`` numbers them.
2. :func:`read_range` seeks to a range's keyframe and decodes exactly the
   frames whose presentation timestamps fall in the range: frames a decoder
   outputs before the range starts (leading pictures of an open GOP) are
   dropped, and the range before it decodes past the next keyframe until it
   has its own last frame. If a seek lands after the keyframe (a container
   without an index), the range is decoded from the start of the file instead.
   The decoded count must equal the planned one, or the range fails naming
   its frames.
3. :func:`join_segments` copies the packets of the per-range output files
   (one encoder run each) into one file, shifting their timestamps by each
   range's first frame (no re-encoding).

Every timestamp is converted to frames of the file's rate (``round(t * time_base
* fps)``) before it is compared or shifted, so containers that keep
milliseconds (Matroska) or their own timescale (MP4) join alike.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from omnidev.errors import OutputError, SourceError
from omnidev.frame import Frame
from omnidev.sources.avfile import frame_image

PLANAR = ("yuv420p", "yuvj420p")


@dataclass(frozen=True)
class FrameRange:
    """Frames ``start`` .. ``stop - 1`` (0-based, presentation order) of one video.

    Attributes:
        number: the range's place in its video (0, 1, ...).
        start, stop: first frame and one past the last.
        start_pts: presentation timestamp (stream time base) of the keyframe the
            range starts at; None for the first range (decoded from the file's start).
        stop_pts: timestamp of the next range's first frame; None for the last range.
    """

    number: int
    start: int
    stop: int
    start_pts: int | None
    stop_pts: int | None

    @property
    def frames(self) -> int:
        return self.stop - self.start


@dataclass(frozen=True)
class VideoIndex:
    """What :func:`index_video` found.

    Attributes:
        frames: frame count (packets that carry a picture).
        size: (width, height), px.
        fps: frame rate (frames per second), None when the file does not say.
        native_layout: ``yuv420p`` / ``yuvj420p`` when the decoder gives 4:2:0
            planes of an even-sized picture, else ``bgr`` (as omnidev.sources.avfile).
        keyframes: number of keyframes.
        ranges: the planned ranges, covering 0 .. frames - 1 in order.
        bytes: the file's size, bytes.
        split: why the file is one range although it is long, or "".
    """

    frames: int
    size: tuple[int, int]
    fps: float | None
    native_layout: str
    keyframes: int
    ranges: tuple[FrameRange, ...]
    bytes: int
    split: str = ""


def plan_ranges(pts: Sequence[int], keyframe_pts: Sequence[int], target: int) -> list[FrameRange]:
    """Cut frames with presentation timestamps ``pts`` into ranges starting at keyframes.

    The frames are cut into ``round(n / target)`` ranges (at least one), each cut
    at the keyframe nearest to its share of equal parts (the one after the cut
    before it), so ranges are about ``target`` frames and as equal as the
    keyframes allow: 480 frames with keyframes every 48 at target 250 are two
    ranges of 240, not 288 + 192 (one of two workers idle for a third of the job). Fewer
    ranges when the keyframes are sparser than the parts; one range for all
    frames when there is no keyframe after the first frame.

    >>> [(r.start, r.stop, r.start_pts) for r in plan_ranges(range(10), [0, 3, 6, 9], 4)]
    [(0, 6, None), (6, 10, 6)]
    >>> [(r.start, r.stop) for r in plan_ranges([0, 2, 1, 3, 4], [0, 2, 4], 1)]
    [(0, 2), (2, 4), (4, 5)]
    >>> [(r.start, r.stop) for r in plan_ranges(range(480), range(0, 480, 48), 250)]
    [(0, 240), (240, 480)]
    """
    if target < 1:
        raise ValueError("target must be >= 1 frame")
    order = np.sort(np.asarray(pts, dtype=np.int64))
    n = len(order)
    if n == 0:
        return []
    positions = np.unique(np.searchsorted(order, np.asarray(keyframe_pts, dtype=np.int64)))
    positions = positions[(positions > 0) & (positions < n)]
    parts = max(1, round(n / target))
    cuts: list[int] = []
    for j in range(1, parts):
        after = positions[positions > (cuts[-1] if cuts else 0)]
        if after.size == 0:
            break
        cuts.append(int(after[np.argmin(np.abs(after - j * n / parts))]))
    ranges: list[FrameRange] = []
    start, start_pts = 0, None
    for pos in cuts:
        ranges.append(FrameRange(len(ranges), start, pos, start_pts, int(order[pos])))
        start, start_pts = pos, int(order[pos])
    ranges.append(FrameRange(len(ranges), start, n, start_pts, None))
    return ranges


def _open(path: Path, threads: int) -> tuple[Any, Any]:
    import av

    name = f"video:{path}"
    if not path.is_file():
        raise SourceError(f"{name}: file not found")
    try:
        container = av.open(str(path))
    except (av.FFmpegError, UnicodeDecodeError) as exc:
        raise SourceError(f"{name}: FFmpeg cannot read this file as a video ({exc})") from None
    if not container.streams.video:
        container.close()
        raise SourceError(f"{name}: the file has no video stream")
    stream = container.streams.video[0]
    stream.thread_type = "AUTO"
    stream.thread_count = max(1, threads)
    return container, stream


def index_video(path: Path, target: int) -> VideoIndex:
    """Read ``path``'s packet headers and plan ranges of about ``target`` frames.

    Raises :class:`SourceError` for a file FFmpeg cannot read, one with no
    pictures, and one whose packets end before the frame count its container
    announces (a truncated file).
    """
    import av

    path = Path(path)
    container, stream = _open(path, 1)
    name = f"video:{path}"
    pts: list[int] = []
    keys: list[int] = []
    missing = 0
    try:
        try:
            for packet in container.demux(stream):
                if not packet.size:
                    continue
                t = packet.pts if packet.pts is not None else packet.dts
                if t is None:
                    missing += 1
                    t = len(pts)
                pts.append(int(t))
                if packet.is_keyframe:
                    keys.append(int(t))
        except av.FFmpegError as exc:
            raise SourceError(
                f"{name}: cannot read packet {len(pts)} ({exc}); the file is damaged"
            ) from None
        cc = stream.codec_context
        size = (int(cc.width), int(cc.height))
        rate = stream.average_rate or stream.guessed_rate
        fps = float(rate) if rate else None
        announced = int(stream.frames or 0)
        pix = cc.pix_fmt
    finally:
        container.close()
    if not pts:
        raise SourceError(f"{name}: no frames")
    if announced and len(pts) < announced:
        raise SourceError(
            f"{name}: frame {len(pts)} is corrupt or missing (truncated file?): the file has "
            f"{len(pts)} of the {announced} frames it announces"
        )
    native = pix if pix in PLANAR and not (size[0] % 2 or size[1] % 2) else "bgr"
    split = ""
    if missing:
        split = f"{missing} packets carry no timestamp"
    elif len(set(pts)) != len(pts):
        split = "two packets carry the same timestamp"
    ranges = (
        plan_ranges(pts, keys, target) if not split else [FrameRange(0, 0, len(pts), None, None)]
    )
    return VideoIndex(
        len(pts), size, fps, native, len(keys), tuple(ranges), path.stat().st_size, split
    )


@dataclass
class ReadStats:
    """What :func:`read_range` read: bytes of packets demuxed, seconds decoding (wall)."""

    bytes: int = 0
    decode_s: float = 0.0
    reseeks: int = 0


def read_range(
    path: Path, r: FrameRange, layout: str, *, threads: int = 1, stats: ReadStats | None = None
) -> Iterator[Frame]:
    """The frames of range ``r`` of ``path`` in ``layout`` (``bgr``, ``gray`` or 4:2:0).

    Frames are numbered ``r.start`` .. ``r.stop - 1`` and come in presentation
    order; raises :class:`SourceError` naming the file and frames when the
    decoder gives a different number of frames than planned.
    """
    if layout not in ("bgr", "gray", *PLANAR):
        raise ValueError(f"unknown layout {layout!r}")
    stats = stats if stats is not None else ReadStats()
    seek = r.start_pts is not None
    for attempt in range(2):
        n = 0
        restart = False
        for frame in _decode(Path(path), r, layout, threads, seek, stats):
            if frame is None:  # the seek landed past the range's keyframe
                restart = True
                break
            yield Frame(frame, time.monotonic_ns(), r.start + n)
            n += 1
        if not restart:
            break
        if attempt == 0 and n == 0:
            stats.reseeks += 1
            seek = False
            continue
        raise SourceError(f"video:{path}: frames {r.start}..{r.stop - 1}: seeking failed")
    if n != r.frames:
        raise SourceError(
            f"video:{path}: frames {r.start}..{r.stop - 1}: decoded {n} of the {r.frames} "
            "frames the packets announce (damaged file?)"
        )


def _decode(
    path: Path, r: FrameRange, layout: str, threads: int, seek: bool, stats: ReadStats
) -> Iterator[np.ndarray[Any, Any] | None]:
    """Images of the range's frames; a None first means the seek went past its keyframe."""
    import av

    fmt = {"bgr": "bgr24", "gray": "gray"}.get(layout, layout)
    container, stream = _open(path, threads)
    name = f"video:{path}"
    size = (int(stream.codec_context.width), int(stream.codec_context.height))
    kept = 0
    try:
        if seek:
            container.seek(int(r.start_pts or 0), stream=stream, backward=True, any_frame=False)
        t0 = time.perf_counter()
        for packet in container.demux(stream):
            stats.bytes += int(packet.size or 0)
            try:
                decoded = packet.decode()
            except av.FFmpegError as exc:
                raise SourceError(
                    f"{name}: frame {r.start + kept} cannot be decoded ({exc})"
                ) from None
            for vf in decoded:
                t = vf.pts if vf.pts is not None else vf.dts
                if t is None:
                    raise SourceError(f"{name}: frame {r.start + kept} has no timestamp")
                if r.start_pts is not None and t < r.start_pts:
                    continue
                if r.stop_pts is not None and t >= r.stop_pts:
                    stats.decode_s += time.perf_counter() - t0
                    return
                if seek and kept == 0 and t != r.start_pts:
                    yield None
                    return
                image = frame_image(vf, fmt, size, name, r.start + kept)
                kept += 1
                stats.decode_s += time.perf_counter() - t0
                yield image
                t0 = time.perf_counter()
        stats.decode_s += time.perf_counter() - t0
    finally:
        container.close()


@dataclass(frozen=True)
class Segment:
    """One range's output file, to be joined: its path and the range's first frame."""

    path: Path
    start: int
    frames: int


def _frames_of(t: int | None, time_base: Fraction, rate: Fraction) -> int | None:
    return None if t is None else round(Fraction(t) * time_base * rate)


def join_segments(segments: Sequence[Segment], target: Path, fps: float) -> int:
    """Copy the packets of ``segments`` (in order) into ``target``, atomically; returns frames.

    Every segment must hold the frames its range planned, with the same codec
    and codec header (they come from one encoder setting). Raises
    :class:`OutputError` naming the segment otherwise.
    """
    import av

    from omnidev.outputs.files import VIDEO_CONTAINERS, rate_fraction

    target = Path(target)
    rate = rate_fraction(fps)
    fd, tmp_name = tempfile.mkstemp(
        prefix=f".{target.stem}.", suffix=target.suffix, dir=target.parent
    )
    os.close(fd)
    tmp = Path(tmp_name)
    total = 0
    try:
        out = av.open(str(tmp), mode="w", format=VIDEO_CONTAINERS[target.suffix.lower()])
        try:
            out_stream: Any = None
            header: bytes | None = None
            plans = []
            delay = 0
            for seg in segments:  # pass 1: timestamps in frames, the decoder's reorder delay
                packets = _segment_packets(seg, rate)
                if sorted(p[0] for p in packets) != list(range(seg.frames)):
                    raise OutputError(
                        f"{seg.path}: holds {len(packets)} frames, not frames 0..{seg.frames - 1} "
                        "of its range"
                    )
                delay = max([delay, *(i - p[0] for i, p in enumerate(packets))])
                plans.append(packets)
            decode_index = 0
            for seg, packets in zip(segments, plans, strict=True):
                container = av.open(str(seg.path))
                try:
                    stream = container.streams.video[0]
                    extradata = bytes(stream.codec_context.extradata or b"")
                    if out_stream is None:
                        out_stream = out.add_stream_from_template(stream)
                        header = extradata
                    elif extradata != header:
                        raise OutputError(
                            f"{seg.path}: its codec header differs from the first segment's"
                        )
                    i = 0
                    for packet in container.demux(stream):
                        if not packet.size:
                            continue
                        pts_frames = packets[i][0]
                        packet.pts = seg.start + pts_frames
                        packet.dts = decode_index - delay
                        packet.time_base = Fraction(1, 1) / rate
                        packet.stream = out_stream
                        out.mux(packet)
                        i += 1
                        decode_index += 1
                    total += i
                finally:
                    container.close()
        finally:
            out.close()
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise
    return total


def _segment_packets(seg: Segment, rate: Fraction) -> list[tuple[int, bool]]:
    """(presentation frame within the segment, keyframe) of each packet in decode order."""
    import av

    try:
        container = av.open(str(seg.path))
    except (av.FFmpegError, FileNotFoundError) as exc:
        raise OutputError(f"{seg.path}: cannot read the segment ({exc})") from None
    try:
        stream = container.streams.video[0]
        tb = Fraction(stream.time_base) if stream.time_base else Fraction(1, 1) / rate
        raw = [(p.pts, p.is_keyframe) for p in container.demux(stream) if p.size]
    finally:
        container.close()
    if all(t is None for t, _ in raw):
        return [(i, k) for i, (_, k) in enumerate(raw)]
    if any(t is None for t, _ in raw):
        raise OutputError(f"{seg.path}: some packets carry no timestamp; cannot join it")
    stamps = [int(t) for t, _ in raw if t is not None]
    first = min(stamps)
    out = []
    for t, (_, k) in zip(stamps, raw, strict=True):
        f = _frames_of(t - first, tb, rate)
        assert f is not None
        out.append((f, bool(k)))
    return out
