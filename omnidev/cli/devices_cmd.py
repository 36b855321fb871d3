"""``omnidev devices``: V4L2 capture nodes with card name and USB vendor:product:serial."""

from __future__ import annotations

import argparse
from typing import Any

from omnidev.devices import list_video_devices


def register(sub: Any) -> None:
    p = sub.add_parser("devices", help="list V4L2 cameras")
    p.add_argument("--sysfs", default="/sys", help=argparse.SUPPRESS)
    p.add_argument("--dev", default="/dev", help=argparse.SUPPRESS)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    devices = list_video_devices(args.sysfs, args.dev)
    if not devices:
        print(
            "no V4L2 capture devices found (no /dev/video* nodes; is the camera plugged in "
            "and its driver loaded?)"
        )
        return 0
    print(f"{'node':<14} {'capture':<8} {'usb id':<28} card")
    for d in devices:
        note = "" if d.readable else "  (not readable: add the user to group 'video')"
        if not d.node_exists:
            note = "  (no /dev node)"
        print(
            f"{d.node:<14} {'yes' if d.capture else 'no':<8} {d.usb_id or '-':<28} {d.card}{note}"
        )
    return 0
