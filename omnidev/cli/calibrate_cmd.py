"""``omnidev calibrate pano-table``: landmarks in, pano-mapping table and fit plot out."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from omnidev.atomic import check_output
from omnidev.budget import check_pixels
from omnidev.cli.options import parse_floats, parse_size
from omnidev.errors import CalibrationError
from omnidev.imagefile import read_image
from omnidev.inputfile import read_json
from omnidev.panotable.camfile import save_table
from omnidev.panotable.center import detect_image_center
from omnidev.panotable.landmarks import check_inside_image, read_landmarks_csv
from omnidev.panotable.table import (
    Calibration,
    GeneralCalibration,
    calibrate,
    calibrate_general,
    dissertation_misfit,
)

TABLE_BYTES_PER_ENTRY = 160.0
"""Peak memory of filling a pano-mapping table and plotting it, bytes per entry (upper bound)."""


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
        help="image center in pixels, or 'detect' to measure it in --image (default: detect); "
        "the generalized model fits it, starting there",
    )
    pt.add_argument(
        "--center-kind",
        choices=("auto", "mirror", "fisheye"),
        default="auto",
        help="what --image-center detect looks for: a mirror's rim and cut-off circle, or a "
        "fisheye's image circle (default: auto)",
    )
    pt.add_argument(
        "--model",
        choices=("dissertation", "general"),
        default="dissertation",
        help="dissertation: one radial function about a given center (ch. 4); general: also "
        "fits the center, pixel aspect, tilt, keystone and azimuth harmonics, the order "
        "chosen by held-out residual (needs >= 13 landmarks; boards give hundreds)",
    )
    pt.add_argument(
        "--max-residual",
        type=float,
        default=2.0,
        metavar="PX",
        help="refuse to write a table whose RMS (general: held-out RMS) is over PX "
        "(default 2.0; 0 = never refuse)",
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
    _register_screen(csub)
    from omnidev.cli.nonsvp_cmd import register_calibrate

    register_calibrate(csub)
    from omnidev.cli.calibrate_fisheye_cmd import register_fisheye

    register_fisheye(csub)
    from omnidev.cli.calibrate_import_cmd import register_import

    register_import(csub)


def run(args: argparse.Namespace) -> int:
    out: Path = args.output
    plot: Path = args.plot or out.with_name(out.name.split(".")[0] + "_fit.png")
    check_output(out, force=args.force)
    check_output(plot, force=args.force)
    lm = read_landmarks_csv(args.landmarks)
    mirror = np.array(parse_floats(args.mirror_center, 3, "--mirror-center"))
    image = None
    if args.image is not None:
        image = read_image(args.image, "omni-image", error=CalibrationError)
    if image is not None:
        size = (image.shape[1], image.shape[0])
    elif args.image_size:
        size = parse_size(args.image_size, "--image-size")
    else:
        raise CalibrationError("give --image or --image-size")
    check_inside_image(lm, size, args.landmarks)
    if args.cutoff_radius is not None and not 0 <= args.cutoff_radius < math.hypot(*size):
        raise CalibrationError(
            f"--cutoff-radius {args.cutoff_radius:g}: give pixels >= 0 within the "
            f"{size[0]}x{size[1]} image"
        )
    cutoff = args.cutoff_radius or 0.0
    disc = None
    sigma = None
    if args.image_center is None or args.image_center == "detect":
        if image is None:
            raise CalibrationError(
                "--image-center detect needs --image (or give --image-center U,V)"
            )
        try:
            est = detect_image_center(np.asarray(image, np.uint8), kind=args.center_kind)
        except CalibrationError as exc:
            raise CalibrationError(f"{args.image}: {exc}") from None
        center, sigma = est.center, est.sigma_px
        if args.cutoff_radius is None:
            cutoff = est.cutoff_radius
        disc = est.disc_radius
        cut = f", cut-off radius {est.cutoff_radius:.1f} px" if est.cutoff is not None else ""
        print(
            f"detected image center ({center[0]:.2f}, {center[1]:.2f}) px +- {sigma:.2f} px "
            f"({est.kind}{cut}, outer radius {disc:.1f} px, aspect {est.aspect:.4f})"
        )
    else:
        cu, cv = parse_floats(args.image_center, 2, "--image-center")
        if not (-0.5 <= cu <= size[0] - 0.5 and -0.5 <= cv <= size[1] - 0.5):
            raise CalibrationError(
                f"--image-center {args.image_center}: outside the {size[0]}x{size[1]} image"
            )
        center = (cu, cv)
    rho_range = None
    if args.elevation_range:
        lo, hi = parse_floats(args.elevation_range, 2, "--elevation-range")
        if not -90 < lo < hi < 90:
            raise CalibrationError(
                f"--elevation-range {args.elevation_range}: give LO,HI degrees with "
                "-90 < LO < HI < 90"
            )
        rho_range = (math.radians(lo), math.radians(hi))
    table_size = None
    if args.table_size:
        table_size = parse_size(args.table_size, "--table-size", minimum=2, maximum=32768)
    tw, th = table_size or size
    check_pixels(tw, th, TABLE_BYTES_PER_ENTRY, f"a {tw}x{th} pano-mapping table")
    if not (math.isfinite(args.max_residual) and args.max_residual >= 0):
        raise CalibrationError(
            f"--max-residual {args.max_residual:g}: give pixels >= 0 (0 = never refuse)"
        )
    bound = args.max_residual if args.max_residual > 0 else None
    print(f"{len(lm.rows)} landmarks from {args.landmarks}")
    calib: Calibration | GeneralCalibration
    if args.model == "general":
        calib = calibrate_general(
            lm.uv,
            lm.xyz,
            mirror,
            center,
            size,
            disc_radius=disc,
            rho_range=rho_range,
            table_size=table_size,
            cutoff_radius=cutoff,
            groups=lm.groups,
            max_heldout_px=bound,
            rows=lm.rows,
        )
        _report_general(calib, lm.rows)
    else:
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
        _report_dissertation(calib, lm.rows)
        rms = float(np.sqrt(np.mean(calib.reprojection_px**2)))
        if bound is not None and rms > bound:
            raise CalibrationError(dissertation_misfit(calib, bound))
    t = calib.table
    print(
        f"table {t.M} x {t.N}, elevation {math.degrees(t.rho_range[0]):.2f} .. "
        f"{math.degrees(t.rho_range[1]):.2f} deg"
    )
    save_table(out, calib, force=args.force)
    print(f"wrote {out}")
    if isinstance(calib, Calibration):
        from omnidev.panotable.plots import plot_radial_fit

        plot_radial_fit(calib, plot, force=args.force)
        print(f"wrote {plot}")
    return 0


def _report_dissertation(calib: Calibration, rows: tuple[int, ...]) -> None:
    t = calib.table
    print(" line   elevation(deg)   radius(px)   radial residual(px)   reprojection(px)")
    for i, line in enumerate(rows):
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


def _report_general(calib: GeneralCalibration, rows: tuple[int, ...]) -> None:
    fit = calib.fit
    print("model order             parameters   held-out RMS(px)   p95(px)   fit RMS(px)")
    for sc in fit.scores:
        mark = "*" if sc.terms == fit.terms else " "
        print(
            f"{mark} {sc.terms.describe()}\n  {'':22s}{sc.terms.n_params():10d}"
            f"   {sc.heldout_rms_px:16.3f}   {sc.heldout_p95_px:7.3f}   {sc.train_rms_px:11.3f}"
        )
    m = fit.mapping
    worst = int(np.argmax(calib.heldout_px))
    print(f"kept: {fit.terms.describe()}")
    print(
        f"held-out RMS {fit.heldout_rms_px:.3f} px (worst: line {rows[worst]}, "
        f"{calib.heldout_px[worst]:.2f} px); fit RMS {fit.rms_px:.3f} px"
    )
    print(
        f"image center ({m.image_center[0]:.2f}, {m.image_center[1]:.2f}) px, aspect "
        f"{m.aspect:.5f}, tilt {m.tilt_deg:.3f} deg, keystone ({m.keystone[0]:.3g}, "
        f"{m.keystone[1]:.3g}) 1/px, azimuth phi = {m.azimuth_sign:+d} theta "
        f"{math.degrees(m.azimuth_offset):+.3f} deg"
    )
    if m.radial_base[0] != 0.0:
        print(
            f"radial: {m.radial_base[0]:.6g} cos(rho) / ({m.radial_base[1]:.6g} + sin(rho)) px"
            + (" + a0..: " + " ".join(f"{c:.6g}" for c in m.coeffs) if np.any(m.coeffs) else "")
        )


# ---------------------------------------------------------------- calibrate screen (ch. 5)


def _register_screen(csub: Any) -> None:
    sc = csub.add_parser(
        "screen",
        help="calibrate camera image -> screen pixels from three patterns (dissertation ch. 5)",
        description="Calibrate a fixed camera watching a screen from captured white, black "
        "and dot-matrix images (--white/--black/--dots), or show the patterns on a "
        "framebuffer and capture them (--show/--source), or write the patterns as PNG "
        "(--write-patterns).",
    )
    sc.add_argument("--white", type=Path, help="captured image of the white pattern")
    sc.add_argument("--black", type=Path, help="captured image of the black pattern")
    sc.add_argument("--dots", type=Path, help="captured image of the dot-matrix pattern")
    sc.add_argument("--n", type=int, default=9, help="dots per row and column (default 9)")
    sc.add_argument("--rows", type=int, help="dot rows (default --n)")
    sc.add_argument("--cols", type=int, help="dot columns (default --n)")
    sc.add_argument(
        "--margin",
        metavar="F[,FY]",
        help="outer dots' distance from the screen edge as a fraction of its width "
        "(and height); default one dot spacing",
    )
    sc.add_argument(
        "--layout",
        type=Path,
        help="the dot layout file --write-patterns wrote (layout.json): rows, columns, margins",
    )
    sc.add_argument("--screen", metavar="WxH", help="screen resolution (default 1920x1080)")
    from omnidev.screencal.calibration import DEFAULT_METHOD, METHODS

    sc.add_argument(
        "--method",
        default=None,
        metavar="|".join(METHODS),
        help=f"image -> screen method: {', '.join(METHODS)} (default {DEFAULT_METHOD})",
    )
    sc.add_argument(
        "--border",
        choices=("region", "tdm"),
        default="region",
        help="screen border from the white-minus-black region (default) or the "
        "dissertation's TDM scan windows",
    )
    sc.add_argument(
        "--dot-exposure",
        choices=("room", "as-is"),
        default="room",
        help="the dot capture's exposure: read from the room and the dots thresholded at "
        "it (default; for auto-exposure cameras) or the images as captured (the "
        "dissertation)",
    )
    sc.add_argument("-o", "--output", type=Path, help="calibration file (.yml or .yml.gz)")
    sc.add_argument(
        "--plot",
        type=Path,
        help="PNG: the border, the dots and the calibrated screen grid over the dot image "
        "(with --truth: every method's error vectors)",
    )
    sc.add_argument(
        "--truth",
        type=Path,
        help="truth JSON (image_points / screen_points pairs, or a rendered fixture's "
        "truth.json): print every method's error on its points",
    )
    sc.add_argument(
        "--recaptured", type=Path, help="a re-captured dot image to evaluate (Fig. 5.14)"
    )
    sc.add_argument("--write-patterns", type=Path, metavar="DIR", help="write the three PNGs")
    sc.add_argument("--show", metavar="/dev/fbN", help="show the patterns on this framebuffer")
    sc.add_argument("--source", help="capture source while --show (e.g. v4l2:/dev/video0)")
    sc.add_argument(
        "--settle", type=int, default=10, help="frames dropped after each pattern change"
    )
    sc.add_argument("--average", type=int, default=4, help="frames averaged per pattern")
    sc.add_argument("--save-captures", type=Path, metavar="DIR", help="keep the captured PNGs")
    sc.add_argument("--force", action="store_true", help="overwrite existing outputs")
    sc.set_defaults(func=run_screen)


def _write_png(path: Path, image: np.ndarray[Any, Any], force: bool) -> None:
    from omnidev.atomic import atomic_path

    with atomic_path(path, force=force) as tmp:
        if not cv2.imwrite(str(tmp), image):
            raise CalibrationError(f"{path}: cannot write PNG")


def _read_grey(path: Path, what: str) -> np.ndarray[Any, Any]:
    """An image file as the API sees it: read as BGR (header checked before decoding),
    converted by screencal's to_gray."""
    from omnidev.screencal.features import to_gray

    img = read_image(path, f"{what} image", error=CalibrationError)
    return to_gray(np.asarray(img, np.uint8))


