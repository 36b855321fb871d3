"""The functions a batch job runs on its workers, one call per task.

Each takes a small, picklable job description and, for the remapping tasks,
the views' :class:`~omnidev.camera.Maps` (built once by the client and
scattered: Dask moves them to a worker once and hands the same objects to
every task there). The remappers made from them (fixed-point maps, chroma
maps) are kept per worker process in a small cache, so they too are made
once per worker, not per task.

A user-facing error (:class:`~omnidev.errors.OmnidevError`: a damaged file, a
wrong frame size) is returned as :class:`Failure` naming the input; anything
else raises and reaches the client as the task's exception. Every file a task
writes is written to a temporary name and renamed into place, so a task that
dies (or a worker that is lost) leaves no partial output and can simply run
again.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import cv2
import numpy as np

from omnidev.batch.avrange import (
    FrameRange,
    ReadStats,
    Segment,
    VideoIndex,
    index_video,
    read_range,
)
from omnidev.batch.avrange import join_segments as _join
from omnidev.camera import Maps
from omnidev.errors import OmnidevError
from omnidev.frame import Frame
from omnidev.outputs import Layout, Output, OutputSpec
from omnidev.outputs.files import FileOutput
from omnidev.videopipe import Remap
from omnidev.videopipe import run as run_pipeline


@dataclass(frozen=True)
class Failure:
    """A task that could not do its work: ``message`` is one line naming the input."""

    message: str


@dataclass(frozen=True)
class RangeJob:
    """One frame range of one video into every view's segment file.

    Attributes:
        path: the video (absolute).
        frames: the range.
        layout: the layout frames are remapped in (unwarp's choice for this input).
        out_layouts: layouts offered to the outputs, preferred first.
        interpolation: ``linear``, ``nearest`` or ``cubic``.
        fps: output frame rate, frames per second.
        segments: one output file per view (absolute; the final file's suffix).
        encode: file output options (``crf``, ``preset``, ``codec``, ``q``).
        map_keys: one key per view naming its maps (the remapper cache's key).
        threads: the cores the task keeps busy: threads of the decoder, the
            encoders and OpenCV's remap, and how many of the pipeline's read,
            remap and write stages work at once (videopipe's ``cpu_slots``).
    """

    path: str
    frames: FrameRange
    layout: Layout
    out_layouts: tuple[Layout, ...]
    interpolation: str
    fps: float
    segments: tuple[str, ...]
    encode: tuple[tuple[str, str], ...]
    map_keys: tuple[str, ...]
    threads: int = 1


@dataclass(frozen=True)
class RangeResult:
    """What a range task did: frames written, bytes, seconds per part (see docs/batch.md).

    ``cpu_s`` holds each pipeline stage's CPU seconds (``read``, ``remap``,
    ``write``: all views' encoders together); ``setup_s`` is the task's wall
    time outside the pipeline (opening, seeking, starting and closing the
    encoders).
    """

    frames: int
    segment_bytes: tuple[int, ...]
    read_bytes: int
    wall_s: float
    setup_s: float
    cpu_s: dict[str, float]
    worker: str
    pid: int
    reseeks: int = 0


@dataclass(frozen=True)
class ImagesJob:
    """A chunk of images: each image into one file per view.

    Attributes:
        images: the input images (absolute).
        outputs: per image, one output path per view.
        interpolation, map_keys, threads: as :class:`RangeJob`.
    """

    images: tuple[str, ...]
    outputs: tuple[tuple[str, ...], ...]
    interpolation: str
    map_keys: tuple[str, ...]
    threads: int = 1


@dataclass(frozen=True)
class ImagesResult:
    """Per image of the chunk: None when written, else the one-line reason."""

    errors: tuple[str | None, ...]
    wall_s: float
    cpu_s: dict[str, float] = field(default_factory=dict)
    worker: str = ""
    pid: int = 0


@dataclass(frozen=True)
class JoinJob:
    """The segments of one input's view into its output file."""

    segments: tuple[tuple[str, int, int], ...]  # (path, first frame, frames)
    target: str
    fps: float


@dataclass(frozen=True)
class JoinResult:
    frames: int
    bytes: int
    wall_s: float


_CACHE_SIZE = 16
_cache: OrderedDict[tuple[str, str, str], Remap] = OrderedDict()
_cache_lock = threading.Lock()


def _remapper(key: str, maps: Maps, layout: Layout, interpolation: str) -> Remap:
    """The remap for (maps, layout, interpolation), made once per worker process."""
    from omnidev.cli.unwarp_cmd import remapper_for

    k = (key, layout, interpolation)
    with _cache_lock:
        fn = _cache.get(k)
        if fn is not None:
            _cache.move_to_end(k)
            return fn
    fn = remapper_for(maps, layout, interpolation)
    with _cache_lock:
        _cache[k] = fn
        while len(_cache) > _CACHE_SIZE:
            _cache.popitem(last=False)
    return fn


def cached_remappers() -> int:
    """How many remappers this process holds (tests: made once per worker)."""
    return len(_cache)


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


def index_task(path: str, camera_size: tuple[int, int], target: int) -> VideoIndex | Failure:
    """Index a video (omnidev.batch.avrange.index_video) and check its frame size."""
    try:
        index = index_video(Path(path), target)
    except OmnidevError as exc:
        return Failure(str(exc))
    if index.size != tuple(camera_size):
        w, h = index.size
        return Failure(
            f"video:{path} frame 0 is {w}x{h}; the calibration is for "
            f"{camera_size[0]}x{camera_size[1]}"
        )
    return index


def range_task(job: RangeJob, maps: Sequence[Maps]) -> RangeResult | Failure:
    """Decode ``job.frames``, unwarp every frame into each view, encode each view's segment."""
    t0 = time.perf_counter()
    cv2.setNumThreads(job.threads)
    try:
        remaps = [
            _remapper(k, m, job.layout, job.interpolation)
            for k, m in zip(job.map_keys, maps, strict=True)
        ]
        read = ReadStats()
        frames = read_range(Path(job.path), job.frames, job.layout, threads=job.threads, stats=read)
        with contextlib.ExitStack() as stack:
            outputs: list[Output] = []
            for seg, m in zip(job.segments, maps, strict=True):
                Path(seg).parent.mkdir(parents=True, exist_ok=True)
                spec = OutputSpec(
                    (m.shape[1], m.shape[0]), job.fps, job.out_layouts, True, False, job.threads
                )
                out = FileOutput(Path(seg), spec, dict(job.encode))
                stack.enter_context(out)
                outputs.append(cast(Output, out))
            stats = run_pipeline(frames, job.layout, remaps, outputs, cpu_slots=job.threads)
        if stats.frames != job.frames.frames:
            return Failure(
                f"video:{job.path}: frames {job.frames.start}..{job.frames.stop - 1}: wrote "
                f"{stats.frames} of {job.frames.frames}"
            )
    except OmnidevError as exc:
        return Failure(str(exc))
    wall = time.perf_counter() - t0
    cpu: dict[str, float] = {"read": 0.0, "remap": 0.0, "write": 0.0}
    for name, st in stats.stages.items():
        cpu[name.partition(":")[0]] += st.cpu_s
    return RangeResult(
        frames=stats.frames,
        segment_bytes=tuple(Path(s).stat().st_size for s in job.segments),
        read_bytes=read.bytes,
        wall_s=wall,
        setup_s=max(0.0, wall - stats.wall_s),
        cpu_s=cpu,
        worker=_worker_name(),
        pid=os.getpid(),
        reseeks=read.reseeks,
    )


def images_task(job: ImagesJob, maps: Sequence[Maps]) -> ImagesResult:
    """Unwarp each image of the chunk into every view (as ``omnidev unwarp IMAGE``)."""
    t0 = time.perf_counter()
    cv2.setNumThreads(job.threads)
    remaps = [
        _remapper(k, m, "bgr", job.interpolation) for k, m in zip(job.map_keys, maps, strict=True)
    ]
    errors: list[str | None] = []
    cpu = {"read": 0.0, "remap": 0.0, "write": 0.0}
    for path, outs in zip(job.images, job.outputs, strict=True):
        try:
            c0 = time.thread_time()
            image = cv2.imread(path, cv2.IMREAD_COLOR)
            c1 = time.thread_time()
            cpu["read"] += c1 - c0
            if image is None:
                raise OmnidevError(f"images:{path}: cannot read image {path} (frame 0)")
            h, w = image.shape[:2]
            sw, sh = maps[0].source_size
            if (w, h) != (sw, sh):
                raise OmnidevError(
                    f"images:{path} frame 0 is {w}x{h}; the calibration is for {sw}x{sh}"
                )
            frame = Frame(np.asarray(image, np.uint8), time.monotonic_ns(), 0)
            for fn, out_path, m in zip(remaps, outs, maps, strict=True):
                c0 = time.thread_time()
                view = fn(frame.image)
                c1 = time.thread_time()
                Path(out_path).parent.mkdir(parents=True, exist_ok=True)
                spec = OutputSpec((m.shape[1], m.shape[0]), 25.0, ("bgr",), True)
                out = FileOutput(Path(out_path), spec)
                with out:
                    out.write(Frame(view, frame.timestamp_ns, 0))
                cpu["remap"] += c1 - c0
                cpu["write"] += time.thread_time() - c1
            errors.append(None)
        except OmnidevError as exc:
            errors.append(str(exc))
    return ImagesResult(tuple(errors), time.perf_counter() - t0, cpu, _worker_name(), os.getpid())


def join_task(job: JoinJob) -> JoinResult | Failure:
    """Join one view's segments into its output file (packets copied, atomically)."""
    t0 = time.perf_counter()
    try:
        segments = [Segment(Path(p), s, n) for p, s, n in job.segments]
        Path(job.target).parent.mkdir(parents=True, exist_ok=True)
        frames = _join(segments, Path(job.target), job.fps)
    except OmnidevError as exc:
        return Failure(str(exc))
    return JoinResult(frames, Path(job.target).stat().st_size, time.perf_counter() - t0)


def noop_task(x: int) -> int:
    """A task that does nothing (the per-task overhead anchor of bench/batch.py)."""
    return x
