"""The camera mouse on randomized hand-held videos: ``omnidev eval mouse``.

Each scene is one seed of :func:`omnidev.sim.handheld.draw_video`, rendered in memory
frame by frame (no file, no frame dropped, capture times from the frame rate) and fed
to one camera-mouse tracker per configuration (the same frames for all), with no
filter. Figures per video and pooled (:mod:`omnidev.mouse.evaluate`): cursor error in
px of a 1920x1080 screen by visibility class, the cursor rate, false cursors on videos
without a monitor, hold violations, the worst videos with their seeds.

Configurations: ``default`` (the tracker's defaults) and, for the comparison of the
missing-landmark predictions on the same frames, one per ``predict`` choice.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from omnidev.errors import OmnidevError

CONFIGS: dict[str, dict[str, Any]] = {
    "default": {"predict": "flow"},
    "translation": {"predict": "translation"},
    "similarity": {"predict": "similarity"},
    "rotation": {"predict": "rotation"},
    "flow": {"predict": "flow"},
    "affine": {"method": "affine"},
}


def run_video(
    seed: int,
    *,
    frames: int = 300,
    configs: Mapping[str, Mapping[str, Any]] | None = None,
    kind: str | None = None,
    size: tuple[int, int] | None = None,
    keep_frames: bool = False,
) -> dict[str, Any]:
    """Render video ``seed`` and track it with every configuration; JSON-ready result.

    ``keep_frames``: also return per-frame truth and cursors (for plots and debugging).
    """
    import cv2

    from omnidev.frame import Frame
    from omnidev.mouse.evaluate import video_errors
    from omnidev.sim.handheld import HandheldRenderer, draw_video
    from omnidev.tracking import open_tracker

    cv2.setNumThreads(1)
    configs = configs or {"default": {}}
    video = draw_video(seed, frames=frames, kind=kind, size=size)
    t0 = time.perf_counter()
    renderer = HandheldRenderer(video)
    render_s = time.perf_counter() - t0
    track_s = dict.fromkeys(configs, 0.0)
    with tempfile.TemporaryDirectory(prefix="omnidev-eval-mouse-") as tmp:
        layout = Path(tmp) / "landmarks.json"
        layout.write_text(json.dumps(video.layout_dict()))
        trackers = {
            name: open_tracker("camera-mouse", dict(opts), layout) for name, opts in configs.items()
        }
        cursors: dict[str, list[tuple[float, float] | None]] = {n: [] for n in configs}
        truth = []
        for i in range(frames):
            t1 = time.perf_counter()
            img = renderer.render(i)
            truth.append(renderer.truth(i))
            render_s += time.perf_counter() - t1
            ts = round(i / video.imaging.fps * 1e9)
            for name, trk in trackers.items():
                t2 = time.perf_counter()
                s = trk.track(Frame(img, ts, i))
                track_s[name] += time.perf_counter() - t2
                cursors[name].append(None if s is None else (s.x, s.y))
    desc = video.describe()
    out: dict[str, Any] = {
        "seed": seed,
        "kind": video.kind,
        "size": desc["size"],
        "video": desc,
        "render_ms_per_frame": round(1000 * render_s / frames, 2),
        "track_ms_per_frame": {n: round(1000 * v / frames, 3) for n, v in track_s.items()},
        "figures": {
            n: video_errors(c, truth, kind=video.kind).summary() for n, c in cursors.items()
        },
    }
    if keep_frames:
        out["truth"] = truth
        out["cursors"] = cursors
    return out


def _job(args: tuple[int, int, Mapping[str, Mapping[str, Any]]]) -> dict[str, Any]:
    seed, frames, configs = args
    return run_video(seed, frames=frames, configs=configs, keep_frames=True)


def evaluate_scenes(
    scenes: int,
    seed: int,
    *,
    frames: int = 300,
    jobs: int = 1,
    configs: Mapping[str, Mapping[str, Any]] | None = None,
    progress: bool = True,
    on_video: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Videos of seeds ``seed .. seed + scenes - 1``: per-video and pooled figures per
    configuration (see the module docstring). ``jobs`` worker processes."""
    from omnidev.mouse.evaluate import VideoErrors, pooled_summary, video_errors

    configs = dict(configs or {"default": {}})
    todo: list[tuple[int, int, Mapping[str, Mapping[str, Any]]]] = [
        (s, frames, configs) for s in range(seed, seed + scenes)
    ]
    results: list[dict[str, Any]] = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(todo), desc="eval mouse", unit="video", file=sys.stderr)
    if jobs > 1:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(jobs) as pool:
            for r in pool.imap_unordered(_job, todo):
                results.append(r)
                if on_video:
                    on_video(r)
                if bar:
                    bar.update()
    else:
        for a in todo:
            r = _job(a)
            results.append(r)
            if on_video:
                on_video(r)
            if bar:
                bar.update()
    if bar:
        bar.close()
    results.sort(key=lambda r: r["seed"])
    pooled: dict[str, Any] = {}
    for name in configs:
        errs: list[VideoErrors] = [
            video_errors(r["cursors"][name], r["truth"], kind=r["kind"]) for r in results
        ]
        pooled[name] = pooled_summary(results, errs)
    videos = [{k: v for k, v in r.items() if k not in ("truth", "cursors")} for r in results]
    return {
        "task": "mouse",
        "seeds": [seed, seed + scenes - 1],
        "frames_per_video": frames,
        "configs": configs,
        "pooled": pooled,
        "videos": videos,
    }


