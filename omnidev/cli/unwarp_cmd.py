"""``omnidev unwarp``: omni-images, videos or live sources into panoramas and perspective views.

The unwarper is chosen by the calibration file's camera kind (``--camera``, or
the calibration a ``--rig`` file names), never by hand. Outputs are plugins
(omnidev.outputs): files, a Y4M or raw pipe (``-o -``), a V4L2 output device.
Frames flow through omnidev.videopipe (read, remap, write on their own
threads); a plain video file is decoded by PyAV (omnidev.sources.avfile) and,
when it decodes to 4:2:0, unwarped plane by plane (omnidev.planar) without a
trip through BGR.
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import os
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, cast

import cv2
from tqdm import tqdm

from omnidev.atomic import check_output
from omnidev.budget import check_memory
from omnidev.calibfile import load_camera
from omnidev.camera import Maps, Remapper, build_maps, map_bytes_per_pixel
from omnidev.cli.options import key_values
from omnidev.errors import OmnidevError, OutputError
from omnidev.frame import Frame
from omnidev.outputs import (
    MAX_FPS,
    Layout,
    Output,
    OutputSpec,
    open_output,
    split_output_uri,
    uses_stdout,
)
from omnidev.outputs.pixels import i420_size
from omnidev.planar import PlanarRemapper
from omnidev.rig import load_rig
from omnidev.sources import Source, avfile, open_source, split_uri
from omnidev.videopipe import Remap
from omnidev.videopipe import run as run_pipeline
from omnidev.viewspec import VIEW_HELP, parse_view


def usable_cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def register(sub: Any) -> None:
    p = sub.add_parser(
        "unwarp",
        help="unwarp an image, video or live source into views",
        description="Unwarp an omni-image, video or live source into one or more views. "
        "Pair each --view with an -o output, in order.",
        epilog=VIEW_HELP
        + "\noutputs: an image or video path (file:PATH?crf=&preset=&codec=), - or y4m:- "
        "(a Y4M stream on standard output), raw:-?format=bgr24, v4l2:/dev/videoN?format=yuyv "
        "(docs/outputs.md)"
        + "\ninputs: an image, a video file, images:GLOB, video:PATH[?loop=1&rate=FPS], "
        "v4l2:/dev/videoN[?width=W&height=H&fps=F], usb:VID:PID[:SERIAL] "
        "(quote a URI with & for the shell)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("input", nargs="?", help="source URI or path (omit with --rig)")
    p.add_argument("--camera", type=Path, help="calibration file (any registered kind)")
    p.add_argument("--rig", type=Path, help="rig TOML binding a source to its calibration")
    p.add_argument(
        "--camera-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="unwarper option, e.g. lookup=nearest for a pano-table",
    )
    p.add_argument("--view", action="append", required=True, help="view description")
    p.add_argument(
        "-o",
        "--output",
        action="append",
        required=True,
        help="output, one per --view: image or video path, -, y4m:-, raw:-, v4l2:/dev/videoN",
    )
    p.add_argument("--interpolation", choices=("linear", "nearest", "cubic"), default="linear")
    p.add_argument("--frames", type=int, help="stop after this many frames (at least 1)")
    p.add_argument(
        "--fps",
        type=float,
        help=f"output video frame rate, frames per second, (0, {MAX_FPS:g}] (default: the "
        "source's, else 25)",
    )
    p.add_argument(
        "--threads",
        type=int,
        default=usable_cores(),
        help="CPU threads for decoding, remapping and encoding (default: the usable cores)",
    )
    p.add_argument(
        "--stats", action="store_true", help="print frame count, fps and per-stage times (JSON)"
    )
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    t_start = time.perf_counter()
    if len(args.view) != len(args.output):
        raise OmnidevError(
            f"{len(args.view)} --view but {len(args.output)} -o: give one output per view"
        )
    if (args.camera is None) == (args.rig is None):
        raise OmnidevError("give exactly one of --camera FILE or --rig RIG.toml")
    if not 1 <= args.threads <= 256:
        raise OmnidevError(f"--threads {args.threads}: give 1 .. 256")
    if args.frames is not None and args.frames < 1:
        raise OmnidevError(f"--frames {args.frames}: give 1 or more")
    if args.fps is not None and not 0 < args.fps <= MAX_FPS:
        raise OmnidevError(f"--fps {args.fps:g}: give frames per second in (0, {MAX_FPS:g}]")
    outputs_uris = [str(o) for o in args.output]
    _check_distinct(outputs_uris)
    for o in outputs_uris:  # the common "exists" / folder mistakes fail before any work
        scheme, rest, _ = split_output_uri(o)
        if scheme == "file":
            check_output(Path(rest), force=args.force)
    uri = args.input
    calib_path = args.camera
    if args.rig is not None:
        rig = load_rig(args.rig)
        calib_path = rig.calibration
        uri = uri or rig.source_uri
    if not uri:
        raise OmnidevError("give an input source (path or URI)")
    views = [parse_view(v) for v in args.view]
    camera = load_camera(calib_path, key_values(args.camera_option, "--camera-option"))
    check_memory(
        sum(v.width * v.height * (map_bytes_per_pixel(camera) + 6.0) for v in views),
        "the maps of " + ", ".join(f"view {s}" for s in args.view),
    )
    try:
        maps = [build_maps(camera, v) for v in views]
    except ValueError as exc:  # a view the camera cannot fill (e.g. no elevation band)
        raise OmnidevError(f"{calib_path}: {exc}") from None
    t_maps = time.perf_counter()
    cv2.setNumThreads(args.threads)
    to_stderr = any(uses_stdout(o) for o in outputs_uris)
    with _open_input(uri, args.threads) as source:
        layout = _layout(source, maps)
        frames = _frames(source, layout)
        first = next(frames, None)
        if first is None:
            raise OmnidevError(f"{source.name}: no frames")
        size = _size(first.image, layout)
        if size != camera.image_size:
            raise OmnidevError(
                f"{source.name} frame {first.index} is {size[0]}x{size[1]}; the calibration is "
                f"for {camera.image_size[0]}x{camera.image_size[1]}"
            )
        if layout == "bgr" and first.image.ndim == 2:
            layout = "gray"
        remaps = [remapper_for(m, layout, args.interpolation) for m in maps]
        fps = args.fps or (source.fps if source.fps and source.fps <= MAX_FPS else None) or 25.0
        live = bool(getattr(source, "live", False))
        preferred = output_layouts(layout)
        with contextlib.ExitStack() as stack:
            outputs: list[Output] = []
            for o, m in zip(outputs_uris, maps, strict=True):
                spec = OutputSpec(
                    (m.shape[1], m.shape[0]), fps, preferred, args.force, live, args.threads
                )
                out = open_output(o, spec)
                stack.enter_context(out)  # closed (committed) on success, aborted on error
                outputs.append(out)
            total = source.frame_count
            if args.frames is not None:
                total = min(total, args.frames) if total else args.frames
            stats = _loop(
                itertools.chain([first], frames), source, size, layout, remaps, outputs, total,
                args.frames, live,
            )  # fmt: skip
    n = stats.frames
    say = sys.stderr if to_stderr else sys.stdout
    for out in outputs:
        verb = "sent" if split_output_uri(out.name)[0] in ("v4l2", "y4m", "raw") else "wrote"
        print(f"{verb} {out.name} ({n} frame{'s' if n != 1 else ''})", file=say)
    if args.stats:
        figures = stats.as_dict()
        figures["setup_s"] = round(t_maps - t_start, 4)
        figures["total_s"] = round(time.perf_counter() - t_start, 4)
        figures["layout"] = layout
        figures["threads"] = args.threads
        print(json.dumps(figures), file=sys.stderr)
    return 0


def _check_distinct(uris: list[str]) -> None:
    keys = []
    for o in uris:
        scheme, rest, _ = split_output_uri(o)
        if scheme == "file":
            keys.append(("file", str(Path(rest).resolve())))
        elif scheme in ("y4m", "raw") and rest in ("", "-"):
            keys.append(("stdout", ""))
        else:
            keys.append((scheme, rest))
    if len(set(keys)) != len(keys):
        raise OutputError("two views write the same output (file, device or standard output)")


def _open_input(uri: str, threads: int) -> Source:
    """A plain video file through PyAV (threaded, 4:2:0 planes); anything else by its plugin."""
    scheme, rest, options = split_uri(uri)
    if scheme == "video" and not options and avfile.available():
        path = rest if uri.startswith("video:") else uri
        return cast(Source, avfile.AvVideoSource(path, threads=threads))
    return open_source(uri)


def _layout(source: Source, maps: list[Maps]) -> Layout:
    return frame_layout(getattr(source, "native_layout", "bgr"), maps)


def frame_layout(native: str, maps: Sequence[Maps]) -> Layout:
    """The layout frames are remapped in: the decoder's 4:2:0 when every view is even-sized."""
    even = all(m.shape[0] % 2 == 0 and m.shape[1] % 2 == 0 for m in maps)
    if native in ("yuv420p", "yuvj420p") and even:
        return cast(Layout, native)
    return "bgr"


