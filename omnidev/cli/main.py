"""The ``omnidev`` command: one subcommand per module of omnidev.cli.

Each subcommand module has ``register(subparsers)`` (which sets ``func``) and
``run(args) -> int``. An :class:`omnidev.errors.OmnidevError` is printed as one
line and exits with status 2; Ctrl-C exits with 130 and SIGTERM with 143, both
after the command's temporaries are removed and its pointer buttons released.

Every command takes ``--max-memory SIZE`` (default: half the physical memory, see
:mod:`omnidev.budget`).
A value that starts with a minus sign and a digit is a value, never an option:
``--elevation-range -50,10`` works as ``--elevation-range=-50,10`` does.
"""

from __future__ import annotations

import argparse
import importlib
import re
import signal
import sys
import threading
from collections.abc import Sequence
from types import FrameType
from typing import Any

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

_NEGATIVE_VALUE = re.compile(r"^-\.?\d")


class OmnidevParser(argparse.ArgumentParser):
    """argparse with one change: ``-50,10``, ``-0.3,0,1`` and ``-1e3`` are values.

    (argparse only takes plain negative numbers such as ``-50`` as values; no omnidev
    option starts with a digit, so nothing else is lost.)
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_VALUE


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that ``finally`` blocks and temporaries clean up."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _version() -> str:
    from importlib import metadata

    import omnidev

    try:
        return metadata.version("omnidev")
    except metadata.PackageNotFoundError:
        return omnidev.__version__


def _leaf_parsers(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        return [parser]
    out: list[argparse.ArgumentParser] = []
    for action in subs:
        for child in dict.fromkeys(action.choices.values()):
            out.extend(_leaf_parsers(child))
    return out


def build_parser() -> argparse.ArgumentParser:
    parser = OmnidevParser(
        prog="omnidev",
        description="Omni-cameras as calibrated instruments and pointing devices.",
    )
    parser.add_argument("--version", action="version", version=f"omnidev {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMANDS:
        module = importlib.import_module(f"omnidev.cli.{name}")
        module.register(sub)
    for leaf in _leaf_parsers(parser):
        if not any("--max-memory" in a.option_strings for a in leaf._actions):
            leaf.add_argument(
                "--max-memory",
                metavar="SIZE",
                help="largest memory this command may use, e.g. 512M or 4G (default: "
                "$OMNIDEV_MAX_MEMORY, else half the physical memory; 0: no limit); larger "
                "views, tables and images are refused with their estimate",
            )
    return parser


def _on_sigterm(signum: int, frame: FrameType | None) -> None:
    raise Terminated(signum)


def main(argv: Sequence[str] | None = None) -> int:
    from omnidev.budget import parse_memory, set_max_memory, start_command

    old_term: Any = None
    if threading.current_thread() is threading.main_thread():
        old_term = signal.signal(signal.SIGTERM, _on_sigterm)
    command = "(starting)"
    try:
        args = build_parser().parse_args(argv)
        command = args.command
        set_max_memory(parse_memory(args.max_memory) if args.max_memory else None)
        start_command()
        return int(args.func(args))
    except OmnidevError as exc:
        print(f"omnidev {command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"omnidev {command}: interrupted", file=sys.stderr)
        return 130
    except Terminated as exc:
        print(f"omnidev {command}: terminated (signal {exc.signum})", file=sys.stderr)
        return 128 + exc.signum
    finally:
        set_max_memory(None)
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)


if __name__ == "__main__":
    sys.exit(main())
