"""``omnidev unwarp``: omni-images, videos or live sources into panoramas and perspective views.

The unwarper is chosen by the calibration file's camera kind (``--camera``, or
the calibration a ``--rig`` file names), never by hand.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path
from typing import Any

from tqdm import tqdm

from omnidev.atomic import check_output
from omnidev.budget import check_memory
from omnidev.calibfile import load_camera
from omnidev.camera import Remapper, build_maps, map_bytes_per_pixel
from omnidev.cli.options import key_values
from omnidev.errors import OmnidevError, OutputError
from omnidev.rig import load_rig
from omnidev.sources import open_source
from omnidev.viewspec import VIEW_HELP, parse_view
from omnidev.writers import MAX_FPS, VIDEO_FOURCC, FrameWriter, is_image_path


def register(sub: Any) -> None:
    p = sub.add_parser(
        "unwarp",
        help="unwarp an image, video or live source into views",
        description="Unwarp an omni-image, video or live source into one or more views. "
        "Pair each --view with an -o output, in order.",
        epilog=VIEW_HELP
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
    p.add_argument(
        "--view",
        action="append",
        required=True,
        metavar="KIND:WxH[,KEY=V...]",
        help="a view (kinds and keys below); repeat with one -o each",
    )
    p.add_argument(
        "-o",
        "--output",
        action="append",
        type=Path,
        required=True,
        help="output image or video, one per --view",
    )
    p.add_argument("--interpolation", choices=("linear", "nearest", "cubic"), default="linear")
    p.add_argument("--frames", type=int, help="stop after this many frames (at least 1)")
    p.add_argument(
        "--fps",
        type=float,
        help="output video frame rate, frames per second, (0, 1000] (default: the source's, "
        "else 25)",
    )
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if len(args.view) != len(args.output):
        raise OmnidevError(
            f"{len(args.view)} --view but {len(args.output)} -o: give one output per view"
        )
    if (args.camera is None) == (args.rig is None):
        raise OmnidevError("give exactly one of --camera FILE or --rig RIG.toml")
    uri = args.input
    calib_path = args.camera
    if args.rig is not None:
        rig = load_rig(args.rig)
        calib_path = rig.calibration
        uri = uri or rig.source_uri
    if not uri:
        raise OmnidevError("give an input source (path or URI)")
    if args.frames is not None and args.frames < 1:
        raise OmnidevError(f"--frames {args.frames}: at least 1")
    if args.fps is not None and not 0 < args.fps <= MAX_FPS:
        raise OmnidevError(f"--fps {args.fps:g}: give frames per second in (0, {MAX_FPS:g}]")
    for out in args.output:
        check_output(out, force=args.force)
        if not (is_image_path(out) or out.suffix.lower() in VIDEO_FOURCC):
            FrameWriter(out, force=args.force)  # the one-line "unknown output type" error
    if len({o.resolve() for o in args.output}) != len(args.output):
        raise OutputError("two views write the same output file")
    views = [parse_view(v) for v in args.view]
    camera = load_camera(calib_path, key_values(args.camera_option, "--camera-option"))
    check_memory(
        sum(v.width * v.height * (map_bytes_per_pixel(camera) + 6.0) for v in views),
        "the maps of " + ", ".join(f"view {s}" for s in args.view),
    )
    try:
        remappers = [
            Remapper(build_maps(camera, v), interpolation=args.interpolation) for v in views
        ]
    except ValueError as exc:  # a view the camera cannot fill (e.g. no elevation band)
        raise OmnidevError(f"{calib_path}: {exc}") from None
    with open_source(uri) as source:
        fps = args.fps or source.fps or 25.0
        with contextlib.ExitStack() as stack:
            writers = [
                stack.enter_context(FrameWriter(o, fps=fps, force=args.force)) for o in args.output
            ]
            total = source.frame_count
            if args.frames is not None:
                total = min(total, args.frames) if total else args.frames
            n = _loop(source, camera.image_size, remappers, writers, total, args.frames)
    for w in writers:
        print(f"wrote {w.path} ({n} frame{'s' if n != 1 else ''})")
    return 0


def _loop(
    source: Any,
    size: tuple[int, int],
    remappers: list[Remapper],
    writers: list[FrameWriter],
    total: int | None,
    limit: int | None,
) -> int:
    live = bool(getattr(source, "live", False))
    bar = tqdm(
        total=total,
        unit="frame",
        file=sys.stderr,
        disable=live or total == 1,
        dynamic_ncols=True,
        leave=False,
    )
    n = 0
    t0 = time.monotonic()
    last_report = t0
    try:
        for frame in source:
            h, w = frame.image.shape[:2]
            if (w, h) != size:
                raise OmnidevError(
                    f"{source.name} frame {frame.index} is {w}x{h}; the calibration is for "
                    f"{size[0]}x{size[1]}"
                )
            for remap, writer in zip(remappers, writers, strict=True):
                writer.write(remap(frame.image))
            n += 1
            bar.update(1)
            now = time.monotonic()
            if live and now - last_report >= 1.0:
                print(f"\r{n} frames, {n / (now - t0):.1f} fps", end="", file=sys.stderr)
                last_report = now
            if limit is not None and n >= limit:
                break
    finally:
        bar.close()
        if live:
            print(file=sys.stderr)
    if n == 0:
        raise OmnidevError(f"{source.name}: no frames")
    return n
