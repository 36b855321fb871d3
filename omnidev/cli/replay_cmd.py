"""``omnidev replay RECORDING --sink NAME``: play a ``record`` sink's JSON lines into a sink."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from omnidev.cli.options import sink_options
from omnidev.errors import OmnidevError


def register(sub: Any) -> None:
    p = sub.add_parser(
        "replay",
        help="replay a pointer recording (JSON lines of the record sink) into a sink",
        description="Send the moves and buttons of a recording to a sink, with the "
        "original timing unless --fast: by default the spacing of the frames the "
        "positions came from (a recording of a video file replays at the video's pace, "
        "however fast it was tracked), or with --timing written the spacing of the "
        "lines as they were written. Recordings of format 1 (no frame timestamps) "
        "replay with their written spacing. Every button is released at the end, on "
        "Ctrl-C and on SIGTERM.",
    )
    p.add_argument("recording", type=Path, help="JSON lines written by the record sink")
    p.add_argument("--sink", required=True, help="sink plugin: uinput, xtest, hidg, record")
    p.add_argument(
        "--sink-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a sink option (repeatable), e.g. display=:1 or device=/dev/hidg0",
    )
    p.add_argument("--screen", default="1920x1080+0+0", help="target screen WxH+X+Y in the layout")
    p.add_argument("--layout", help="whole desktop WxH (default: the screen's extent)")
    p.add_argument("--fast", action="store_true", help="no pauses between events")
    p.add_argument(
        "--timing",
        choices=("frames", "written"),
        default="frames",
        help="pace of the replay: the frames' timestamps (default) or the write times",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from omnidev.inputfile import not_a_file
    from omnidev.screen import ScreenMapping, ScreenRect
    from omnidev.sinks import open_sink, release_on_signals
    from omnidev.sinks.record import replay

    why = not_a_file(args.recording, "recording")
    if why is not None:
        raise OmnidevError(f"{args.recording}: {why}")
    options = sink_options(args.sink_option)
    try:
        rect = ScreenRect.parse(args.screen)
        layout = ScreenRect.parse(args.layout) if args.layout else None
        mapping = ScreenMapping(
            rect,
            layout.width if layout else rect.x + rect.width,
            layout.height if layout else rect.y + rect.height,
        )
    except ValueError as exc:
        raise OmnidevError(str(exc)) from None
    sink = open_sink(args.sink, options, mapping)
    with release_on_signals(sink):
        sent = replay(args.recording, sink, realtime=not args.fast, timing=args.timing)
    if sent == 0:
        raise OmnidevError(f"{args.recording}: no move or button events to replay")
    print(f"replayed {sent} events into {args.sink}")
    return 0
