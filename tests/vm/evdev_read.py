"""Reading a device back through python-evdev, for the in-VM tests.

A *frame* is the list of ``(type, code, value)`` events between two SYN_REPORTs
(the SYN_REPORT itself not included).
"""

from __future__ import annotations

import fcntl
import os
import select
import struct
import time
from typing import Any

import evdev
from evdev import ecodes

Event = tuple[int, int, int]

# _IOW('E', 0xa0, int): which clock stamps this reader's events.
EVIOCSCLOCKID = (1 << 30) | (4 << 16) | (ord("E") << 8) | 0xA0


def open_reader(node: str, *, timeout_s: float = 10.0) -> Any:
    """An evdev reader of ``node``, waiting for the node to appear (devtmpfs/udev)."""
    deadline = time.monotonic() + timeout_s
    while not os.path.exists(node):
        if time.monotonic() > deadline:
            raise AssertionError(f"{node} did not appear within {timeout_s} s")
        time.sleep(0.02)
    return evdev.InputDevice(node)


def use_monotonic_clock(dev: Any) -> None:
    """Stamp this reader's events with CLOCK_MONOTONIC (``time.monotonic_ns``'s clock)."""
    fcntl.ioctl(dev.fd, EVIOCSCLOCKID, struct.pack("i", time.CLOCK_MONOTONIC))


def read_frames_timed(
    dev: Any, count: int, *, timeout_s: float = 10.0
) -> list[tuple[list[Event], int]]:
    """The next ``count`` frames with the SYN_REPORT's kernel timestamp (ns)."""
    frames: list[tuple[list[Event], int]] = []
    current: list[Event] = []
    deadline = time.monotonic() + timeout_s
    while len(frames) < count:
        ready, _, _ = select.select([dev.fd], [], [], max(deadline - time.monotonic(), 0.0))
        if not ready:
            raise AssertionError(
                f"only {len(frames)} of {count} SYN_REPORT frames arrived within {timeout_s} s: "
                f"{[f for f, _ in frames]} (partial: {current})"
            )
        for ev in dev.read():
            if ev.type == ecodes.EV_SYN and ev.code == ecodes.SYN_REPORT:
                frames.append((current, ev.sec * 1_000_000_000 + ev.usec * 1000))
                current = []
            else:
                current.append((ev.type, ev.code, ev.value))
    return frames


def read_frames(dev: Any, count: int, *, timeout_s: float = 10.0) -> list[list[Event]]:
    """The next ``count`` frames."""
    return [f for f, _ in read_frames_timed(dev, count, timeout_s=timeout_s)]


def pending_frames(dev: Any, *, wait_s: float = 0.3) -> list[list[Event]]:
    """Whatever complete frames are queued (to check nothing extra was emitted)."""
    frames: list[list[Event]] = []
    current: list[Event] = []
    while select.select([dev.fd], [], [], wait_s)[0]:
        try:
            events = list(dev.read())
        except OSError:  # the device went away
            break
        for ev in events:
            if ev.type == ecodes.EV_SYN and ev.code == ecodes.SYN_REPORT:
                frames.append(current)
                current = []
            else:
                current.append((ev.type, ev.code, ev.value))
    return frames
