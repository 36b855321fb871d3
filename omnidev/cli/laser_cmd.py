"""``omnidev laser SOURCE --calibration FILE --sink NAME``: the laser pointer in the foreground.

Runs the daemon's pipeline (source -> laser-pointer tracker -> One Euro filter
-> sink) on any source into any sink, until a file source ends or Ctrl-C /
SIGTERM; a spot that vanishes and every exit release the pointer buttons.
``--method`` picks the spot detector (``white-core``, the default, or ``colour``)
and ``--detector-option KEY=VALUE`` sets its limits, as the daemon config's
[tracker.options] table does (docs/laser-pointer.md lists them). The One Euro
filter uses the laser's defaults (restarted after 0.1 s without a spot).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from omnidev.cli.foreground import add_pointer_arguments
from omnidev.errors import OmnidevError


def register(sub: Any) -> None:
    p = sub.add_parser(
        "laser",
        help="run the laser pointer (a fixed camera watching a calibrated screen) into a sink",
        description=__doc__.splitlines()[0].replace("``", "") if __doc__ else None,
    )
    p.add_argument("source", help="source URI or path (v4l2:/dev/video0, a video file, ...)")
    p.add_argument(
        "--calibration",
        required=True,
        type=Path,
        help="the screen calibration written by `omnidev calibrate screen`",
    )
    p.add_argument(
        "--colour", choices=("red", "green", "any"), default="red", help="the laser's colour"
    )
    p.add_argument(
        "--method",
        choices=("colour", "white-core"),
        default="white-core",
        help="spot detector: white-core (default) or colour (no white core needed)",
    )
    p.add_argument(
        "--detector-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a detector limit, e.g. saturated=240 (see docs/laser-pointer.md)",
    )
    add_pointer_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from omnidev.cli.foreground import run_foreground
    from omnidev.inputfile import not_a_file

    why = not_a_file(args.calibration, "screen calibration file")
    if why is not None:
        raise OmnidevError(f"{args.calibration}: {why}")
    options: dict[str, Any] = {"colour": args.colour, "method": args.method}
    for item in args.detector_option:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise OmnidevError(f"--detector-option {item!r}: expected KEY=VALUE")
        if key.strip() in ("colour", "method"):
            raise OmnidevError(f"--detector-option {key.strip()}: use --{key.strip()}")
        options[key.strip()] = value.strip()
    tracker = {
        "name": "laser-pointer",
        "calibration": str(args.calibration.resolve()),
        "options": options,
    }
    return run_foreground(args, "laser", tracker)
