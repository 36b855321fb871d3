"""``omnidev sim nonsvp OUTDIR``: an omni-image through a misaligned hyperbolic mirror, with truth.

Registered under ``omnidev sim`` by :func:`register_nonsvp` (called from
:mod:`omnidev.cli.sim_cmd` with the ``sim`` subparsers).
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path
from typing import Any

from omnidev.cli.options import parse_floats, parse_size


def register_nonsvp(ssub: Any) -> None:
    """Add ``nonsvp`` to the subparsers of ``omnidev sim``."""
    s = ssub.add_parser(
        "nonsvp",
        help="an omni-image through a misaligned (non-SVP) hyperbolic mirror, with exact "
        "top and side views",
    )
    s.add_argument("outdir", type=Path)
    s.add_argument(
        "--scene",
        choices=("pseudo-target", "textured"),
        default="textured",
        help="the dissertation's Fig. 2.9 ground grid with an L-shaped wall, or a textured "
        "room whose walls and floor are the view planes",
    )
    s.add_argument(
        "--pose",
        choices=("dissertation", "large", "svp"),
        default="dissertation",
        help="the lens pose: the dissertation's calibration, a larger misalignment, or aligned",
    )
    s.add_argument(
        "--T",
        dest="T",
        metavar="TX,TY,TZ",
        help="override the pose's T (mm); write --T=-1,0,88 for a leading minus",
    )
    s.add_argument("--angles", metavar="PITCH,YAW,TILT", help="override the pose's angles (rad)")
    s.add_argument(
        "--size", default="640x480", metavar="WxH", help="omni-image size (3.2x2.4 mm sensor)"
    )
    s.add_argument("--view-size", default="320x240", metavar="WxH", help="truth view size")
    s.add_argument("--supersample", type=int, default=3, help="samples per pixel side")
    s.add_argument("--seed", type=int, default=0, help="texture seed (textured scene)")
    s.add_argument(
        "--convention",
        choices=("eq2.13", "eq2.4"),
        default="eq2.13",
        help="how T places the lens: eq. 2.16 (default, omnidev.nonsvp.model) or eq. 2.4",
    )
    s.add_argument("--force", action="store_true", help="replace an existing folder")
    s.set_defaults(func=run_nonsvp)


def run_nonsvp(args: argparse.Namespace) -> int:
    import dataclasses

    from omnidev.errors import OmnidevError
    from omnidev.nonsvp.model import NonSvpCamera
    from omnidev.sim.nonsvp import make_nonsvp_fixture, preset_camera

    if not 1 <= args.supersample <= 8:
        raise OmnidevError(f"--supersample {args.supersample}: from 1 to 8")
    size = parse_size(args.size, "--size", 32)
    view_size = parse_size(args.view_size, "--view-size", 32)
    cam = preset_camera(args.pose, size)
    pose = cam.pose
    if args.T:
        tx, ty, tz = parse_floats(args.T, 3, "--T")
        pose = dataclasses.replace(pose, T=(tx, ty, tz))
    if args.angles:
        p, y, t = parse_floats(args.angles, 3, "--angles")
        pose = dataclasses.replace(pose, pitch=p, yaw=y, tilt=t)
    cam = NonSvpCamera(cam.mirror, cam.lens, pose)
    cmd = [
        "omnidev", "sim", "nonsvp", str(args.outdir), "--scene", args.scene, "--pose", args.pose,
        "--size", args.size, "--view-size", args.view_size, "--supersample",
        str(args.supersample), "--seed", str(args.seed), "--convention", args.convention,
    ]  # fmt: skip
    if args.T:
        cmd += [f"--T={args.T}"]
    if args.angles:
        cmd += [f"--angles={args.angles}"]
    make_nonsvp_fixture(
        args.outdir,
        cam,
        args.scene,
        view_size=view_size,
        supersample=args.supersample,
        seed=args.seed,
        convention=args.convention,
        regenerate=shlex.join([*cmd, "--force"]),
        force=args.force,
    )
    print(f"wrote {args.outdir}/")
    return 0
