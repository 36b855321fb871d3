"""``omnidev ctl``: talk to a running omnidevd through its control socket.

    omnidev ctl status [--socket PATH] [--json]
    omnidev ctl pause | resume | reload [--socket PATH] [--json]

``status`` prints the daemon's state, source, tracker, sink, frame rate (frames
per second), latency from frame capture to the sink (p50/p99, milliseconds),
frame and drop counts, camera retries and uptime. ``--json`` prints the reply
object as received. A refused command or an unreachable daemon is a one-line
error (exit status 2).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from omnidev.daemon.control import COMMANDS, DEFAULT_SOCKET, ControlError, request


def register(sub: Any) -> None:
    p = sub.add_parser(
        "ctl",
        help="control a running omnidevd (status, pause, resume, reload)",
        description="Send a command to omnidevd's control socket and print its reply.",
    )
    p.add_argument("action", choices=COMMANDS, help="command to send")
    p.add_argument(
        "--socket",
        type=Path,
        default=DEFAULT_SOCKET,
        metavar="PATH",
        help=f"control socket (default {DEFAULT_SOCKET}, the [daemon] socket of the config)",
    )
    p.add_argument("--json", action="store_true", help="print the reply as one JSON object")
    p.add_argument(
        "--timeout", type=float, default=5.0, metavar="S", help="seconds to wait (default 5)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if not 0 < args.timeout <= 3600:
        raise ControlError(f"--timeout {args.timeout:g}: give seconds in (0, 3600]")
    reply = request(args.socket, args.action, timeout=args.timeout)
    if not reply.get("ok"):
        raise ControlError(f"omnidevd refused {args.action!r}: {reply.get('error', 'no reason')}")
    if args.json:
        print(json.dumps(reply, sort_keys=True))
    elif args.action == "status":
        print(format_status(reply))
    else:
        state = reply.get("state")
        message = reply.get("message")
        parts = [f"omnidevd: {args.action} ok"]
        if state:
            parts.append(f"state {state}")
        if message:
            parts.append(str(message))
        print(", ".join(parts))
    return 0


def _num(value: Any, fmt: str, unit: str = "") -> str:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return "-"
    if fmt.endswith("d"):
        value = int(value)
    return f"{value:{fmt}}{unit}"


def format_duration(seconds: Any) -> str:
    """``seconds`` as ``1 d 02:03:04`` / ``02:03:04`` (hours:minutes:seconds), ``-`` if unknown.

    >>> format_duration(3723.9)
    '01:02:03'
    >>> format_duration(90061)
    '1 d 01:01:01'
    """
    if isinstance(seconds, bool) or not isinstance(seconds, int | float) or seconds < 0:
        return "-"
    s = int(seconds)
    days, s = divmod(s, 86400)
    hours, s = divmod(s, 3600)
    minutes, s = divmod(s, 60)
    clock = f"{hours:02d}:{minutes:02d}:{s:02d}"
    return f"{days} d {clock}" if days else clock


def format_status(reply: dict[str, Any]) -> str:
    """The human-readable status block for a ``status`` reply (missing keys show ``-``).

    >>> print(format_status({"ok": True, "state": "running", "source": "v4l2:/dev/video0",
    ...     "tracker": "bright-blob", "sink": "uinput", "fps": 29.97, "latency_p50_ms": 1.234,
    ...     "latency_p99_ms": 3.5, "frames": 1200, "dropped_frames": 3, "events": 1197,
    ...     "camera_retries": 0, "uptime_s": 65}))
    state:           running
    source:          v4l2:/dev/video0
    tracker:         bright-blob
    sink:            uinput
    fps:             29.97
    latency:         p50 1.23 ms, p99 3.50 ms
    frames:          1200 (dropped 3)
    events:          1197
    camera retries:  0
    uptime:          00:01:05
    >>> print(format_status({"frames": 500, "dropped_frames": 0, "source_kind": "recorded"}))
    ... # doctest: +ELLIPSIS
    state:...
    frames:          500 (dropped 0; a file: the reader waits for the tracker)
    ...
    """
    frames = _num(reply.get("frames"), "d")
    dropped = _num(reply.get("dropped_frames"), "d")
    policy = {
        "live": "; live: the oldest frame is dropped when the tracker is behind",
        "recorded": "; a file: the reader waits for the tracker",
    }.get(str(reply.get("source_kind")), "")
    rows = [
        ("state", str(reply.get("state", "-"))),
        ("source", str(reply.get("source", "-"))),
        ("tracker", str(reply.get("tracker", "-"))),
        ("sink", str(reply.get("sink", "-"))),
        ("fps", _num(reply.get("fps"), ".2f")),
        (
            "latency",
            f"p50 {_num(reply.get('latency_p50_ms'), '.2f', ' ms')}, "
            f"p99 {_num(reply.get('latency_p99_ms'), '.2f', ' ms')}",
        ),
        ("frames", f"{frames} (dropped {dropped}{policy})"),
        ("events", _num(reply.get("events"), "d")),
        ("camera retries", _num(reply.get("camera_retries"), "d")),
        ("uptime", format_duration(reply.get("uptime_s"))),
    ]
    return "\n".join(f"{name + ':':<16} {value}" for name, value in rows)
