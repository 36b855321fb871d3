"""``omnidev calibrate fisheye IMAGES... -o camera.yml``: chessboard / ChArUco views -> lens.

Detects the pattern in every image (progress bar), calibrates a KB4 (cv2.fisheye) or Mei
(cv2.omnidir) lens robustly with K-fold held-out errors (:mod:`omnidev.fisheye.calibrate`),
prints a per-image table and the warnings, writes the ``kind: fisheye`` camera file and a
per-view error plot.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from omnidev.atomic import atomic_path, check_output
from omnidev.errors import CalibrationError
from omnidev.imagefile import read_image


def register_fisheye(csub: Any) -> None:
    from omnidev.fisheye.calibrate import MODELS
    from omnidev.fisheye.camera import MOUNTS

    p = csub.add_parser(
        "fisheye",
        help="calibrate a fisheye / central omni-camera from chessboard or ChArUco images",
        description="Find the pattern in each image, calibrate a KB4 (cv2.fisheye) or Mei "
        "(cv2.omnidir) lens, dropping the views the solver rejects, report the reprojection "
        "RMS on held-out views (K-fold) and warn when parameters are poorly determined.",
    )
    p.add_argument("images", type=Path, nargs="+", help="calibration images (all one size)")
    p.add_argument(
        "--pattern",
        required=True,
        metavar="SPEC",
        help="chessboard:COLSxROWS,SQUARE_MM (inner corners, e.g. chessboard:9x6,25) or "
        "charuco:COLSxROWS,SQUARE_MM,MARKER_MM[,DICT] (squares; DICT default DICT_5X5_100)",
    )
    p.add_argument("--model", choices=MODELS, default="kb4", help="lens model (default kb4)")
    p.add_argument(
        "--holdout",
        type=int,
        default=4,
        metavar="K",
        help="K-fold held-out evaluation (default 4; 0 = none)",
    )
    p.add_argument(
        "--mount",
        choices=tuple(MOUNTS),
        default="up",
        help="how the optical axis sits in omnidev's z-up frame: up (default, a lens "
        "looking at the sky), down, forward (a camera looking ahead: perspective views "
        "with pan=0,tilt=0 look through the lens centre), mirror-up/-down (docs/fisheye.md)",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="camera file (.yml)")
    p.add_argument("--plot", type=Path, help="per-view error plot (PNG)")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.set_defaults(func=run_fisheye)


def run_fisheye(args: argparse.Namespace) -> int:
    from omnidev.fisheye.calibrate import Detection, calibrate_views, detect_corners
    from omnidev.fisheye.camera import MOUNTS
    from omnidev.fisheye.camfile import write_camera_file
    from omnidev.fisheye.pattern import parse_pattern

    pattern = parse_pattern(args.pattern)
    if args.holdout < 0 or args.holdout == 1:
        raise CalibrationError(f"--holdout {args.holdout}: 0 (none) or K >= 2 folds")
    check_output(args.output, force=args.force)
    if args.plot is not None:
        check_output(args.plot, force=args.force)
    size: tuple[int, int] | None = None
    first: Path | None = None
    detections: list[Detection | None] = []
    names = [str(p) for p in args.images]
    for path in tqdm(args.images, desc="finding the pattern", unit="image", file=sys.stderr):
        image = read_image(path, "calibration image", grey=True, error=CalibrationError)
        this = (int(image.shape[1]), int(image.shape[0]))
        if size is None:
            size, first = this, path
        elif this != size:
            raise CalibrationError(
                f"{path}: the image is {this[0]}x{this[1]} but {first} is {size[0]}x{size[1]}; "
                "all calibration images must come from one camera mode"
            )
        detections.append(detect_corners(np.asarray(image, np.uint8), pattern, name=str(path)))
    assert size is not None
    found = sum(d is not None for d in detections)
    if found == 0:
        raise CalibrationError(
            f"no {pattern.describe()} found in any of the {len(names)} images "
            f"({names[0]}{' ...' if len(names) > 1 else ''}); check --pattern (a chessboard "
            "counts inner corners) and that the whole board is in view"
        )
    print(f"{pattern.describe()} found in {found} of {len(names)} images ({size[0]}x{size[1]})")
    result = calibrate_views(
        detections,
        size,
        args.model,
        names=names,
        holdout=args.holdout,
        mount=MOUNTS[args.mount],
    )
    print(f"solver: {result.flags}")
    print(" image                                  corners  status      train px  held-out px")
    for v in result.views:
        tr = "" if math.isnan(v.train_rms_px) else f"{v.train_rms_px:8.3f}"
        ho = "" if math.isnan(v.heldout_rms_px) else f"{v.heldout_rms_px:11.3f}"
        line = f" {_short(v.name, 38):38s} {v.n_points:7d}  {v.status:10s} {tr:>8s}  {ho:>11s}"
        print(line + (f"  {v.note}" if v.note else ""))
    dropped = [v.name for v in result.views if v.status == "dropped"]
    if dropped:
        print(f"dropped {len(dropped)} view(s): " + ", ".join(dropped))
    used = sum(v.status == "used" for v in result.views)
    held = (
        f"held-out RMS {result.heldout_rms_px:.3f} px ({result.folds}-fold)"
        if result.folds
        else "no held-out evaluation (--holdout 0)"
    )
    print(f"{used} views used: training RMS {result.train_rms_px:.3f} px, {held}")
    for name, value in result.params.items():
        print(f"  {name:3s} = {value: .8g}  +- {result.std[name]:.3g}")
    print(f"corners reach {100 * result.coverage:.0f} % of the way to the image border")
    for w in result.warnings:
        print(f"warning: {w}", file=sys.stderr)
    write_camera_file(args.output, result.camera, force=args.force)
    print(f"wrote {args.output}")
    if args.plot is not None:
        plot_view_errors(result, args.plot, force=args.force)
        print(f"wrote {args.plot}")
    return 0


def _short(name: str, n: int) -> str:
    return name if len(name) <= n else "..." + name[-(n - 3) :]


def plot_view_errors(result: Any, path: Path, *, force: bool = False) -> None:
    """Bars of each image's training and held-out RMS; dropped and not-found images marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    views = result.views
    x = np.arange(len(views))
    train = np.array([v.train_rms_px for v in views])
    held = np.array([v.heldout_rms_px for v in views])
    fig, ax = plt.subplots(figsize=(max(6.0, 0.45 * len(views) + 2), 4.2))
    ax.bar(x - 0.2, np.nan_to_num(train), 0.4, label="training (final calibration)")
    ax.bar(x + 0.2, np.nan_to_num(held), 0.4, label="held out (pose fitted, fold without it)")
    top = float(np.nanmax(np.concatenate([train, held, [0.1]])))
    for i, v in enumerate(views):
        if v.status != "used":
            ax.axvspan(i - 0.5, i + 0.5, color="0.85", zorder=0)
            ax.text(i, top * 1.02, v.status, rotation=90, ha="center", va="bottom", fontsize=7)
    if not math.isnan(result.heldout_rms_px):
        ax.axhline(result.heldout_rms_px, color="C1", lw=0.8, ls="--")
    ax.axhline(result.train_rms_px, color="C0", lw=0.8, ls="--")
    ax.set_xticks(x)
    ax.set_xticklabels([Path(v.name).name for v in views], rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("reprojection RMS (px)")
    ax.set_ylim(0, top * 1.35)
    held_txt = (
        f"held-out {result.heldout_rms_px:.3f} px ({result.folds}-fold)"
        if result.folds
        else "no held-out"
    )
    ax.set_title(f"{result.model}: training {result.train_rms_px:.3f} px, {held_txt}", fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    with atomic_path(Path(path), force=force) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)
