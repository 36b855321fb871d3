"""``omnidev mouse SOURCE --layout FILE --sink NAME``: the camera mouse in the foreground.

Runs the daemon's pipeline (source -> camera-mouse tracker -> One Euro filter
-> sink) on any source into any sink, until a file source ends or Ctrl-C /
SIGTERM; buttons are released on the way out.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from omnidev.cli.foreground import add_pointer_arguments
from omnidev.errors import OmnidevError
from omnidev.mouse import DEFAULT_PREDICT, PREDICTIONS


def register(sub: Any) -> None:
    p = sub.add_parser(
        "mouse",
        help="run the camera mouse (hand-held webcam aimed at a monitor) into a pointer sink",
        description=__doc__.splitlines()[0].replace("``", "") if __doc__ else None,
    )
    p.add_argument("source", help="source URI or path (v4l2:/dev/video0, a video file, ...)")
    p.add_argument("--layout", required=True, type=Path, help="landmark layout (JSON or TOML)")
    p.add_argument(
        "--method",
        choices=("homography", "affine"),
        default="homography",
        help="cursor from the four screen corners (affine: the dissertation's eqs. 6.1-6.4)",
    )
    p.add_argument(
        "--predict",
        choices=PREDICTIONS,
        default=DEFAULT_PREDICT,
        help="how one or two missing landmarks are predicted (translation: the dissertation's)",
    )
    p.add_argument(
        "--fov-deg",
        type=float,
        default=60.0,
        help="the webcam's horizontal field of view, degrees (--predict rotation; flow's "
        "fallback when too few features agree)",
    )
    add_pointer_arguments(p)
    p.set_defaults(func=run)
    ev = sub.add_parser(
        "mouse-eval",
        help="camera-mouse cursor error against a rendered fixture's truth",
        description="Run the camera-mouse tracker frame by frame (no filter, no frame "
        "dropped) on fixture folders written by `omnidev sim mouse` and print the cursor "
        "error against truth on the 1920x1080 screen: frames with all four landmarks "
        "visible, with one or two predicted, and with three or more missing (which must "
        "give no cursor).",
    )
    ev.add_argument("fixtures", nargs="+", type=Path, help="fixture folders (truth.json inside)")
    ev.add_argument(
        "--method", choices=("homography", "affine", "both"), default="both", help="cursor model"
    )
    ev.add_argument(
        "--predict",
        choices=PREDICTIONS,
        default=DEFAULT_PREDICT,
        help="how missing landmarks are predicted (translation: the dissertation's)",
    )
    ev.add_argument("--fov-deg", type=float, default=60.0, help="webcam horizontal field of view")
    ev.add_argument("--layout", type=Path, help="layout file (default: FIXTURE/landmarks.json)")
    ev.add_argument("--json", action="store_true", help="print the figures as JSON")
    ev.set_defaults(func=run_eval)
    lm = sub.add_parser(
        "mouse-landmarks",
        help="write the printable camera-mouse landmark sheet (PNG, PDF) and its layout file",
        description="Write landmarks.png and landmarks.pdf (A4, true size: check the 100 mm "
        "scale bar after printing) and landmarks.json, the layout `omnidev mouse --layout` "
        "reads. Stick the landmarks with their circle centres MARGIN outside each screen corner.",
    )
    lm.add_argument("outdir", type=Path)
    lm.add_argument(
        "--screen-mm", required=True, metavar="WxH", help="the lit screen area, mm (e.g. 527x296)"
    )
    lm.add_argument(
        "--margin-mm",
        default="25x25",
        metavar="XxY",
        help="circle centre outside each screen corner, mm (default 25x25)",
    )
    lm.add_argument("--circle-mm", type=float, default=20.0, help="circle diameter, mm")
    lm.add_argument("--square-mm", type=float, default=30.0, help="white square side, mm")
    lm.add_argument("--dpi", type=float, default=300.0)
    lm.add_argument("--force", action="store_true", help="overwrite existing files")
    lm.set_defaults(func=run_landmarks)


def run(args: argparse.Namespace) -> int:
    from omnidev.cli.foreground import run_foreground
    from omnidev.inputfile import not_a_file

    why = not_a_file(args.layout, "landmark layout file")
    if why is not None:
        raise OmnidevError(f"{args.layout}: {why}")
    tracker = {
        "name": "camera-mouse",
        "calibration": str(args.layout.resolve()),
        "options": {"method": args.method, "predict": args.predict, "fov_deg": args.fov_deg},
    }
    return run_foreground(
        args,
        "mouse",
        tracker,
        check=lambda pipeline, config: _warn_aspect(
            getattr(pipeline.tracker, "layout", None), config.screen.screen
        ),
    )


def _warn_aspect(layout: Any, rect: Any) -> None:
    """Warn when the landmark layout's screen (mm) and the target screen (px) differ in
    shape: the cursor would then be stretched."""
    if layout is None:
        return
    mm = layout.screen_width_mm / layout.screen_height_mm
    px = rect.width / rect.height
    if abs(mm / px - 1.0) > 0.02:
        print(
            f"omnidev mouse: warning: the layout's screen is {layout.screen_width_mm:g}x"
            f"{layout.screen_height_mm:g} mm (aspect {mm:.3f}) but --screen is "
            f"{rect.width}x{rect.height} px (aspect {px:.3f}): the cursor will be stretched",
            file=sys.stderr,
        )


def _pair(text: str, what: str) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in text.lower().split("x"))
    except ValueError:
        raise OmnidevError(f"{what} {text!r} is not WxH in mm (e.g. 527x296)") from None
    return a, b


def run_landmarks(args: argparse.Namespace) -> int:
    import json

    import cv2
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from omnidev.atomic import atomic_path
    from omnidev.mouse.landmarks import LandmarkLayout, draw_landmark_sheet

    w, h = _pair(args.screen_mm, "--screen-mm")
    mx, my = _pair(args.margin_mm, "--margin-mm")
    if not (50 <= w <= 5000 and 50 <= h <= 5000):
        raise OmnidevError(f"--screen-mm {args.screen_mm}: give 50..5000 mm per side")
    if not (0 <= mx <= 500 and 0 <= my <= 500):
        raise OmnidevError(f"--margin-mm {args.margin_mm}: give 0..500 mm")
    for flag, v in (("--circle-mm", args.circle_mm), ("--square-mm", args.square_mm)):
        if not 1 <= v <= 300:
            raise OmnidevError(f"{flag} {v:g}: give 1..300 mm")
    if args.dpi < 72 or args.dpi > 1200:
        raise OmnidevError(f"--dpi {args.dpi:g}: use 72..1200")
    layout = LandmarkLayout.symmetric(
        w, h, margin_mm=(mx, my), circle_diameter_mm=args.circle_mm, square_side_mm=args.square_mm
    )
    page = draw_landmark_sheet(layout, dpi=args.dpi)
    args.outdir.mkdir(parents=True, exist_ok=True)
    outs = {n: args.outdir / n for n in ("landmarks.png", "landmarks.pdf", "landmarks.json")}
    for path in outs.values():
        if path.exists() and not args.force:
            raise OmnidevError(f"{path} exists; pass --force to overwrite")
    with atomic_path(outs["landmarks.png"], force=args.force) as tmp:
        if not cv2.imwrite(str(tmp), page, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
            raise OmnidevError(f"{outs['landmarks.png']}: cannot write the PNG")
    paper_in = (210.0 / 25.4, 297.0 / 25.4)
    fig = plt.figure(figsize=paper_in)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))  # the page image fills the A4 page exactly
    ax.imshow(page, cmap="gray", vmin=0, vmax=255, interpolation="nearest")
    ax.set_axis_off()
    with atomic_path(outs["landmarks.pdf"], force=args.force) as tmp:
        fig.savefig(tmp, format="pdf", dpi=args.dpi)
    plt.close(fig)
    with atomic_path(outs["landmarks.json"], force=args.force) as tmp:
        tmp.write_text(json.dumps(layout.to_dict(), indent=2) + "\n")
    for path in outs.values():
        print(f"wrote {path}")
    print("print the PDF at 100% (no fit-to-page) and check the 100 mm scale bar")
    return 0


def evaluate_fixture(
    folder: Path,
    method: str,
    predict: str = DEFAULT_PREDICT,
    layout: Path | None = None,
    fov_deg: float = 60.0,
) -> dict[str, Any]:
    """The :func:`omnidev.mouse.evaluate.evaluate` figures of one fixture folder."""
    import json

    from omnidev.frame import Frame
    from omnidev.mouse.evaluate import evaluate
    from omnidev.sources import open_source
    from omnidev.tracking import open_tracker

    truth_path = folder / "truth.json"
    try:
        doc = json.loads(truth_path.read_text(encoding="utf-8"))
        truth = doc["per_frame"]
    except OSError as exc:
        raise OmnidevError(f"{truth_path}: cannot read: {exc.strerror}") from None
    except (ValueError, KeyError, TypeError) as exc:
        raise OmnidevError(f"{truth_path}: not a camera-mouse truth file ({exc})") from None
    layout = layout or folder / "landmarks.json"
    options = {"method": method, "predict": predict, "fov_deg": fov_deg}
    tracker = open_tracker("camera-mouse", options, layout)
    cursors: list[tuple[float, float] | None] = []
    with open_source(str(folder / "mouse.avi")) as source:
        for frame in source:
            # capture times from the truth's frame times (the file's are delivery times)
            i = frame.index
            t = truth[i].get("t") if i < len(truth) else None
            ts = round(float(t) * 1e9) if isinstance(t, int | float) else i
            s = tracker.track(Frame(frame.image, ts, i))
            cursors.append(None if s is None else (s.x, s.y))
    if len(cursors) != len(truth):
        raise OmnidevError(
            f"{folder / 'mouse.avi'}: {len(cursors)} frames, truth.json has {len(truth)}"
        )
    cam = doc.get("camera", {})
    size = (int(cam["width"]), int(cam["height"])) if "width" in cam else None
    figures = evaluate(cursors, truth, image_size=size).as_dict()
    figures.update(
        fixture=str(folder), method=method, predict=predict, fov_deg=fov_deg, frames=len(truth)
    )
    figures["relocks"] = getattr(tracker, "relocks", None)
    return figures


def run_eval(args: argparse.Namespace) -> int:
    import json

    methods = ("homography", "affine") if args.method == "both" else (args.method,)
    rows = []
    for folder in args.fixtures:
        for m in methods:
            rows.append(evaluate_fixture(folder, m, args.predict, args.layout, args.fov_deg))
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0

    def fig(c: dict[str, Any]) -> str:
        if not c["with_cursor"]:
            return f"{'-':>13} {c['with_cursor']:>3}/{c['frames']:<3}"
        return f"{c['rms_px']:6.2f}/{c['max_px']:6.2f} {c['with_cursor']:>3}/{c['frames']:<3}"

    width = max(len(Path(r["fixture"]).name) for r in rows)
    print(
        f"{'fixture':<{width}}  {'method':<10}  {'all four visible':>21}  "
        f"{'1-2 predicted':>21}  {'3+ missing: held':>16}"
    )
    print(f"{'':<{width}}  {'':<10}  {'RMS/max px cursors':>21}  {'RMS/max px cursors':>21}")
    for r in rows:
        held = f"{r['hold_frames'] - r['hold_violations']}/{r['hold_frames']}"
        print(
            f"{Path(r['fixture']).name:<{width}}  {r['method']:<10}  {fig(r['all4']):>21}  "
            f"{fig(r['predicted']):>21}  {held:>16}"
            + (f"  FALSE CURSORS {r['false_cursors']}" if r["false_cursors"] else "")
        )
    print("(errors in px of a 1920x1080 screen; cursors = frames with a cursor / frames)")
    return 0
