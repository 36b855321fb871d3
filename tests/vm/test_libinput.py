"""libinput, the input stack under Wayland compositors and Xorg, as the uinput sink's client.

Runs inside the VM (udev running). ``libinput debug-events`` prints absolute
motion transformed to a 100 x 100 "screen"
(``libinput_event_pointer_get_absolute_x_transformed(event, 100)``), i.e. the
percentage (value - min) * 100 / (max - min + 1) of the device's range, to two
decimals; the expected percentages below come from the device values of
tests/vm/test_uinput.py's hand-computed truth.
"""

from __future__ import annotations

import queue
import re
import subprocess
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from omnidev.screen import ScreenMapping
from omnidev.sinks.uinput_sink import open_uinput

SINGLE = ScreenMapping.single(1920, 1080)
# (nx, ny) -> device value (see test_uinput.py) -> percent = value * 100 / 32768
MOVES = [
    ((0.25, 0.75), (8192, 24575)),
    ((0.5, 0.5), (16384, 16384)),
    ((0.1, 0.9), (3277, 29490)),
    ((1.0, 0.0), (32767, 0)),
]
MOTION = re.compile(r"POINTER_MOTION_ABSOLUTE\s+\+?[\d.]+s\s+(-?[\d.]+)\s*/\s*(-?[\d.]+)")
BUTTON = re.compile(r"POINTER_BUTTON\s+\+?[\d.]+s\s+(BTN_\w+) \(\d+\) (pressed|released)")
ADDED = re.compile(r"DEVICE_ADDED\s+(.*?)\s+seat\S*\s.*\bcap:(\S*)")


def udev_properties(node: str) -> dict[str, str]:
    subprocess.run(["udevadm", "settle", "--timeout=60"], check=True)
    out = subprocess.run(
        ["udevadm", "info", "--query=property", f"--name={node}"],
        capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    return dict(line.split("=", 1) for line in out.splitlines() if "=" in line)


class DebugEvents:
    """``libinput debug-events --device NODE``, its output lines in a queue."""

    def __init__(self, node: str) -> None:
        self.proc = subprocess.Popen(
            ["stdbuf", "-oL", "libinput", "debug-events", "--device", node],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1,
        )  # fmt: skip
        self.lines: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put(line.rstrip("\n"))

    def wait_for(self, pattern: re.Pattern[str], timeout_s: float = 30.0) -> re.Match[str]:
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                line = self.lines.get(timeout=max(deadline - time.monotonic(), 0.01))
            except queue.Empty:
                raise AssertionError(
                    f"libinput printed no {pattern.pattern!r} within {timeout_s} s; "
                    f"its output so far:\n" + "\n".join(self.seen[-30:])
                ) from None
            self.seen.append(line)
            m = pattern.search(line)
            if m:
                return m

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


@pytest.fixture
def sink_and_libinput() -> Iterator[tuple[Any, DebugEvents]]:
    sink = open_uinput({"phys": "omnidev/libinput-test"}, SINGLE)
    assert sink.event_node is not None
    udev_properties(sink.event_node)  # udev has tagged it before libinput looks
    li = DebugEvents(sink.event_node)
    try:
        yield sink, li
    finally:
        li.stop()
        sink.close()


def test_udev_tags_it_a_mouse_not_a_tablet_or_touchscreen() -> None:
    with open_uinput({"phys": "omnidev/udev-test"}, SINGLE) as sink:
        assert sink.event_node is not None
        props = udev_properties(sink.event_node)
    assert props.get("ID_INPUT") == "1"
    assert props.get("ID_INPUT_MOUSE") == "1", props
    for key in ("ID_INPUT_TABLET", "ID_INPUT_TOUCHSCREEN", "ID_INPUT_TOUCHPAD",
                "ID_INPUT_JOYSTICK", "ID_INPUT_KEYBOARD"):  # fmt: skip
        assert key not in props, f"{key}={props.get(key)}"


def test_libinput_sees_an_absolute_pointer(sink_and_libinput: Any) -> None:
    sink, li = sink_and_libinput
    added = li.wait_for(ADDED)
    assert added.group(1).strip() == "omnidev absolute pointer"
    assert added.group(2) == "p", f"capabilities {added.group(2)!r}: want pointer only"
    for (nx, ny), (vx, vy) in MOVES:
        sink.move(nx, ny)
        m = li.wait_for(MOTION)
        got = float(m.group(1)), float(m.group(2))
        want = vx * 100 / 32768, vy * 100 / 32768
        assert got == pytest.approx(want, abs=0.0051), f"move({nx}, {ny}): {m.group(0)}"
    sink.press("left")
    assert li.wait_for(BUTTON).groups() == ("BTN_LEFT", "pressed")
    sink.release("left")
    assert li.wait_for(BUTTON).groups() == ("BTN_LEFT", "released")
    sink.click("right")
    assert li.wait_for(BUTTON).groups() == ("BTN_RIGHT", "pressed")
    assert li.wait_for(BUTTON).groups() == ("BTN_RIGHT", "released")