def _layout(args: argparse.Namespace, size: tuple[int, int]) -> Any:
    """The dot layout from --layout, or --rows/--cols/--n and --margin."""
    from omnidev.screencal.patterns import dot_grid, layout_from_dict

    if args.layout is not None:
        if args.rows or args.cols or args.margin:
            raise CalibrationError("give --layout or --rows/--cols/--margin, not both")
        doc = read_json(args.layout, "JSON layout file", error=CalibrationError)
        if not isinstance(doc, dict):
            raise CalibrationError(f"{args.layout}: not a JSON layout object")
        try:
            lay = layout_from_dict(doc, str(args.layout))
        except ValueError as exc:
            raise CalibrationError(str(exc)) from None
        if args.screen and lay.screen_px != size:
            raise CalibrationError(
                f"--screen {size[0]}x{size[1]} but {args.layout} is for "
                f"{lay.screen_px[0]}x{lay.screen_px[1]}"
            )
        return lay
    margin = None
    if args.margin:
        vals = parse_floats(args.margin, 2 if "," in args.margin else 1, "--margin")
        margin = (vals[0], vals[-1])
    rows = args.rows or args.n
    cols = args.cols or args.n
    if not (2 <= rows <= 64 and 2 <= cols <= 64):
        raise CalibrationError(f"dot layout {rows} x {cols}: give 2..64 dots per row and column")
    try:
        return dot_grid(size[0], size[1], rows=rows, cols=cols, margin=margin)
    except ValueError as exc:
        raise CalibrationError(f"dot layout: {exc}") from None


