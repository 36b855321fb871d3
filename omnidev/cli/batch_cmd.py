"""``omnidev batch unwarp``: unwarp video archives and image sets on a Dask cluster.

See docs/batch.md. The work is done by omnidev.batch (inputs, ranges, tasks,
journal, runner); this module reads the options, starts or reaches the
cluster, and prints the per-input summary. Exit status: 0 when every input
is done, 1 when some failed (each was reported on one line and the others
finished), 2 for a mistake in the command, 130 when interrupted (what
finished is kept; the same command finishes the job).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import sys
import tempfile
from pathlib import Path
from typing import Any

from omnidev.batch.inputs import VIDEO_FORMATS, collect_inputs
from omnidev.batch.runner import JobReport, Settings, connect, run_job, start_local_cluster
from omnidev.batch.runner import usable_cores as _cores
from omnidev.cli.options import key_values
from omnidev.errors import OmnidevError
from omnidev.outputs import OutputSpec
from omnidev.outputs.files import IMAGE_SUFFIXES, FileOutput


def register(sub: Any) -> None:
    p = sub.add_parser(
        "batch",
        help="batch jobs on a Dask cluster (unwarp video archives and image sets)",
        description="Batch jobs on a Dask cluster (docs/batch.md).",
    )
    jobs = p.add_subparsers(dest="job", metavar="JOB", required=True)
    u = jobs.add_parser(
        "unwarp",
        help="unwarp many videos and images into views, frame-exact and resumable",
        description="Unwarp videos and images into views on a Dask cluster: a local one "
        "(--workers N, the default) or an existing one (--scheduler tcp://HOST:PORT, or the "
        "Dask config's scheduler-address). Videos are split into frame ranges at keyframes, "
        "one task each, and joined into one file per input and view: OUT/VIEW/REL, with REL "
        "the input's path below the inputs' common folder. Rerunning the same command does "
        "only what is missing (job manifest in OUT/.omnidev-batch/).",
    )
    u.add_argument(
        "inputs",
        nargs="+",
        metavar="INPUT",
        help="video or image file, glob ('archive/**/*.mp4', quoted), or manifest (.csv or "
        ".jsonl rows: input, camera, views)",
    )
    u.add_argument(
        "--camera", type=Path, help="calibration file (rows of a manifest may name their own)"
    )
    u.add_argument(
        "--view",
        action="append",
        default=[],
        metavar="[NAME=]SPEC",
        help="a view (omnidev unwarp's syntax), repeatable; NAME names its output folder",
    )
    u.add_argument("--out", type=Path, required=True, help="output folder")
    where = u.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        default=None,
        help=f"worker processes of a local cluster (default: the usable cores, {_cores()})",
    )
    where.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler")
    u.add_argument(
        "--format", default="mp4", choices=[s.lstrip(".") for s in VIDEO_FORMATS],
        help="video output container (mp4/mkv/mov: H.264; avi: Motion JPEG)",
    )  # fmt: skip
    u.add_argument(
        "--image-format", default="png", choices=sorted(s.lstrip(".") for s in IMAGE_SUFFIXES),
        help="output format of image inputs",
    )  # fmt: skip
    u.add_argument(
        "--encode",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="video encoder option (as file:PATH?KEY=VALUE of omnidev unwarp: codec, crf, "
        "preset, q)",
    )
    u.add_argument(
        "--camera-option", action="append", default=[], metavar="KEY=VALUE",
        help="unwarper option, e.g. lookup=nearest for a pano-table",
    )  # fmt: skip
    u.add_argument("--interpolation", choices=("linear", "nearest", "cubic"), default="linear")
    u.add_argument("--fps", type=float, help="output frame rate (default: each input's)")
    u.add_argument(
        "--range-frames", type=int, default=250,
        help="about this many frames per video task (ranges start at keyframes)",
    )  # fmt: skip
    u.add_argument("--images-per-task", type=int, default=16, help="images per image task")
    u.add_argument(
        "--task-threads", type=int, default=1,
        help="cores per task: threads for decoding, remapping, encoding, and its stages at work "
        "at once (default 1: one task per core)",
    )  # fmt: skip
    u.add_argument("--force", action="store_true", help="overwrite outputs of other jobs")
    u.add_argument(
        "--keep-segments", action="store_true", help="keep the per-range files after joining"
    )
    u.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    u.add_argument("--no-progress", action="store_true", help="no progress bar")
    u.set_defaults(func=run)


def _settings(args: argparse.Namespace) -> Settings:
    for flag, value in (
        ("--range-frames", args.range_frames),
        ("--images-per-task", args.images_per_task),
        ("--task-threads", args.task_threads),
    ):
        if value < 1:
            raise OmnidevError(f"{flag} {value}: give 1 or more")
    if args.workers is not None and args.workers < 1:
        raise OmnidevError(f"--workers {args.workers}: give 1 or more")
    if args.fps is not None and not args.fps > 0:
        raise OmnidevError(f"--fps {args.fps}: give a frame rate > 0")
    encode = key_values(args.encode, "--encode")
    suffix = f".{args.format}"
    with tempfile.TemporaryDirectory() as tmp:  # the file output checks the options
        FileOutput(Path(tmp) / f"check{suffix}", OutputSpec((2, 2), 25.0), encode).abort()
    return Settings(
        interpolation=args.interpolation,
        video_suffix=suffix,
        image_suffix=f".{args.image_format}",
        encode=tuple(sorted(encode.items())),
        camera_options=tuple(sorted(key_values(args.camera_option, "--camera-option").items())),
        range_frames=args.range_frames,
        images_per_task=args.images_per_task,
        task_threads=args.task_threads,
        fps=args.fps,
        force=args.force,
        keep_segments=args.keep_segments,
    )


def run(args: argparse.Namespace) -> int:
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise OmnidevError(
            "omnidev batch needs Dask: pip install 'omnidev[batch]' (dask[distributed])"
        ) from None
    settings = _settings(args)
    inputs, bad = collect_inputs(args.inputs, camera=args.camera, views=args.view)
    if not inputs and not bad:
        raise OmnidevError("no inputs")
    logging.getLogger("distributed").setLevel(logging.ERROR)
    with contextlib.ExitStack() as stack:
        if args.scheduler is not None or _configured_scheduler():
            client = connect(args.scheduler)
        else:
            cluster, client = start_local_cluster(args.workers or _cores())
            stack.callback(cluster.close)
        stack.callback(client.close)
        try:
            report = run_job(inputs, bad, args.out, settings, client, progress=not args.no_progress)
        except KeyboardInterrupt as exc:
            partial: JobReport | None = getattr(exc, "report", None)
            if partial is not None:
                _print(partial, args.json)
            done = sum(u.ranges_run for u in partial.inputs) if partial else 0
            print(
                f"omnidev batch: interrupted; {done} ranges finished now are kept: run the "
                "same command to finish",
                file=sys.stderr,
            )
            return 130
    _print(report, args.json)
    return 1 if report.failed else 0


def _configured_scheduler() -> bool:
    import dask

    return bool(dask.config.get("scheduler-address", None))


def _print(report: JobReport, as_json: bool) -> None:
    if as_json:
        print(json.dumps(report.as_dict()))
        return
    rows = [("input", "status", "frames", "ranges run/before", "seconds")]
    for u in report.inputs:
        ranges = f"{u.ranges_run}/{u.ranges_before}" if u.kind == "video" else "-"
        status = u.status if u.status != "skipped" else "done before"
        rows.append((u.input, status, str(u.frames), ranges, f"{u.seconds:.1f}"))
    widths = [max(len(r[c]) for r in rows) for c in range(len(rows[0]))]
    for r in rows:
        print("  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)).rstrip())
    d = report.as_dict()
    frames = sum(u.frames for u in report.inputs if u.status == "ok")
    print(
        f"{len(report.inputs)} inputs: {d['ok']} done, {d['skipped']} done before, "
        f"{d['failed']} failed; {frames} frames in {report.wall_s:.1f} s on "
        f"{report.workers} workers ({report.threads} threads)"
    )
