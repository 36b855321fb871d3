"""``omnidev eval TASK --scenes N --seed S``: a method over randomized scenes, pooled figures.

Tasks live in :mod:`omnidev.evaluation.tasks` (one module each). ``--scene-seed K
--write DIR`` replays one scene and writes its images and truth for inspection.
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
from typing import Any

from omnidev.errors import OmnidevError

MAX_SEED = 2**31 - 1
"""Largest scene seed."""


def register(sub: Any) -> None:
    p = sub.add_parser(
        "eval",
        help="evaluate a method over randomized scenes (refusals, errors, worst seeds)",
        description="Run TASK over N randomized scenes with seeds S..S+N-1 and report "
        "per-scene and pooled figures, classes of scenes apart, refusals with their "
        "messages and the worst scenes' seeds. See docs/evaluation.md.",
    )
    p.add_argument("task", help="task name (omnidev eval --list)", nargs="?")
    p.add_argument("--list", action="store_true", help="list the tasks and their options")
    p.add_argument("--scenes", type=int, default=20, help="number of scenes (default 20)")
    p.add_argument("--seed", type=int, default=0, help="first scene seed (default 0)")
    p.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="worker processes (default 1; 0 = one per core)",
    )
    p.add_argument("--json", action="store_true", help="print the whole report as JSON")
    p.add_argument("-o", "--output", type=Path, help="also write the JSON report to this file")
    p.add_argument("--opt", action="append", default=[], metavar="KEY=VALUE", help="a task option")
    p.add_argument("--scene-seed", type=int, help="replay this one scene and print its result")
    p.add_argument("--write", type=Path, metavar="DIR", help="with --scene-seed: write its images")
    p.add_argument("--force", action="store_true", help="overwrite --output / --write")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument(
        "--merge",
        nargs="+",
        type=Path,
        metavar="REPORT",
        help="pool JSON reports of TASK (e.g. a long run made in chunks of seeds) into one",
    )
    p.set_defaults(func=run)


def _clean(obj: Any) -> Any:
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    return obj


def run(args: argparse.Namespace) -> int:
    from omnidev.atomic import atomic_path, check_output
    from omnidev.cli.options import key_values
    from omnidev.evaluation.framework import (
        evaluate,
        load_task,
        merge_reports,
        report_text,
        run_one,
        task_names,
    )

    if args.list or args.task is None:
        for name in task_names():
            t = load_task(name)
            opts = ", ".join(f"{k}={v}" for k, v in t.options.items()) or "no options"
            print(f"{name}: {t.help} ({opts})")
        return 0
    task = load_task(args.task)
    from omnidev.evaluation.framework import typed_options

    options = typed_options(task, key_values(args.opt, "--opt"))
    if args.output is not None:
        check_output(args.output, force=args.force)
    if args.scene_seed is not None:
        w = args.write
        if w is not None and (w.exists() or w.is_symlink()):
            if not w.is_dir():
                raise OmnidevError(f"--write {w}: exists and is not a folder")
            if any(w.iterdir()) and not args.force:
                raise OmnidevError(f"{args.write} exists and is not empty; pass --force")
        if w is not None:
            try:
                w.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise OmnidevError(f"--write {w}: {exc.strerror or exc}") from None
        if not 0 <= args.scene_seed <= MAX_SEED:
            raise OmnidevError(f"--scene-seed {args.scene_seed}: give 0 .. {MAX_SEED}")
        res = run_one(task, args.scene_seed, options, args.write)
        doc = _clean(res.to_dict())
        if args.json:
            print(json.dumps(doc))
        else:
            print(f"scene {res.seed}: {res.status}" + (f": {res.message}" if res.message else ""))
            for key, label in res.classes.items():
                print(f"  {key}: {label}")
            for key, value in sorted(res.metrics.items()):
                print(f"  {key} = {value:.4g}")
            for key, flag in sorted(res.flags.items()):
                print(f"  {key}: {flag}")
            if args.write is not None and res.status != "error":
                print(f"wrote {args.write}/")
        return 0 if res.status != "error" else 1
    if args.write is not None:
        raise OmnidevError("--write needs --scene-seed (the one scene to write)")
    if args.merge:
        doc = merge_reports(task, [(str(f), _read_report(f)) for f in args.merge])
    else:
        if not 1 <= args.scenes <= 1_000_000:
            raise OmnidevError(f"--scenes {args.scenes}: give 1 .. 1000000 scenes")
        if not 0 <= args.jobs <= 256:
            raise OmnidevError(f"--jobs {args.jobs}: give 0 (one per core) .. 256")
        if not 0 <= args.seed <= MAX_SEED - args.scenes + 1:
            raise OmnidevError(f"--seed {args.seed}: the scene seeds must be 0 .. {MAX_SEED}")
        jobs = args.jobs if args.jobs > 0 else (os.cpu_count() or 1)
        doc = evaluate(
            task,
            scenes=args.scenes,
            seed=args.seed,
            options=options,
            jobs=jobs,
            progress=not args.no_progress,
        )
    doc = _clean(doc)
    if args.output is not None:
        with atomic_path(args.output, force=args.force) as tmp:
            tmp.write_text(json.dumps(doc) + "\n")
    if args.json:
        print(json.dumps(doc))
    else:
        print(report_text(doc, task.headline))
        if args.output is not None:
            print(f"wrote {args.output}")
    return 1 if doc["pooled"]["errors"] else 0


def _read_report(path: Path) -> Any:
    from omnidev.inputfile import read_json

    if not (path.exists() or path.is_symlink()):
        raise OmnidevError(f"{path}: no such report")
    return read_json(path, "JSON report of omnidev eval")
