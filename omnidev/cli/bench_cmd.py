"""``omnidev bench NAME [--json]``: run a benchmark from the checkout's bench/ folder.

A benchmark is ``bench/NAME.py`` with ``run(quick: bool) -> dict`` whose keys
name each figure with its unit (``build_ms``, ``ratio_vs_remap``...). Speed is
reported as ratios against an anchor measured in the same run.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import re
from pathlib import Path
from typing import Any

import omnidev
from omnidev.errors import OmnidevError


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
    result: dict[str, Any] = module.run(quick=args.quick)
    if args.json:
        print(json.dumps(result))
    else:
        width = max(len(k) for k in result)
        for key, value in result.items():
            shown = f"{value:.4g}" if isinstance(value, float) else str(value)
            print(f"{key:<{width}}  {shown}")
    return 0
