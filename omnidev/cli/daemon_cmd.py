"""``omnidev daemon``: the pointer daemon in the foreground (the same as ``omnidevd``)."""

from __future__ import annotations

import argparse
from typing import Any


def register(sub: Any) -> None:
    from omnidev.daemon.main import add_arguments

    p = sub.add_parser(
        "daemon",
        help="run the pointer daemon (source -> tracker -> filter -> sink)",
        description="Run the pointer pipeline of a configuration file until SIGTERM/SIGINT.",
    )
    add_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from omnidev.daemon.main import run_daemon

    return run_daemon(args)
