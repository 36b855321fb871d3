"""The ``omnidev`` command: one subcommand per module of omnidev.cli.

Each subcommand module has ``register(subparsers)`` (which sets ``func``) and
``run(args) -> int``. An :class:`omnidev.errors.OmnidevError` is printed as one
line and exits with status 2; Ctrl-C exits with 130.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from omnidev.errors import OmnidevError

SUBCOMMANDS = (
    "plugins_cmd",
    "devices_cmd",
    "calibrate_cmd",
    "landmarks_cmd",
    "unwarp_cmd",
    "sim_cmd",
    "bench_cmd",
    "daemon_cmd",
    "ctl_cmd",
    "replay_cmd",
    "mouse_cmd",
    "laser_cmd",
    "nonsvp_cmd",
    "eval_cmd",
    "batch_cmd",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="omnidev",
        description="Omni-cameras as calibrated instruments and pointing devices.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMANDS:
        module = importlib.import_module(f"omnidev.cli.{name}")
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except OmnidevError as exc:
        print(f"omnidev {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"omnidev {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