def _capture(args: argparse.Namespace, size: tuple[int, int]) -> list[np.ndarray[Any, Any]]:
    """Show white, black and dots on the framebuffer; grab each from the source."""
    from omnidev.screencal.framebuffer import Framebuffer
    from omnidev.screencal.patterns import black_pattern, dot_pattern, white_pattern
    from omnidev.sources import open_source

    if not args.source:
        raise CalibrationError("--show needs --source (the camera watching the screen)")
    shots = []
    with Framebuffer(args.show) as fb, open_source(args.source) as src:
        w, h = fb.size
        if args.screen and (w, h) != size:
            raise CalibrationError(f"--screen {size[0]}x{size[1]} but {args.show} is {w}x{h}")
        frames = iter(src)
        patterns = (
            ("white", white_pattern(w, h)),
            ("black", black_pattern(w, h)),
            ("dots", dot_pattern(w, h, layout=_layout(args, (w, h)))[0]),
        )
        for name, pat in patterns:
            print(f"showing the {name} pattern on {args.show} ({w}x{h}); capturing", flush=True)
            fb.show(pat)
            acc = None
            for k in range(args.settle + args.average):
                frame = next(frames, None)
                if frame is None:
                    raise CalibrationError(f"{args.source}: no more frames while capturing {name}")
                if k >= args.settle:
                    from omnidev.screencal.features import to_gray

                    g = to_gray(np.asarray(frame.image, np.uint8)).astype(np.float64)
                    acc = g if acc is None else acc + g
            assert acc is not None
            shots.append(np.clip(acc / max(args.average, 1) + 0.5, 0, 255).astype(np.uint8))
        fb.show(black_pattern(w, h))
    return shots


