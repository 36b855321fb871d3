"""``omnidev sim screen OUTDIR``: a screen seen by a fixed camera (patterns, laser video, truth).

Registered under ``omnidev sim`` by :func:`register_screen` (called from
:mod:`omnidev.cli.sim_cmd` with the ``sim`` subparsers).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from omnidev.cli.options import parse_size


def register_screen(ssub: Any) -> None:
    """Add ``screen`` to the subparsers of ``omnidev sim``."""
    s = ssub.add_parser(
        "screen",
        help="a screen seen by a distorted camera: calibration patterns and a laser video, "
        "with truth",
    )
    s.add_argument("outdir", type=Path)
    s.add_argument("--size", default="1280x720", metavar="WxH", help="camera image size")
    s.add_argument(
        "--k1",
        type=float,
        default=-0.25,
        help="radial distortion (-0.3 barrel .. +0.15 pincushion)",
    )
    s.add_argument("--n", type=int, default=9, help="dots per row and column of the dot matrix")
    s.add_argument("--frames", type=int, default=120, help="laser video length (30 fps)")
    s.add_argument("--colour", choices=("red", "green"), default="red", help="laser colour")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--force", action="store_true", help="replace an existing folder")
    s.set_defaults(func=run_screen)


def run_screen(args: argparse.Namespace) -> int:
    from omnidev.errors import OmnidevError
    from omnidev.sim.screen import make_screen_fixture

    if args.frames < 1:
        raise OmnidevError("--frames must be >= 1")
    if not -0.5 <= args.k1 <= 0.5:
        raise OmnidevError(f"--k1 {args.k1:g}: outside [-0.5, 0.5]")
    if not 2 <= args.n <= 40:
        raise OmnidevError(f"--n {args.n}: from 2 to 40 dots")
    make_screen_fixture(
        args.outdir,
        size=parse_size(args.size, minimum=64),
        k1=args.k1,
        n=args.n,
        frames=args.frames,
        colour=args.colour,
        seed=args.seed,
        force=args.force,
    )
    print(f"wrote {args.outdir}/")
    return 0
