"""Running a tracker pipeline in the foreground, shared by ``omnidev mouse`` and
``omnidev laser``: the daemon's pipeline on any source into any sink until a file
source ends or Ctrl-C / SIGTERM; every button is released on the way out.

The source policy is the daemon's (docs/daemon.md, "Sources and the frame queue"):
a file is read as fast as the tracker takes it, every frame, with the file's own
timestamps; a camera (or a file paced with ``rate=``) drops its oldest frame when
the tracker is behind, and the exit summary counts the drops. A missing, truncated
or corrupt file ends the run with one line naming the last good frame (exit 2)."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any

from omnidev.cli.options import sink_options
from omnidev.errors import OmnidevError


def add_pointer_arguments(p: argparse.ArgumentParser) -> None:
    """The options every foreground pointer command has: sink, screen, filter, buttons."""
    p.epilog = (
        "Sources: a video file or image set is read as fast as the tracker takes it, every "
        "frame, with the file's own timestamps for the filter and --dwell; a camera, or a "
        "file paced with ?rate=N or ?rate=realtime, drops its oldest frame when the tracker "
        "is behind. The summary at the end counts frames, drops and cursor positions. A "
        "missing, truncated or corrupt file stops with an error naming its last good "
        "frame (exit 2). See docs/daemon.md, 'Sources and the frame queue'."
    )
    p.add_argument(
        "--sink",
        default="record",
        metavar="NAME",
        help="where the pointer goes: uinput (the kernel pointer), xtest (an X server, "
        "--sink-option display=:0), hidg (a USB gadget), record (JSON lines to "
        "--sink-option path=FILE; default: record to standard output); see docs/sinks.md",
    )
    p.add_argument(
        "--sink-option", action="append", default=[], metavar="KEY=VALUE", help="sink option"
    )
    p.add_argument("--screen", default="1920x1080+0+0", help="target screen WxH+X+Y")
    p.add_argument("--filter", choices=("one-euro", "none"), default="one-euro")
    p.add_argument(
        "--buttons",
        default="",
        metavar="SPEC",
        help="pointer buttons from a key or HID remote, e.g. "
        "'evdev:/dev/input/event3?KEY_SPACE=left' (see docs/buttons.md)",
    )
    p.add_argument("--dwell", action="store_true", help="click when the cursor rests")
    p.add_argument("--dwell-s", type=float, default=0.8, help="dwell time, s (default 0.8)")
    p.add_argument(
        "--dwell-radius-px",
        type=float,
        default=12.0,
        help="the cursor rests while it stays within this radius, screen px (default 12)",
    )


def run_foreground(
    args: argparse.Namespace,
    name: str,
    tracker: dict[str, Any],
    *,
    check: Callable[[Any, Any], None] | None = None,
) -> int:
    """Run ``tracker`` (the daemon config's [tracker] table) on ``args.source``.

    ``check(pipeline, config)`` may warn about the configuration before the start.
    """
    from omnidev.daemon.config import parse_config
    from omnidev.daemon.pipeline import Pipeline
    from omnidev.sources import open_source

    options = sink_options(args.sink_option)
    if args.sink == "record" and "path" not in options:
        options["path"] = "-"  # the default: the pointer's events on standard output
    with open_source(args.source):  # a missing camera: a clear error now, not a retry loop
        pass
    doc = {
        "source": {"uri": args.source},
        "tracker": tracker,
        "filter": {"kind": args.filter},
        "sink": {"name": args.sink, "options": options},
        "screen": {"rect": args.screen},
        "daemon": {"queue": 1},
        "buttons": {
            "input": args.buttons,
            "dwell": args.dwell,
            "dwell_s": args.dwell_s,
            "dwell_radius_px": args.dwell_radius_px,
        },
    }
    config = parse_config(doc, Path(f"omnidev {name}"))
    pipeline = Pipeline(config, log_fatal=False)  # the error ends the command, once
    if check is not None:
        check(pipeline, config)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    pipeline.start()
    failure: str | None = None
    try:
        while not stop.wait(0.05):
            if pipeline.fatal is None and pipeline.ended.is_set():
                break  # the file ended
            if pipeline.fatal is not None or not pipeline.alive:
                failure = pipeline.fatal or "the pipeline stopped unexpectedly (see the log above)"
                break
    finally:
        pipeline.stop()
        for s, h in old.items():
            signal.signal(s, h)
    st = pipeline.status()
    clicks = f", {st['dwell_clicks']} dwell clicks" if args.dwell else ""
    print(f"{pipeline.summary()}{clicks}; buttons released", file=sys.stderr)
    if failure is not None:
        raise OmnidevError(failure)
    return 0