_LENS_FORM_NAMES = {"poly": "polynomial undistortion", "brown": "forward distortion"}


def run_screen(args: argparse.Namespace) -> int:
    from omnidev.screencal.calibration import (
        DEFAULT_METHOD,
        METHODS,
        detect_screen,
        fit_calibration,
    )

    size = parse_size(args.screen, "--screen", maximum=16384) if args.screen else None
    method = DEFAULT_METHOD if args.method is None else args.method
    if method not in METHODS:
        raise CalibrationError(f"--method {method!r}: choose from {', '.join(METHODS)}")
    if not 2 <= args.n <= 64:
        raise CalibrationError(f"--n {args.n}: give 2..64 dots per row")
    if args.settle < 0 or args.average < 1:
        raise CalibrationError("--settle must be >= 0 and --average >= 1 frames")
    layout = _layout(args, size or (1920, 1080))
    size = layout.screen_px
    check_pixels(size[0], size[1], 12, f"patterns of a {size[0]}x{size[1]} screen")
    if args.write_patterns is not None:
        import json

        from omnidev.atomic import atomic_dir
        from omnidev.screencal.patterns import black_pattern, dot_pattern, white_pattern

        w, h = size
        with atomic_dir(args.write_patterns, force=args.force) as tmp:
            _write_png(tmp / "white.png", white_pattern(w, h), True)
            _write_png(tmp / "black.png", black_pattern(w, h), True)
            _write_png(tmp / "dots.png", dot_pattern(w, h, layout=layout)[0], True)
            (tmp / "layout.json").write_text(json.dumps(layout.to_dict(), indent=1) + "\n")
        for name in ("white.png", "black.png", "dots.png", "layout.json"):
            print(f"wrote {args.write_patterns / name} ({w}x{h}, {layout.describe()})")
        if args.output is None:
            return 0
    if args.output is None:
        raise CalibrationError("give -o/--output for the calibration file")
    check_output(args.output, force=args.force)
    if args.plot is not None:
        check_output(args.plot, force=args.force)
    truth = _read_truth(args.truth) if args.truth is not None else None
    if args.show:
        white, black, dots = _capture(args, size)
        if args.save_captures is not None:
            from omnidev.atomic import atomic_dir

            with atomic_dir(args.save_captures, force=args.force) as tmp:
                for name, img in (("white", white), ("black", black), ("dots", dots)):
                    _write_png(tmp / f"{name}.png", img, True)
    else:
        missing = [k for k in ("white", "black", "dots") if getattr(args, k) is None]
        if missing:
            raise CalibrationError(
                "give --white, --black and --dots (missing: "
                + ", ".join("--" + m for m in missing)
                + "), or --show /dev/fbN --source URI"
            )
        white = _read_grey(args.white, "white")
        black = _read_grey(args.black, "black")
        dots = _read_grey(args.dots, "dot-matrix")
    print(f"finding the screen border and the dots ({layout.describe()}) ...", flush=True)
    features = detect_screen(
        white, black, dots, layout=layout, border=args.border, exposure=args.dot_exposure
    )
    calib = fit_calibration(features, method)
    v = features.border.vertices
    print(
        "screen border polygon P0..P7 (image px): " + " ".join(f"({x:.1f},{y:.1f})" for x, y in v)
    )
    lens = _LENS_FORM_NAMES.get(getattr(calib.transform, "form", ""))
    print(
        f"dots used: {calib.dots_used} of {layout.count}; method {method}"
        + (f" (lens: {lens})" if lens else "")
    )
    if truth is not None:
        _compare(args, features, size, truth)
    elif args.plot is not None:
        from omnidev.screencal.plots import plot_calibration

        plot_calibration(calib, dots, args.plot, force=args.force)
        print(f"wrote {args.plot}")
    calib.save(args.output, force=args.force)
    print(f"wrote {args.output}")
    return 0


