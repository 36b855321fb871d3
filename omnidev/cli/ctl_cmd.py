"""``omnidev ctl``: talk to a running omnidevd through its control socket.

    omnidev ctl status [--socket PATH] [--json]
    omnidev ctl pause | resume | reload [--socket PATH] [--json]
    omnidev ctl view NAME pan=DEG tilt=DEG fov=DEG [--socket PATH] [--json]

``status`` prints the daemon's state, source, tracker, sink, frame rate (frames
per second), latency from frame capture to the sink (p50/p99, milliseconds),
frame and drop counts, camera retries and uptime, then each video stream's
state, fps, drops and latency (capture -> output, p50/p99) and its views.
``view`` steers a running perspective view: ``pan=30`` is absolute,
``pan=+10``/``pan=-10`` relative (``pan==-30``: absolute -30); the view moves
there at its ``max_deg_s``. ``--json`` prints the reply
object as received. A refused command or an unreachable daemon is a one-line
error (exit status 2).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from omnidev.daemon.control import COMMANDS, DEFAULT_SOCKET, ControlError, request
from omnidev.ptz import parse_moves


def register(sub: Any) -> None:
    p = sub.add_parser(
        "ctl",
        help="control a running omnidevd (status, pause, resume, reload, view)",
        description="Send a command to omnidevd's control socket and print its reply.",
    )
    p.add_argument("action", choices=COMMANDS, help="command to send")
    p.add_argument(
        "words",
        nargs="*",
        metavar="ARG",
        help="for view: the view's name, then pan=DEG tilt=DEG fov=DEG (+/-: relative)",
    )
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
    extra: dict[str, Any] = {}
    if args.action == "view":
        if len(args.words) < 2:
            raise ControlError("ctl view NAME pan=DEG [tilt=DEG] [fov=DEG]: give a view and a move")
        parse_moves(args.words[1:])  # a malformed move fails here, before the daemon
        extra = {"view": args.words[0], "moves": args.words[1:]}
    elif args.words:
        raise ControlError(f"ctl {args.action} takes no arguments, got {' '.join(args.words)}")
    reply = request(args.socket, args.action, timeout=args.timeout, **extra)
    if not reply.get("ok"):
        raise ControlError(f"omnidevd refused {args.action!r}: {reply.get('error', 'no reason')}")
    if args.json:
        print(json.dumps(reply, sort_keys=True))
    elif args.action == "status":
        if "pointer" in reply and reply["pointer"] is None:  # a streams-only configuration
            print(f"{'state:':<16} {reply.get('state', '-')}\n{'pointer:':<16} none (streams only)")
        else:
            print(format_status(reply))
        for stream in reply.get("streams") or []:
            print(format_stream(stream))
    elif args.action == "view":
        t = reply.get("target") or {}
        print(
            f"omnidevd: view {reply.get('view')} -> pan {_num(t.get('pan'), '.2f')}, "
            f"tilt {_num(t.get('tilt'), '.2f')}, fov {_num(t.get('fov'), '.2f')}"
        )
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


def format_stream(st: dict[str, Any]) -> str:
    """The status block of one video stream (missing keys show ``-``).

    >>> print(format_stream({"name": "room", "state": "running", "source": "v4l2:/dev/video2",
    ...     "fps": 30.0, "latency_p50_ms": 12.0, "latency_p99_ms": 20.5, "frames": 900,
    ...     "written": 898, "dropped_frames": 2, "camera_retries": 0, "views": [{"name": "ptz",
    ...     "view": "perspective:640x480,fov=70", "outputs": ["v4l2:/dev/video10"],
    ...     "pose": {"pan": 10.0, "tilt": 0.0, "fov": 70.0}}]}))  # doctest: +NORMALIZE_WHITESPACE
    stream room:     running, v4l2:/dev/video2
      fps:           30.00
      latency:       p50 12.00 ms, p99 20.50 ms (capture -> output)
      frames:        900 (written 898, dropped 2)
      camera retries: 0
      view ptz:      perspective:640x480,fov=70 -> v4l2:/dev/video10
        (pan 10.00, tilt 0.00, fov 70.00)
    """
    rows = [
        f"{'stream ' + str(st.get('name', '-')) + ':':<16} {st.get('state', '-')}, "
        f"{st.get('source', '-')}",
        f"  {'fps:':<14} {_num(st.get('fps'), '.2f')}",
        f"  {'latency:':<14} p50 {_num(st.get('latency_p50_ms'), '.2f', ' ms')}, "
        f"p99 {_num(st.get('latency_p99_ms'), '.2f', ' ms')} (capture -> output)",
        f"  {'frames:':<14} {_num(st.get('frames'), 'd')} (written "
        f"{_num(st.get('written'), 'd')}, dropped {_num(st.get('dropped_frames'), 'd')})",
        f"  camera retries: {_num(st.get('camera_retries'), 'd')}",
    ]
    if st.get("error"):
        rows.append(f"  {'error:':<14} {st['error']}")
    for v in st.get("views") or []:
        line = f"  {'view ' + str(v.get('name', '-')) + ':':<14} {v.get('view', '-')} -> "
        line += ", ".join(str(o) for o in v.get("outputs") or [])
        pose = v.get("pose")
        if isinstance(pose, dict):
            line += (
                f" (pan {_num(pose.get('pan'), '.2f')}, tilt {_num(pose.get('tilt'), '.2f')}, "
                f"fov {_num(pose.get('fov'), '.2f')})"
            )
        rows.append(line)
    return "\n".join(rows)
