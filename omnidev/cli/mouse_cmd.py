"""``omnidev mouse SOURCE --layout FILE --sink NAME``: the camera mouse in the foreground.

Runs the daemon's pipeline (source -> camera-mouse tracker -> One Euro filter
-> sink) on any source into any sink, until a file source ends or Ctrl-C /
SIGTERM; buttons are released on the way out.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from pathlib import Path
from types import FrameType
from typing import Any

from omnidev.errors import OmnidevError


def register(sub: Any) -> None:
    p = sub.add_parser(
        "mouse",
        help="run the camera mouse (hand-held webcam aimed at a monitor) into a pointer sink",
        description=__doc__.splitlines()[0] if __doc__ else None,
    )
    p.add_argument("source", help="source URI or path (v4l2:/dev/video0, a video file, ...)")
    p.add_argument("--layout", required=True, type=Path, help="landmark layout (JSON or TOML)")
    p.add_argument("--sink", default="record", help="sink plugin (uinput, xtest, hidg, record)")
    p.add_argument(
        "--sink-option", action="append", default=[], metavar="KEY=VALUE", help="sink option"
    )
    p.add_argument("--method", choices=("homography", "affine"), default="homography")
    p.add_argument("--screen", default="1920x1080+0+0", help="target screen WxH+X+Y")
    p.add_argument("--filter", choices=("one-euro", "none"), default="one-euro")
    p.set_defaults(func=run)


def _value(text: str) -> Any:
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


def run(args: argparse.Namespace) -> int:
    from omnidev.daemon.config import parse_config
    from omnidev.daemon.pipeline import Pipeline
    from omnidev.sources import open_source

    if not args.layout.is_file():
        raise OmnidevError(f"{args.layout}: landmark layout file not found")
    options: dict[str, Any] = {}
    for item in args.sink_option:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise OmnidevError(f"--sink-option {item!r} is not KEY=VALUE")
        options[key] = _value(value)
    with open_source(args.source) as probe:  # a clear error now, not a retry loop
        ends = probe.frame_count is not None  # a file that is not looped
    doc = {
        "source": {"uri": args.source},
        "tracker": {
            "name": "camera-mouse",
            "calibration": str(args.layout.resolve()),
            "options": {"method": args.method},
        },
        "filter": {"kind": args.filter},
        "sink": {"name": args.sink, "options": options},
        "screen": {"rect": args.screen},
    }
    config = parse_config(doc, Path("omnidev mouse"))
    pipeline = Pipeline(config)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    pipeline.start()
    try:
        while not stop.wait(0.1):
            st = pipeline.status()
            if ends and st["state"] == "waiting for camera":
                break  # the file ended
            if not pipeline.alive:
                raise OmnidevError("the pipeline stopped unexpectedly (see the log above)")
        time.sleep(0.05)
    finally:
        pipeline.stop()
        for s, h in old.items():
            signal.signal(s, h)
    st = pipeline.status()
    print(
        f"{st['frames']} frames, {st['tracked']} cursor positions, latency p50 "
        f"{st['latency_p50_ms']} ms; buttons released",
        file=sys.stderr,
    )
    return 0