def output_layouts(layout: Layout) -> tuple[Layout, ...]:
    """The layouts offered to the outputs for frames in ``layout``, preferred first."""
    return (layout, "yuv420p", "bgr") if layout == "yuvj420p" else (layout,)


def _frames(source: Source, layout: Layout) -> Iterator[Frame]:
    if layout != "bgr" and isinstance(source, avfile.AvVideoSource):
        return source.frames(layout)
    return iter(source)


def _size(image: Any, layout: Layout) -> tuple[int, int]:
    if layout in ("yuv420p", "yuvj420p"):
        return i420_size(image)
    return int(image.shape[1]), int(image.shape[0])


def remapper_for(maps: Maps, layout: Layout, interpolation: Any) -> Remap:
    """The remap that unwarps frames in ``layout`` (4:2:0 plane by plane, else BGR/gray)."""
    if layout in ("yuv420p", "yuvj420p"):
        return PlanarRemapper(maps, interpolation=interpolation, full_range=layout == "yuvj420p")
    return Remapper(maps, interpolation=interpolation)


def _loop(
    frames: Iterator[Frame],
    source: Source,
    size: tuple[int, int],
    layout: Layout,
    remaps: list[Remap],
    outputs: list[Output],
    total: int | None,
    limit: int | None,
    live: bool,
) -> Any:
    bar = tqdm(
        total=total,
        unit="frame",
        file=sys.stderr,
        disable=live or total == 1,
        dynamic_ncols=True,
        leave=False,
    )
    t0 = time.monotonic()
    last_report = [t0]

    def check(frame: Frame) -> None:
        got = _size(frame.image, layout)
        if got != size:
            raise OmnidevError(
                f"{source.name} frame {frame.index} is {got[0]}x{got[1]}; the calibration is "
                f"for {size[0]}x{size[1]}"
            )

    def progress(n: int) -> None:
        bar.update(1)
        now = time.monotonic()
        if live and now - last_report[0] >= 1.0:
            print(f"\r{n} frames, {n / (now - t0):.1f} fps", end="", file=sys.stderr)
            last_report[0] = now

    try:
        stats = run_pipeline(
            frames, layout, remaps, outputs, limit=limit, check=check, on_written=progress
        )
    finally:
        bar.close()
        if live:
            print(file=sys.stderr)
    if stats.frames == 0:
        raise OmnidevError(f"{source.name}: no frames")
    return stats
