"""``omnidev sim omni OUTDIR``: render the omni fixture (video + ground truth)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from omnidev.cli.options import parse_size


def register(sub: Any) -> None:
    from omnidev.sim.monitor import TRAJECTORIES, VARIANTS

    p = sub.add_parser("sim", help="render fixtures with ground truth")
    ssub = p.add_subparsers(dest="what", metavar="WHAT", required=True)
    o = ssub.add_parser("omni", help="an omni-camera video of a textured room, with truth")
    o.add_argument("outdir", type=Path)
    o.add_argument("--size", type=int, default=640, help="omni-image size in px (square)")
    o.add_argument("--frames", type=int, default=36)
    o.add_argument("--fps", type=float, default=12.0)
    o.add_argument("--seed", type=int, default=0)
    o.add_argument("--camera", choices=("svp-hyperbolic", "equidistant"), default="svp-hyperbolic")
    o.add_argument("--force", action="store_true", help="replace an existing folder")
    o.set_defaults(func=run)
    b = ssub.add_parser("blob", help="a bright spot moving over a dark picture (pointer fixture)")
    b.add_argument("outdir", type=Path)
    b.add_argument("--size", default="640x480", metavar="WxH")
    b.add_argument("--frames", type=int, default=120)
    b.add_argument("--fps", type=float, default=60.0)
    b.add_argument("--seed", type=int, default=0)
    b.add_argument("--force", action="store_true", help="replace an existing folder")
    b.set_defaults(func=run_blob)
    m = ssub.add_parser(
        "mouse", help="a hand-held camera filming a monitor with corner landmarks, with truth"
    )
    m.add_argument("outdir", type=Path)
    m.add_argument(
        "--trajectory",
        default="drift",
        choices=TRAJECTORIES,
        help="how the hand moves the camera (see omnidev.sim.monitor.trajectory_pose)",
    )
    m.add_argument(
        "--scene",
        default="normal",
        choices=VARIANTS,
        help="what is in front of the camera (the last two must produce no cursor)",
    )
    m.add_argument("--size", default="640x480", metavar="WxH")
    m.add_argument("--frames", type=int, default=60)
    m.add_argument("--fps", type=float, default=30.0)
    m.add_argument("--seed", type=int, default=0)
    m.add_argument("--force", action="store_true", help="replace an existing folder")
    m.set_defaults(func=run_mouse)
    from omnidev.cli.sim_screen_cmd import register_screen

    register_screen(ssub)
    from omnidev.cli.sim_nonsvp_cmd import register_nonsvp

    register_nonsvp(ssub)
    from omnidev.cli.sim_chessboard_cmd import register_chessboard

    register_chessboard(ssub)


def run(args: argparse.Namespace) -> int:
    from omnidev.sim.fixtures import make_omni_fixture

    make_omni_fixture(
        args.outdir,
        size=args.size,
        frames=args.frames,
        fps=args.fps,
        seed=args.seed,
        camera=args.camera,
        force=args.force,
    )
    print(f"wrote {args.outdir}/")
    return 0


def run_mouse(args: argparse.Namespace) -> int:
    from omnidev.errors import OmnidevError
    from omnidev.sim.monitor import make_mouse_fixture

    if args.frames < 1 or args.fps <= 0:
        raise OmnidevError("--frames must be >= 1 and --fps > 0")
    make_mouse_fixture(
        args.outdir,
        trajectory=args.trajectory,
        size=parse_size(args.size, minimum=64),
        frames=args.frames,
        fps=args.fps,
        seed=args.seed,
        variant=args.scene,
        force=args.force,
    )
    print(f"wrote {args.outdir}/")
    return 0


def run_blob(args: argparse.Namespace) -> int:
    from omnidev.errors import OmnidevError
    from omnidev.sim.blob import make_blob_fixture

    w, h = parse_size(args.size, minimum=64)
    if args.frames < 8 or args.fps <= 0:
        raise OmnidevError("--frames must be >= 8 and --fps > 0")
    make_blob_fixture(
        args.outdir,
        frames=args.frames,
        width=w,
        height=h,
        fps=args.fps,
        seed=args.seed,
        force=args.force,
    )
    print(f"wrote {args.outdir}/")
    return 0
