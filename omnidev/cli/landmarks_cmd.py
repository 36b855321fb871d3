"""``omnidev landmarks board``: landmark pairs from ChArUco boards at measured places."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from omnidev.atomic import atomic_path, check_output
from omnidev.errors import CalibrationError
from omnidev.imagefile import read_image


def register(sub: Any) -> None:
    p = sub.add_parser("landmarks", help="collect landmark pairs for a pano-mapping table")
    lsub = p.add_subparsers(dest="what", metavar="HOW", required=True)
    b = lsub.add_parser(
        "board",
        help="landmarks from ChArUco boards at measured places (docs/panotable-general.md)",
        description="Detect the ChArUco boards of a board rig (TOML: pattern, first marker id, "
        "and three measured corners of each board) in omni-images and write every detected "
        "corner as a landmark pair u,v,X,Y,Z with its group (one per board and image).",
    )
    b.add_argument("images", nargs="+", type=Path, help="omni-images of the camera")
    b.add_argument("--boards", type=Path, required=True, help="board rig file (TOML)")
    b.add_argument("-o", "--output", type=Path, required=True, help="landmark CSV to write")
    b.add_argument(
        "--min-corners", type=int, default=4, help="ignore boards with fewer corners (default 4)"
    )
    b.add_argument("--force", action="store_true", help="overwrite an existing output")
    b.set_defaults(func=run_board)


def run_board(args: argparse.Namespace) -> int:
    from omnidev.panotable.boards import detect_board, read_rig

    check_output(args.output, force=args.force)
    boards = read_rig(args.boards)
    names = {p.name for p in args.images}
    for bd in boards:
        if bd.image is not None and Path(bd.image).name not in names:
            raise CalibrationError(f"{bd.name}: its image {bd.image!r} is not among the inputs")
    lines = ["u,v,X,Y,Z,group"]
    group = 0
    if args.min_corners < 1:
        raise CalibrationError(f"--min-corners {args.min_corners}: give 1 or more")
    total = 0
    size: tuple[int, int] | None = None
    for path in tqdm(args.images, desc="images", unit="image", file=sys.stderr):
        img = read_image(path, "omni-image", error=CalibrationError)
        if size is None:
            size = (img.shape[1], img.shape[0])
        elif size != (img.shape[1], img.shape[0]):
            raise CalibrationError(
                f"{path}: {img.shape[1]}x{img.shape[0]}, the first image is {size[0]}x{size[1]}"
            )
        for bd in boards:
            if bd.image is not None and Path(bd.image).name != path.name:
                continue
            c = detect_board(np.asarray(img, np.uint8), bd)
            n = len(c.ids)
            shown = f"{path.name}: {bd.name}: {n} of {bd.pattern.n_corners} corners"
            if n < args.min_corners:
                print(shown + " (left out)")
                continue
            print(shown + (" (mirror-reversed image)" if c.mirrored else ""))
            for (u, v), (x, y, z) in zip(c.uv, c.xyz, strict=True):
                lines.append(f"{u:.4f},{v:.4f},{x:.6f},{y:.6f},{z:.6f},{group}")
            group += 1
            total += n
    if total == 0:
        raise CalibrationError(
            "no board found in any image: check the pattern (squares, sizes, dictionary) and "
            "first_marker of each board, and that the boards are large enough in the image"
        )
    with atomic_path(args.output, force=args.force) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    print(f"wrote {total} landmarks in {group} groups to {args.output}")
    return 0