def _read_truth(path: Path) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]:
    """Truth pairs (image px (N, 2), screen px (N, 2)) from a JSON file: either
    ``{"image_points": [[u, v], ...], "screen_points": [[x, y], ...]}`` (any source),
    or the truth.json of an ``omnidev sim screen`` fixture (its rig: held-out points
    every 20 screen px). Errors name the file and the key."""
    import json

    try:
        doc = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise CalibrationError(f"{path}: no such truth file") from None
    except (OSError, ValueError) as exc:
        raise CalibrationError(f"{path}: not a JSON truth file ({exc})") from None
    if not isinstance(doc, dict):
        raise CalibrationError(f"{path}: a truth file is a JSON object")
    if "image_points" in doc or "screen_points" in doc:
        arrs = []
        for key in ("image_points", "screen_points"):
            if key not in doc:
                raise CalibrationError(f"{path}: missing key {key!r} (pairs of [x, y])")
            try:
                a = np.asarray(doc[key], np.float64).reshape(-1, 2)
            except (TypeError, ValueError):
                raise CalibrationError(f"{path}: key {key!r} must be a list of [x, y]") from None
            arrs.append(a)
        if len(arrs[0]) != len(arrs[1]) or len(arrs[0]) == 0:
            raise CalibrationError(
                f"{path}: 'image_points' ({len(arrs[0])}) and 'screen_points' "
                f"({len(arrs[1])}) must be equally long and not empty"
            )
        ok = np.isfinite(arrs[0]).all(axis=1) & np.isfinite(arrs[1]).all(axis=1)
        return arrs[0][ok], arrs[1][ok]
    if "rig" in doc:
        from omnidev.screencal.evaluate import heldout_grid
        from omnidev.sim.screen import ScreenRig, screen_to_image

        try:
            rig = ScreenRig.from_dict(doc["rig"])
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationError(f"{path}: key 'rig' is not a screen rig ({exc})") from None
        xy = heldout_grid(rig.screen_px)
        return screen_to_image(rig, xy), xy
    raise CalibrationError(
        f"{path}: a truth file needs 'image_points' and 'screen_points' "
        "(or a rendered fixture's 'rig'); see docs/screen-calibration.md"
    )


