"""``omnidev calibrate import``: another tool's fisheye/omni calibration -> an omnidev camera file.

Reads OCamCalib, py-OCamCalib, Kalibr, basalt, camera-intrinsic-model or OpenCV files
(:mod:`omnidev.fisheye.formats`), mounts the lens (``--mount``) and writes a ``fisheye``
camera file that ``omnidev unwarp --camera`` reads; ``--export-opencv`` also writes
K, D (and xi) for cv2.fisheye / cv2.omnidir users.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np

from omnidev.atomic import check_output
from omnidev.budget import check_pixels
from omnidev.cli.options import parse_size
from omnidev.errors import CalibrationError, OmnidevError


def register_import(csub: Any) -> None:
    """The ``import`` subcommand of ``omnidev calibrate``."""
    from omnidev.fisheye.camera import MOUNTS

    c = csub.add_parser(
        "import",
        help="import a fisheye/omni calibration from OCamCalib, Kalibr, basalt or OpenCV",
        description="Read another tool's calibration of a fisheye or central omni-camera "
        "(OCamCalib calib_results.txt, py-OCamCalib JSON, Kalibr camchain YAML, basalt "
        "calibration.json, "
        "camera-intrinsic-model JSON, OpenCV FileStorage with K/D[/xi]) and write an omnidev "
        "'fisheye' camera file for `omnidev unwarp --camera`. docs/fisheye-import.md lists "
        "the models and conventions.",
    )
    c.add_argument("file", type=Path, help="the calibration file")
    c.add_argument(
        "--format",
        choices=("auto", "ocamcalib", "pyocamcalib", "kalibr", "basalt", "cim", "opencv"),
        default="auto",
        help="file format (default: from the name and contents)",
    )
    c.add_argument(
        "--camera", metavar="NAME|N", help="camera of a multi-camera file (cam1 or 1; default 0)"
    )
    c.add_argument(
        "--mount",
        choices=tuple(MOUNTS),
        help="where the optical axis points in omnidev's camera frame (z up): up (default), "
        "down, forward (+x); mirror-up / mirror-down for a catadioptric camera calibrated "
        "with a central model (Mei, OCamCalib), whose model frame is mirror-imaged",
    )
    c.add_argument(
        "--max-angle-deg",
        type=float,
        help="use the lens up to this angle from the optical axis (deg; default: all of it)",
    )
    c.add_argument("--image-size", metavar="WxH", help="image size when the file lacks it")
    c.add_argument("-o", "--output", type=Path, required=True, help="camera file (.yml)")
    c.add_argument(
        "--export-opencv",
        type=Path,
        metavar="OUT.yml",
        help="also write K, D (and xi) as cv2.fisheye / cv2.omnidir read them",
    )
    c.add_argument("--force", action="store_true", help="overwrite existing outputs")
    c.set_defaults(func=run_import)


def _describe(lens: Any) -> str:
    """``name: a=1 b=2 ...`` with every parameter of the lens."""
    parts = []
    for f in dataclasses.fields(lens):
        v = getattr(lens, f.name)
        if isinstance(v, tuple):
            parts.append(f"{f.name}=[" + " ".join(f"{x:.6g}" for x in v) + "]")
        elif isinstance(v, float):
            parts.append(f"{f.name}={v:.6g}")
    return f"{lens.name}: " + " ".join(parts)


def _coverage(lens: Any, size: tuple[int, int]) -> str:
    """How far from the optical axis the image's pixels see (on a 4 px grid)."""
    w, h = size
    check_pixels(w // 4 + 2, h // 4 + 2, 200, f"the coverage of a {w}x{h} image")
    u, v = np.meshgrid(np.linspace(0, w - 1, w // 4 + 2), np.linspace(0, h - 1, h // 4 + 2))
    rays, ok = lens.unproject(np.stack([u, v], -1))
    if not ok.any():
        return "no pixel of the image is the image of a ray (check the image size)"
    theta = np.degrees(np.arccos(np.clip(rays[..., 2][ok], -1.0, 1.0)))
    return (
        f"the model puts its pixels up to {theta.max():.1f} deg from the optical axis "
        f"(corners outside the lens's image circle included; the model images up to "
        f"{math.degrees(lens.max_angle):.1f} deg)"
    )


def run_import(args: argparse.Namespace) -> int:
    from omnidev.fisheye.camera import MOUNTS, FisheyeCamera
    from omnidev.fisheye.camfile import write_camera_file
    from omnidev.fisheye.formats import import_calibration, opencv_nodes, write_opencv

    check_output(args.output, force=args.force)
    if args.export_opencv is not None:
        if args.export_opencv == args.output:
            raise OmnidevError("--export-opencv and -o name the same file")
        check_output(args.export_opencv, force=args.force)
    got = import_calibration(args.file, fmt=args.format, camera=args.camera)
    size = got.image_size
    if args.image_size:
        given = parse_size(args.image_size, "--image-size")
        if size is not None and given != size:
            raise CalibrationError(
                f"{args.file}: the file says {size[0]}x{size[1]} px, --image-size {args.image_size}"
            )
        size = given
    if size is None:
        raise CalibrationError(f"{args.file}: no image size in the file; give --image-size WxH")
    mount = MOUNTS[args.mount] if args.mount else got.mount
    max_angle = got.max_angle_deg if args.max_angle_deg is None else args.max_angle_deg
    try:
        camera = FisheyeCamera(got.lens, size, MOUNTS["up"] if mount is None else mount, max_angle)
    except ValueError as exc:
        raise OmnidevError(f"--max-angle-deg: {exc}") from None
    if args.export_opencv is not None:
        opencv_nodes(got.lens, size)  # fails here, before any file is written
    which = f" camera {got.camera} of {', '.join(got.cameras)}" if got.camera else ""
    print(f"read {args.file} ({got.format}{which})")
    print(_describe(got.lens))
    print(f"image {size[0]}x{size[1]} px; {_coverage(got.lens, size)}")
    write_camera_file(args.output, camera, force=args.force)
    print(f"wrote {args.output}")
    if args.export_opencv is not None:
        write_opencv(args.export_opencv, got.lens, size, force=args.force)
        print(f"wrote {args.export_opencv}")
    return 0
