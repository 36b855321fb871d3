"""``omnidev sim chessboard OUTDIR``: a rendered fisheye calibration sequence with its truth."""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import Any

from omnidev.cli.options import parse_size


def register_chessboard(ssub: Any) -> None:
    c = ssub.add_parser(
        "chessboard",
        help="chessboard / ChArUco views through a fisheye lens, with the true lens and poses",
        description="Render calibration views (viewNN.png) through the KB4, Mei or Scaramuzza "
        "(catadioptric) test lens "
        "(omnidev.sim.chessboard.default_lens; board poses by default_pose_options: Mei "
        "boards reach the image border) and write truth.json: the lens parameters, "
        "every board pose and every corner's exact pixel.",
    )
    c.add_argument("outdir", type=Path)
    c.add_argument("--model", choices=("kb4", "mei", "scaramuzza"), default="kb4")
    c.add_argument("--pattern", default="chessboard:9x6,30", metavar="SPEC")
    c.add_argument("--views", type=int, default=14)
    c.add_argument("--size", default="800x800", metavar="WxH")
    c.add_argument("--seed", type=int, default=0)
    c.add_argument("--force", action="store_true", help="replace an existing folder")
    c.set_defaults(func=run_chessboard)


def run_chessboard(args: argparse.Namespace) -> int:
    import cv2

    from omnidev.atomic import atomic_dir
    from omnidev.errors import OmnidevError
    from omnidev.fisheye.pattern import parse_pattern
    from omnidev.sim.chessboard import default_lens, default_pose_options, render_sequence

    if args.views < 1:
        raise OmnidevError("--views must be >= 1")
    size = parse_size(args.size, minimum=64)
    pattern = parse_pattern(args.pattern)
    lens = default_lens(args.model, size)
    try:
        seq = render_sequence(
            lens, size, pattern, args.views, seed=args.seed, **default_pose_options(args.model)
        )
    except ValueError as exc:
        raise OmnidevError(f"--size {args.size} with --pattern {args.pattern}: {exc}") from None
    truth = {
        "model": args.model,
        "lens": {k: v for k, v in dataclasses.asdict(lens).items()},  # type: ignore[call-overload]
        "image_width": size[0],
        "image_height": size[1],
        "pattern": pattern.describe(),
        "frame": "X_opt = R @ X_board + t (mm); board frame of omnidev.fisheye.pattern",
        "views": [
            {
                "image": f"view{i:02d}.png",
                "R": v.rotation.tolist(),
                "t": v.translation.tolist(),
                "corners_uv": v.corners_uv.tolist(),
            }
            for i, v in enumerate(seq.views)
        ],
    }
    with atomic_dir(args.outdir, force=args.force) as tmp:
        for i, img in enumerate(seq.images):
            if not cv2.imwrite(str(tmp / f"view{i:02d}.png"), img):
                raise OmnidevError(f"{args.outdir}: cannot write view{i:02d}.png")
        (tmp / "truth.json").write_text(json.dumps(truth, indent=1) + "\n", encoding="utf-8")
    print(
        f"wrote {args.outdir}/ ({len(seq.images)} views, {args.model} lens, {pattern.describe()})"
    )
    return 0