def _compare(
    args: argparse.Namespace,
    features: Any,
    size: tuple[int, int],
    truth: tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]],
) -> None:
    """Every method's error on the truth pairs (and Fig. 5.14 with --recaptured)."""
    from omnidev.screencal.calibration import METHODS, detect_screen
    from omnidev.screencal.evaluate import MethodErrors, compare_methods, estimate, table
    from omnidev.screencal.plots import plot_error_vectors

    uv, xy = truth
    rows = compare_methods(features, uv, xy)
    print(f"truth points: {len(xy)} from {args.truth}")
    print(table(rows))
    if args.plot is not None:
        plot_error_vectors(
            rows,
            args.plot,
            size,
            title=f"truth points, {args.truth.name}",
            dots=features.screen_dots,
            force=args.force,
        )
        print(f"wrote {args.plot}")
    if args.recaptured is not None:
        d2 = _read_grey(args.recaptured, "re-captured dot")
        again = detect_screen(
            _read_grey(args.white, "white"),
            _read_grey(args.black, "black"),
            d2,
            layout=features.layout,
            border=args.border,
            exposure=args.dot_exposure,
        )
        ok = again.dots.found
        rec = [
            MethodErrors(
                m,
                features.screen_dots[ok],
                estimate(features, m, again.dots.centers[ok]),
            )
            for m in METHODS
        ]
        print(f"re-captured dot image (Fig. 5.14): {int(ok.sum())} dots")
        print(table(rec))
