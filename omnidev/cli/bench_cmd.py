"""``omnidev bench NAME [--json]``: run a benchmark from the checkout's bench/ folder.

A benchmark is ``bench/NAME.py`` with ``run(quick: bool) -> dict`` whose keys
name each figure with its unit (``build_ms``, ``ratio_vs_remap``...). Speed is
reported as ratios against an anchor measured in the same run.

Full runs take minutes and print their figures only at the end, so the command
says on stderr when it starts, how long it has run every ``HEARTBEAT_S``
seconds, and how long it took.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import re
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import omnidev
from omnidev.errors import OmnidevError

HEARTBEAT_S = 30.0  # seconds between the "still running" lines


def bench_dir() -> Path:
    env = os.environ.get("OMNIDEV_BENCH_DIR")
    if env:
        return Path(env)
    return Path(omnidev.__file__).resolve().parents[1] / "bench"


def available() -> list[str]:
    d = bench_dir()
    return (
        sorted(p.stem for p in d.glob("*.py") if not p.stem.startswith("_")) if d.is_dir() else []
    )


_DOC = re.compile(r'^"""(.*?)(?:\n\n|""")', re.S)


def summary(name: str) -> str:
    """The first paragraph of ``bench/NAME.py``'s docstring, on one line (the file is
    read, not imported: every ``omnidev`` start builds this help)."""
    try:
        with open(bench_dir() / f"{name}.py", encoding="utf-8") as f:
            head = f.read(4000)
    except (OSError, UnicodeDecodeError):
        return ""
    m = _DOC.match(head)
    return " ".join(m.group(1).replace("``", "").split()) if m else ""


def _listing() -> str:
    names = available()
    if not names:
        return f"no benchmarks found in {bench_dir()}"
    width = max(len(n) for n in names)
    lines = [f"  {n:<{width}}  {summary(n)}" for n in names]
    return "benchmarks (bench/NAME.py):\n" + "\n".join(lines)


def register(sub: Any) -> None:
    p = sub.add_parser(
        "bench",
        help="run a benchmark (ratios against its anchor)",
        epilog=_listing(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("name", help="benchmark name: one of those listed below")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--quick", action="store_true", help="fewer repetitions (smoke run)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    path = bench_dir() / f"{args.name}.py"
    if not path.is_file():
        names = ", ".join(available()) or "none found"
        raise OmnidevError(f"no benchmark {args.name!r} in {bench_dir()}; available: {names}")
    spec = importlib.util.spec_from_file_location(f"omnidev_bench_{args.name}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with _heartbeat(args.name, args.quick):
        result: dict[str, Any] = module.run(quick=args.quick)
    if args.json:
        print(json.dumps(result))
    else:
        width = max(len(k) for k in result)
        for key, value in result.items():
            shown = f"{value:.4g}" if isinstance(value, float) else str(value)
            print(f"{key:<{width}}  {shown}")
    return 0


def _minutes(seconds: float) -> str:
    m, s = divmod(round(seconds), 60)
    return f"{m} min {s:02d} s" if m else f"{s} s"


@contextmanager
def _heartbeat(name: str, quick: bool) -> Iterator[None]:
    """Lines on stderr while benchmark ``name`` runs: its start, the time so far every
    HEARTBEAT_S seconds (from a daemon thread), and its wall time at the end."""
    t0 = time.monotonic()
    how = "a short run (--quick)" if quick else "a full run takes minutes; --quick is short"
    print(f"omnidev bench {name}: running ({how})", file=sys.stderr, flush=True)
    stop = threading.Event()

    def beat() -> None:
        while not stop.wait(HEARTBEAT_S):
            so_far = _minutes(time.monotonic() - t0)
            print(f"omnidev bench {name}: {so_far} so far", file=sys.stderr, flush=True)

    thread = threading.Thread(target=beat, name="bench-heartbeat", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
    took = _minutes(time.monotonic() - t0)
    print(f"omnidev bench {name}: done in {took}", file=sys.stderr, flush=True)
