"""``omnidev sim omni OUTDIR``: render the omni fixture (video + ground truth)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def register(sub: Any) -> None:
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
