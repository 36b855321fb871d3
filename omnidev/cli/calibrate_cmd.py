"""``omnidev calibrate pano-table``: landmarks in, pano-mapping table and fit plot out."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from omnidev.atomic import check_output
from omnidev.errors import CalibrationError
from omnidev.landmarks import parse_floats, read_landmarks_csv
from omnidev.omnicenter import detect_omni_circles
from omnidev.panotable import calibrate
from omnidev.panotable_file import save_table


def register(sub: Any) -> None:
    p = sub.add_parser("calibrate", help="calibrate a camera")
    csub = p.add_subparsers(dest="what", metavar="KIND", required=True)
    pt = csub.add_parser(
        "pano-table",
        help="learn a pano-mapping table from landmarks (dissertation ch. 4)",
        description="Fit the radial stretching function to landmark pairs (Algorithm 1) and "
        "fill a pano-mapping table (Algorithm 2).",
    )
    pt.add_argument("landmarks", type=Path, help="CSV with header u,v,X,Y,Z")
    pt.add_argument(
        "--mirror-center",
        required=True,
        metavar="X,Y,Z",
        help="world position of the mirror center O_m (landmarks' unit)",
    )
    pt.add_argument(
        "--image-center",
        metavar="U,V|detect",
        help="image center in pixels, or 'detect' to find it in --image",
    )
    pt.add_argument("--image", type=Path, help="an omni-image of this camera (size, center)")
    pt.add_argument("--image-size", metavar="WxH", help="omni-image size when no --image")
    pt.add_argument(
        "--azimuth",
        choices=("fit", "identity"),
        default="fit",
        help="azimuth mapping: fit sign and offset (default) or the "
        "dissertation's identity phi = theta",
    )
    pt.add_argument(
        "--elevation-range",
        metavar="LO,HI",
        help="table elevation range in degrees (default: from the landmarks)",
    )
    pt.add_argument("--table-size", metavar="MxN", help="table size (default: ~1 entry/pixel)")
    pt.add_argument(
        "--cutoff-radius",
        type=float,
        help="px radius of the self-occluded center (default: detected with "
        "--image-center detect, else 0)",
    )
    pt.add_argument("-o", "--output", type=Path, required=True, help="table file (.yml[.gz])")
    pt.add_argument("--plot", type=Path, help="PNG of the fitted function (default: OUTPUT.png)")
    pt.add_argument("--force", action="store_true", help="overwrite existing outputs")
    pt.set_defaults(func=run)


def _size(text: str, what: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise CalibrationError(f"{what} must look like 640x480, got {text!r}") from None
    if w < 1 or h < 1:
        raise CalibrationError(f"{what} must be positive, got {text!r}")
    return w, h


def run(args: argparse.Namespace) -> int:
    out: Path = args.output
    plot: Path = args.plot or out.with_name(out.name.split(".")[0] + "_fit.png")
    check_output(out, force=args.force)
    check_output(plot, force=args.force)
    lm = read_landmarks_csv(args.landmarks)
    mirror = np.array(parse_floats(args.mirror_center, 3, "--mirror-center"))
    image = None
    if args.image is not None:
        image = cv2.imread(str(args.image), cv2.IMREAD_COLOR)
        if image is None:
            raise CalibrationError(f"{args.image}: cannot read image")
    if image is not None:
        size = (image.shape[1], image.shape[0])
    elif args.image_size:
        size = _size(args.image_size, "--image-size")
    else:
        raise CalibrationError("give --image or --image-size")
    cutoff = args.cutoff_radius or 0.0
    disc = None
    if args.image_center is None or args.image_center == "detect":
        if image is None:
            raise CalibrationError("--image-center detect needs --image")
        circles = detect_omni_circles(np.asarray(image, np.uint8))
        center = circles.center
        if args.cutoff_radius is None:
            cutoff = circles.cutoff_radius
        disc = circles.disc_radius
        print(
            f"detected image center ({center[0]:.2f}, {center[1]:.2f}) px, "
            f"cut-off radius {circles.cutoff_radius:.1f} px, "
            f"mirror disc radius {circles.disc_radius:.1f} px"
        )
    else:
        cu, cv = parse_floats(args.image_center, 2, "--image-center")
        center = (cu, cv)
    rho_range = None
    if args.elevation_range:
        lo, hi = parse_floats(args.elevation_range, 2, "--elevation-range")
        rho_range = (math.radians(lo), math.radians(hi))
    table_size = _size(args.table_size, "--table-size") if args.table_size else None
    calib = calibrate(
        lm.uv,
        lm.xyz,
        mirror,
        center,
        size,
        disc_radius=disc,
        azimuth=args.azimuth,
        rho_range=rho_range,
        table_size=table_size,
        cutoff_radius=cutoff,
    )
    t = calib.table
    print(f"{len(lm.rows)} landmarks from {args.landmarks}")
    print(" line   elevation(deg)   radius(px)   radial residual(px)   reprojection(px)")
    for i, line in enumerate(lm.rows):
        print(
            f"{line:5d}   {math.degrees(calib.polar.rho[i]):14.3f}   {calib.polar.r[i]:10.2f}"
            f"   {calib.fit.residual_px[i]:19.3f}   {calib.reprojection_px[i]:16.3f}"
        )
    print(
        f"radial fit RMS {calib.fit.rms_px:.3f} px, max |residual| "
        f"{np.max(np.abs(calib.fit.residual_px)):.3f} px; reprojection RMS "
        f"{np.sqrt(np.mean(calib.reprojection_px**2)):.3f} px"
    )
    print("coefficients a0..a4: " + " ".join(f"{c:.6g}" for c in t.coeffs))
    print(f"azimuth: phi = {t.azimuth_sign:+d} theta {math.degrees(t.azimuth_offset):+.3f} deg")
    print(
        f"table {t.M} x {t.N}, elevation {math.degrees(t.rho_range[0]):.2f} .. "
        f"{math.degrees(t.rho_range[1]):.2f} deg"
    )
    save_table(out, calib, force=args.force)
    from omnidev.plots import plot_radial_fit

    plot_radial_fit(calib, plot, force=args.force)
    print(f"wrote {out}")
    print(f"wrote {plot}")
    return 0
