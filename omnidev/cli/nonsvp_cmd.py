"""Misaligned hyperbolic-mirror cameras on the command line.

- ``omnidev nonsvp-ring OUTDIR --mirror-radius-mm M``: the printable calibration
  ring of sec. 2.3.2 (PNG and PDF at true size).
- ``omnidev calibrate nonsvp-hyper (--image RING.png | --points PTS.csv) --mirror
  A,B,M --lens F,SW,SH --size WxH -o cam.yml``: the camera's pose relative to the
  mirror by Tsai's coplanar calibration (sec. 2.3.2-2.3.3), written as a
  ``nonsvp-hyper`` calibration file that ``omnidev unwarp --camera`` reads.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from omnidev.cli.options import parse_floats, parse_size
from omnidev.errors import CalibrationError, OmnidevError, naming


def register(sub: Any) -> None:
    r = sub.add_parser(
        "nonsvp-ring",
        help="write the printable calibration ring of a hyperbolic-mirror camera (PNG, PDF)",
        description="Write ring.png and ring.pdf (A4, true size: check the 100 mm scale "
        "bar after printing): 16 marks around a circle of the mirror's base radius, "
        "to glue around the mirror base (dissertation sec. 2.3.2).",
    )
    r.add_argument("outdir", type=Path)
    r.add_argument("--mirror-radius-mm", type=float, required=True, help="mirror base radius m")
    r.add_argument("--dpi", type=float, default=300.0)
    r.add_argument("--force", action="store_true", help="overwrite existing files")
    r.set_defaults(func=run_ring)


def register_calibrate(csub: Any) -> None:
    """The ``nonsvp-hyper`` subcommand of ``omnidev calibrate``."""
    c = csub.add_parser(
        "nonsvp-hyper",
        help="pose of a misaligned hyperbolic-mirror camera from its calibration ring",
        description="Find the lens's pose relative to the mirror base from the 16 points of "
        "the calibration ring (a picture of it, or their pixels in a CSV) by Tsai's coplanar "
        "calibration with the focal length known (dissertation sec. 2.3.2-2.3.3), and write "
        "a nonsvp-hyper calibration file for `omnidev unwarp --camera`.",
    )
    src = c.add_mutually_exclusive_group(required=True)
    src.add_argument("--image", type=Path, help="a picture of the ring (the camera's own image)")
    src.add_argument("--points", type=Path, help="CSV of u,v,X,Y (pixels, base-plane mm)")
    c.add_argument(
        "--mirror",
        required=True,
        metavar="A,B,M",
        help="mirror a, b (mm; b along the axis, eq. 2.2) and base radius m (mm); its height "
        "h follows",
    )
    c.add_argument(
        "--lens", required=True, metavar="F,SW,SH", help="focal length, sensor width, height (mm)"
    )
    c.add_argument("--size", required=True, metavar="WxH", help="image size, px")
    c.add_argument(
        "--refine",
        choices=("full", "tsai"),
        default="full",
        help="full (default): all parameters refined; tsai: Tsai's two stages only",
    )
    c.add_argument("-o", "--output", type=Path, required=True, help="calibration file (.yml)")
    c.add_argument("--force", action="store_true")
    c.set_defaults(func=run_calibrate)


def run_ring(args: argparse.Namespace) -> int:
    from omnidev.nonsvp.ring_pattern import ring_pattern, save_ring_pattern

    if not 0 < args.mirror_radius_mm <= 90:
        raise OmnidevError("--mirror-radius-mm must be in (0, 90] mm (the sheet is A4)")
    if not 72 <= args.dpi <= 1200:
        raise OmnidevError(f"--dpi {args.dpi:g}: use 72..1200")
    sheet = ring_pattern(args.mirror_radius_mm, dpi=args.dpi)
    args.outdir.mkdir(parents=True, exist_ok=True)
    for path in save_ring_pattern(sheet, args.outdir, force=args.force):
        print(f"wrote {path}")
    print("print the PDF at 100 % (no fit-to-page) and check the 100 mm scale bar")
    return 0


def run_calibrate(args: argparse.Namespace) -> int:
    import numpy as np

    from omnidev.nonsvp.camfile import write_camera_file
    from omnidev.nonsvp.model import Lens, Mirror, NonSvpCamera
    from omnidev.nonsvp.ring_pattern import RingLayout
    from omnidev.nonsvp.ringcal import (
        calibrate_tsai,
        detect_ring_points,
        parse_points_csv,
        solvepnp_pose,
    )

    a, b, m = parse_floats(args.mirror, 3, "--mirror")
    f, sw, sh = parse_floats(args.lens, 3, "--lens")
    for flag, values in (("--mirror", (a, b, m)), ("--lens", (f, sw, sh))):
        if not all(0 < v <= 1e4 for v in values):
            raise OmnidevError(f"{flag} {getattr(args, flag[2:])}: give lengths in (0, 10000] mm")
    size = parse_size(args.size)
    mirror = Mirror.from_rim(a, b, m)
    lens = Lens(f, (sw, sh), size)
    indices = None
    if args.image is not None:
        from omnidev.imagefile import read_image

        image = read_image(args.image, "ring image", grey=True)
        if (image.shape[1], image.shape[0]) != size:
            raise OmnidevError(
                f"{args.image}: the image is {image.shape[1]}x{image.shape[0]}, --size {args.size}"
            )
        det = detect_ring_points(np.asarray(image, np.uint8), source=str(args.image))
        pixels, indices = det.pixels, det.indices
        plane = RingLayout(m).calibration_points_mm()[det.indices]
        print(f"{len(pixels)} of 16 ring points found in {args.image}")
        for line in det.dropped:
            print(f"  left out: {line}")
    else:
        from omnidev.inputfile import read_text

        text = read_text(args.points, "point file (CSV u,v,X,Y)")
        pixels, plane = parse_points_csv(text, source=str(args.points))
    try:
        cal = calibrate_tsai(pixels, plane, lens, indices=indices, refine=args.refine)
    except CalibrationError as exc:
        raise CalibrationError(naming(args.points or args.image, exc)) from None
    pnp = solvepnp_pose(pixels, plane, lens, cal)
    camera = NonSvpCamera(mirror, lens, cal.pose)
    write_camera_file(args.output, camera, force=args.force)
    p = cal.pose
    print(
        f"mirror: a {a:g}, b {b:g}, c {mirror.c:.4f}, height h {mirror.h:.4f}, base radius {m:g} mm"
    )
    print(
        f"pose: pitch {p.pitch:.5f}, yaw {p.yaw:.5f}, tilt {p.tilt:.5f} rad; "
        f"T ({p.T[0]:.3f}, {p.T[1]:.3f}, {p.T[2]:.3f}) mm"
    )
    print(
        f"reprojection RMS {cal.rms_px:.3f} px over {len(pixels)} points; cv2.solvePnP "
        f"differs by {pnp.rotation_diff_mrad:.3f} mrad, {pnp.translation_diff_mm:.4f} mm"
    )
    print(f"wrote {args.output}")
    return 0