def register(sub: Any) -> None:
    """``omnidev eval mouse`` (registered by omnidev.cli.eval_cmd)."""
    p = sub.add_parser(
        "mouse",
        help="the camera mouse on randomized hand-held videos (cursor error by visibility)",
        description=(__doc__ or "").split("\n\n")[1].replace("\n", " "),
    )
    p.add_argument("--scenes", type=int, default=20, help="number of videos (default 20)")
    p.add_argument("--seed", type=int, default=10000, help="first seed (default 10000)")
    p.add_argument("--frames", type=int, default=300, help="frames per video (default 300)")
    p.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    p.add_argument(
        "--configs",
        default="default",
        help="comma-separated tracker configurations: default, translation, similarity, "
        "rotation, flow, affine, or all (default: default)",
    )
    p.add_argument("--json", action="store_true", help="print the whole result as JSON")
    p.add_argument("--out", type=Path, help="also write the JSON result to this file")
    p.set_defaults(func=run)


def _configs(text: str) -> dict[str, dict[str, Any]]:
    names = list(CONFIGS) if text == "all" else [n.strip() for n in text.split(",") if n.strip()]
    for n in names:
        if n not in CONFIGS:
            raise OmnidevError(
                f"--configs: unknown configuration {n!r} ({', '.join(CONFIGS)}, all)"
            )
    return {n: CONFIGS[n] for n in names}


def run(args: argparse.Namespace) -> int:
    if args.scenes < 1:
        raise OmnidevError(f"--scenes {args.scenes}: need at least 1")
    if args.frames < 2:
        raise OmnidevError(f"--frames {args.frames}: need at least 2")
    if args.jobs < 1 or args.jobs > (os.cpu_count() or 1) * 4:
        raise OmnidevError(f"--jobs {args.jobs}: use 1..{(os.cpu_count() or 1) * 4}")
    res = evaluate_scenes(
        args.scenes, args.seed, frames=args.frames, jobs=args.jobs, configs=_configs(args.configs)
    )
    if args.out:
        from omnidev.atomic import atomic_path

        with atomic_path(args.out, force=True) as tmp:
            tmp.write_text(json.dumps(res, indent=1) + "\n")
    if args.json:
        print(json.dumps(res, indent=1))
    else:
        print_summary(res)
    return 0


def print_summary(res: Mapping[str, Any]) -> None:
    """A short human-readable table of the pooled figures."""

    def f(x: Any) -> str:
        return "-" if x is None else f"{x:.2f}"

    print(f"seeds {res['seeds'][0]}..{res['seeds'][1]}, {res['frames_per_video']} frames each")
    for name, pooled in res["pooled"].items():
        for group, g in pooled.items():
            a, p, o = g["all4"], g["predicted"], g["off_screen"]
            print(
                f"[{name}] {group}: {g['normal_videos']}/{g['videos']} videos with a monitor; "
                f"all four: RMS {f(a['rms_px'])} p95 {f(a['p95_px'])} max {f(a['max_px'])} px "
                f"({a['n']} frames), videos within {g['all4_video_rms_bound_px']:g} px: "
                f"{g['all4_videos_within_bound']}; predicted: RMS {f(p['rms_px'])} "
                f"p95 {f(p['p95_px'])} ({p['n']}); off screen (pinned): RMS {f(o['rms_px'])}; "
                f"cursor rate {g['cursor_rate']}; hold violations {g['hold_violations']}; "
                f"gross {g['gross_errors']}; false cursors {g['false_cursors']}"
            )


def main_standalone(argv: Sequence[str] | None = None) -> int:
    """``python -m omnidev.cli.eval_mouse`` (the same options as ``omnidev eval mouse``)."""
    parser = argparse.ArgumentParser(prog="omnidev eval")
    sub = parser.add_subparsers(dest="task", required=True)
    register(sub)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except OmnidevError as exc:
        print(f"omnidev eval: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main_standalone())
