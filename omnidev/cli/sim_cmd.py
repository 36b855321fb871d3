"""``omnidev sim omni OUTDIR``: render the omni fixture (video + ground truth)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
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
    for parser in ssub.choices.values():
        _document(parser)
        func = parser.get_default("func")
        if func is not None:
            parser.set_defaults(func=_validated(func))


_HELP = {
    "--frames": "frames to render",
    "--fps": "frame rate of the written video, frames per second",
    "--seed": "random seed of the scene (same seed, same fixture)",
    "--size": "image size, px (WxH)",
    "--views": "number of chessboard views",
    "--model": "lens model",
    "--pattern": "board: chessboard:COLSxROWS,SQUARE_MM (inner corners)",
    "--trajectory": "how the hand-held camera moves",
    "--scene": "what the camera sees",
    "--supersample": "samples per pixel along each axis (anti-aliasing)",
    "--seed-scene": "random seed of the scene",
}


def _document(parser: argparse.ArgumentParser) -> None:
    """Every option says what it is and shows its default in ``--help``."""
    parser.formatter_class = argparse.ArgumentDefaultsHelpFormatter
    for action in parser._actions:
        if action.help is None and action.option_strings:
            action.help = _HELP.get(action.option_strings[-1], " ")


def _validated(func: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """``func`` after the checks every sim command shares (sizes, counts, rates, memory)."""

    def run_checked(args: argparse.Namespace) -> int:
        _check_sim_args(args)
        return func(args)

    return run_checked


MAX_SIM_SIDE = 8192
MAX_SIM_FRAMES = 100_000


def _check_sim_args(args: argparse.Namespace) -> None:
    from omnidev.budget import check_pixels
    from omnidev.cli.options import parse_floats
    from omnidev.errors import OmnidevError

    ss = getattr(args, "supersample", None)
    if ss is not None and not 1 <= ss <= 8:
        raise OmnidevError(f"--supersample {ss}: give 1..8")
    for name in ("size", "view_size"):
        value = getattr(args, name, None)
        if value is None:
            continue
        flag = "--" + name.replace("_", "-")
        if isinstance(value, int):
            w = h = value
            if not 16 <= value <= MAX_SIM_SIDE:
                raise OmnidevError(f"{flag} {value}: give 16..{MAX_SIM_SIDE} px")
        else:
            w, h = parse_size(value, flag, maximum=MAX_SIM_SIDE)
        check_pixels(w, h, 400.0 * (ss or 1) ** 2, f"rendering {w}x{h} images")
    frames = getattr(args, "frames", None)
    if frames is not None and not 1 <= frames <= MAX_SIM_FRAMES:
        raise OmnidevError(f"--frames {frames}: give 1..{MAX_SIM_FRAMES}")
    views = getattr(args, "views", None)
    if views is not None and not 1 <= views <= 1000:
        raise OmnidevError(f"--views {views}: give 1..1000")
    fps = getattr(args, "fps", None)
    if fps is not None and not 0 < fps <= 1000:
        raise OmnidevError(f"--fps {fps:g}: give frames per second in (0, 1000]")
    n = getattr(args, "n", None)
    if n is not None and not 2 <= n <= 64:
        raise OmnidevError(f"--n {n}: give 2..64 dots per row")
    k1 = getattr(args, "k1", None)
    if k1 is not None and not -1 <= k1 <= 1:
        raise OmnidevError(f"--k1 {k1:g}: give a radial distortion in [-1, 1]")
    pattern = getattr(args, "pattern", None)
    if isinstance(pattern, str):
        import re

        m = re.search(r"(\d+)\s*x\s*(\d+)", pattern)
        if m and max(int(m.group(1)), int(m.group(2))) > 200:
            raise OmnidevError(f"--pattern {pattern}: at most 200 squares per side")
    for name in ("T", "angles"):
        text = getattr(args, name, None)
        if isinstance(text, str):
            values = parse_floats(text, 3, f"--{name}")
            if max(abs(v) for v in values) > 1e4:
                raise OmnidevError(f"--{name} {text}: values beyond 1e4 are not a camera pose")


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
