"""The uinput sink on a real kernel, read back through python-evdev (runs inside the VM).

Truth: a normalized position n on a target screen at layout x0 with width w maps
to the layout pixel x0 + n * (w - 1), and the device value is
round(pixel * 32767 / (layout width - 1)) (omnidev.screen). The expected values
below were computed by hand from that formula, not by calling the code under test.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import pytest
from evdev import ecodes
from evdev_read import (
    open_reader,
    pending_frames,
    read_frames,
    read_frames_timed,
    use_monotonic_clock,
)

from omnidev.errors import SinkError
from omnidev.evdev_find import device_info, find_event_nodes
from omnidev.frame import PointerSample
from omnidev.screen import ScreenMapping, ScreenRect
from omnidev.sinks.uinput_sink import DEFAULT_NAME, DEFAULT_PHYS, UinputSink, open_uinput

REPO = Path(__file__).resolve().parents[2]
EV_ABS, EV_KEY = ecodes.EV_ABS, ecodes.EV_KEY
ABS_X, ABS_Y = ecodes.ABS_X, ecodes.ABS_Y
BTN = {"left": ecodes.BTN_LEFT, "right": ecodes.BTN_RIGHT, "middle": ecodes.BTN_MIDDLE}

SINGLE = ScreenMapping.single(1920, 1080)
# The right monitor of two 1920x1080 monitors side by side.
RIGHT_OF_TWO = ScreenMapping(ScreenRect(1920, 0, 1920, 1080), 3840, 1080)

# (nx, ny) -> (ABS_X, ABS_Y) on SINGLE: round(n * 1919 * 32767 / 1919), ties to even.
SINGLE_CASES = [
    ((0.5, 0.5), (16384, 16384)),  # 16383.5 -> 16384
    ((0.0, 0.0), (0, 0)),
    ((1.0, 1.0), (32767, 32767)),
    ((0.25, 0.75), (8192, 24575)),  # 8191.75, 24575.25
    ((0.1, 0.9), (3277, 29490)),  # 3276.7, 29490.3
    ((1.7, -3.0), (32767, 0)),  # out of range: clamped to (1, 0)
    ((-0.2, 2.0), (0, 32767)),  # clamped to (0, 1)
    ((float("nan"), 0.5), (16384, 16384)),  # NaN: the middle, not a corner
]
# On RIGHT_OF_TWO: x pixel 1920 + nx * 1919, value round(px * 32767 / 3839).
RIGHT_CASES = [
    ((0.0, 0.0), (16388, 0)),  # 1920 * 32767 / 3839 = 16387.77
    ((1.0, 1.0), (32767, 32767)),  # 3839 -> 32767
    ((0.5, 0.5), (24577, 16384)),  # 2879.5 -> 24577.38
    ((-1.0, 0.25), (16388, 8192)),  # clamped to the right monitor's left edge
]


@pytest.fixture
def sink() -> Any:
    s = open_uinput({}, SINGLE)
    yield s
    s.close()


def expected_frame(prev: tuple[int, int], new: tuple[int, int]) -> list[tuple[int, int, int]]:
    """The kernel passes only axes whose value changed."""
    frame = []
    if new[0] != prev[0]:
        frame.append((EV_ABS, ABS_X, new[0]))
    if new[1] != prev[1]:
        frame.append((EV_ABS, ABS_Y, new[1]))
    return frame


def check_moves(sink: UinputSink, cases: list[Any]) -> None:
    dev = open_reader(sink.event_node or "")
    try:
        state = (0, 0)  # the axes start at value 0
        for (nx, ny), want in cases:
            sink.move(nx, ny)
            want_frame = expected_frame(state, want)
            if not want_frame:
                continue
            assert read_frames(dev, 1) == [want_frame], f"move({nx}, {ny})"
            state = want
        assert pending_frames(dev) == []
        assert dev.absinfo(ABS_X).value == state[0] and dev.absinfo(ABS_Y).value == state[1]
    finally:
        dev.close()


def test_device_properties(sink: UinputSink) -> None:
    assert sink.event_node is not None and sink.event_node.startswith("/dev/input/event")
    dev = open_reader(sink.event_node)
    try:
        assert dev.name == DEFAULT_NAME == "omnidev absolute pointer"
        assert dev.phys == DEFAULT_PHYS == "omnidev/pointer0"
        assert dev.info.bustype == 0x06  # BUS_VIRTUAL
        assert dev.input_props() == [ecodes.INPUT_PROP_DIRECT]
        caps = dev.capabilities(absinfo=True)
        assert set(caps) == {ecodes.EV_SYN, EV_KEY, EV_ABS}, "no EV_REL, no EV_MSC"
        assert sorted(caps[EV_KEY]) == [ecodes.BTN_LEFT, ecodes.BTN_RIGHT, ecodes.BTN_MIDDLE]
        axes = dict(caps[EV_ABS])
        assert sorted(axes) == [ABS_X, ABS_Y]
        for code in (ABS_X, ABS_Y):
            info = axes[code]
            assert (info.min, info.max, info.fuzz, info.flat) == (0, 32767, 0, 0)
            # Set by UI_ABS_SETUP and kept by python-uinput's legacy setup write.
            assert info.resolution == 100
    finally:
        dev.close()


def test_resolution_from_screen_size() -> None:
    # A 527 x 296 mm monitor: x 32767 * 1920 / (1919 * 527) = 62.2,
    # y 32767 * 1080 / (1079 * 296) = 110.8 (units/mm).
    with open_uinput({"screen_mm": "527x296", "phys": "omnidev/res-test"}, SINGLE) as s:
        dev = open_reader(s.event_node or "")
        assert (dev.absinfo(ABS_X).resolution, dev.absinfo(ABS_Y).resolution) == (62, 111)
        dev.close()


def test_find_own_device_in_sysfs(sink: UinputSink) -> None:
    assert sink.sysname is not None and sink.sysname.startswith("input")
    info = device_info(sink.sysname)
    assert info is not None and info.event_node == sink.event_node
    assert find_event_nodes(name=DEFAULT_NAME, phys=DEFAULT_PHYS) == [sink.event_node]


def test_exact_abs_values_single_screen(sink: UinputSink) -> None:
    check_moves(sink, SINGLE_CASES)


def test_exact_abs_values_right_monitor_of_two() -> None:
    with open_uinput({}, RIGHT_OF_TWO) as s:
        check_moves(s, RIGHT_CASES)


def test_buttons_down_up_each_in_its_own_report(sink: UinputSink) -> None:
    dev = open_reader(sink.event_node or "")
    try:
        for name, code in BTN.items():
            sink.press(name)
            assert read_frames(dev, 1) == [[(EV_KEY, code, 1)]], f"press {name}"
            assert dev.active_keys() == [code]
            sink.press(name)  # already down: nothing emitted
            sink.release(name)
            assert read_frames(dev, 1) == [[(EV_KEY, code, 0)]], f"release {name}"
            assert dev.active_keys() == []
        assert pending_frames(dev) == []
    finally:
        dev.close()


def test_sample_is_one_report_move_then_buttons(sink: UinputSink) -> None:
    dev = open_reader(sink.event_node or "")
    try:
        sink.emit(PointerSample(0.25, 0.75, 0, buttons=frozenset({"left", "middle"})))
        sink.emit(PointerSample(0.5, 0.5, 0, buttons=frozenset({"middle"})))
        sink.emit(PointerSample(0.5, 0.5, 0))
        assert read_frames(dev, 3) == [
            [(EV_ABS, ABS_X, 8192), (EV_ABS, ABS_Y, 24575), (EV_KEY, BTN["left"], 1),
             (EV_KEY, BTN["middle"], 1)],
            [(EV_ABS, ABS_X, 16384), (EV_ABS, ABS_Y, 16384), (EV_KEY, BTN["left"], 0)],
            [(EV_KEY, BTN["middle"], 0)],
        ]  # fmt: skip
        assert pending_frames(dev) == []
    finally:
        dev.close()


class Observed(UinputSink):
    """Reads the test's evdev reader just before the device is destroyed.

    Needed because a reader cannot read queued events once the device is gone
    (evdev returns ENODEV), and EVIOCGKEY (``active_keys``) drops queued key
    events, so frames are read first, then the key state.
    """

    reader: Any = None
    seen: dict[str, Any]

    def _close(self) -> None:
        self.seen = {"frames": pending_frames(self.reader), "keys": self.reader.active_keys()}
        super()._close()


def test_close_releases_buttons_before_the_device_goes() -> None:
    sink = Observed(SINGLE, phys="omnidev/close-test")
    sink.reader = reader = open_reader(sink.event_node or "")
    try:
        sink.press("right")
        sink.press("middle")
        sink.close()
        # Released by the sink in one report (sorted: middle, right), written
        # before UI_DEV_DESTROY.
        assert sink.seen["frames"] == [
            [(EV_KEY, BTN["right"], 1)],
            [(EV_KEY, BTN["middle"], 1)],
            [(EV_KEY, BTN["middle"], 0), (EV_KEY, BTN["right"], 0)],
        ]
        assert sink.seen["keys"] == []
        assert not os.path.exists(sink.event_node or "")
    finally:
        reader.close()


def test_exception_in_with_block_releases() -> None:
    sink = Observed(SINGLE, phys="omnidev/exc-test")
    sink.reader = reader = open_reader(sink.event_node or "")
    try:
        with pytest.raises(RuntimeError, match="tracker blew up"), sink:
            sink.press("left")
            sink.press("right")
            raise RuntimeError("tracker blew up")
        assert sink.seen["frames"] == [
            [(EV_KEY, BTN["left"], 1)],
            [(EV_KEY, BTN["right"], 1)],
            [(EV_KEY, BTN["left"], 0), (EV_KEY, BTN["right"], 0)],
        ]
        assert sink.seen["keys"] == []
        assert sink.closed and sink.pressed == set()
    finally:
        reader.close()


STUCK_CHILD = textwrap.dedent(
    """
    import sys, time
    from omnidev.screen import ScreenMapping
    from omnidev.sinks import release_on_signals
    from omnidev.sinks.uinput_sink import UinputSink

    class Observed(UinputSink):
        def _close(self):
            # Let the parent look at the device after the release, before it goes.
            print("closing", flush=True)
            sys.stdin.readline()
            super()._close()

    sink = Observed(ScreenMapping.single(1920, 1080), phys="omnidev/stuck-test")
    with release_on_signals(sink):
        sink.press("left")
        sink.press("right")
        print("pressed", sink.event_node, flush=True)
        while True:
            time.sleep(1)
    """
)


def test_sigterm_releases_stuck_buttons() -> None:
    child = subprocess.Popen(
        [sys.executable, "-c", STUCK_CHILD],
        cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert child.stdout is not None and child.stdin is not None
        word, node = child.stdout.readline().split()
        assert word == "pressed"
        dev = open_reader(node)
        try:
            assert sorted(dev.active_keys()) == [BTN["left"], BTN["right"]]
            child.send_signal(15)  # SIGTERM
            assert child.stdout.readline().strip() == "closing"
            # Frames first: EVIOCGKEY (active_keys) drops queued key events.
            assert read_frames(dev, 1) == [[(EV_KEY, BTN["left"], 0), (EV_KEY, BTN["right"], 0)]]
            assert dev.active_keys() == [], "buttons still down while the device exists"
            child.stdin.write("\n")
            child.stdin.flush()
            assert child.wait(timeout=60) == 128 + 15
            assert find_event_nodes(phys="omnidev/stuck-test") == []  # the device is gone
        finally:
            dev.close()
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()


def test_missing_node_error() -> None:
    with pytest.raises(SinkError) as err:
        open_uinput({"device": "/nonexistent"}, SINGLE)
    assert str(err.value) == (
        "uinput sink: /nonexistent missing: load the module (modprobe uinput; "
        "udev/modules-load.d/omnidev.conf loads it at boot)"
    )


def test_unwritable_node_error() -> None:
    """Opened by an unprivileged user (uid/gid 65534, no groups) in a forked child.

    Forked rather than spawned: the virtualenv's interpreter may live under /root,
    which that user cannot execute.
    """
    st = os.stat("/dev/uinput")
    assert not st.st_mode & 0o002, "/dev/uinput is world-writable here; the test needs it not"
    import uinput  # noqa: F401  (imported before dropping privileges)

    rfd, wfd = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: drop root, try, report through the pipe, exit
        try:
            os.setgroups([])
            os.setgid(65534)
            os.setuid(65534)
            try:
                open_uinput({}, SINGLE).close()
                msg = "opened"
            except SinkError as exc:
                msg = str(exc)
            os.write(wfd, msg.encode())
        finally:
            os._exit(0)
    os.close(wfd)
    with os.fdopen(rfd, "rb") as fh:
        msg = fh.read().decode()
    os.waitpid(pid, 0)
    assert msg == (
        "uinput sink: /dev/uinput not writable: install udev/60-omnidev.rules "
        "(GROUP=input, MODE=0660) and add the user to group input "
        "(sudo usermod -aG input $USER, then log in again)"
    )


def test_unknown_option_error() -> None:
    with pytest.raises(SinkError, match="unknown option 'colour'"):
        open_uinput({"colour": "red"}, SINGLE)


def test_sink_to_kernel_timestamp(sink: UinputSink, vm_figures: dict[str, Any]) -> None:
    """Time from just before move() to the kernel's event timestamp (figure, not asserted)."""
    dev = open_reader(sink.event_node or "")
    try:
        use_monotonic_clock(dev)
        lat_us = []
        for i in range(200):
            nx = (i % 50 + 1) / 52  # a new x every move (unchanged values are not passed)
            t0 = time.monotonic_ns()
            sink.move(nx, 1 - nx)
            [(frame, t_kernel)] = read_frames_timed(dev, 1)
            assert frame and frame[0][:2] == (EV_ABS, ABS_X)
            lat_us.append((t_kernel - t0) / 1000)
        assert min(lat_us) >= -1  # the kernel stamp comes after t0 (to the µs it reports)
        q = statistics.quantiles(lat_us, n=100)
        vm_figures["vm_sink_to_kernel_p50_us"] = round(statistics.median(lat_us), 1)
        vm_figures["vm_sink_to_kernel_p99_us"] = round(q[98], 1)
        vm_figures["vm_sink_to_kernel_samples"] = len(lat_us)
    finally:
        dev.close()
