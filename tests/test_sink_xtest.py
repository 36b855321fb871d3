"""The xtest sink against a real X server (Xvfb), read back by other X clients.

Truth: ``xdotool getmouselocation`` for the pointer's root pixel, the core
pointer's QueryPointer button mask from a second connection, and the events the
server delivers to the root window. Expected pixels are written out from the
mapping's definition: normalized (nx, ny) on a target screen WxH+X+Y lands on
root pixel (X + nx (W - 1), Y + ny (H - 1)), rounded half to even, nx and ny
clamped to [0, 1] and NaN taken as 0.5.
"""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from omnidev.errors import SinkError
from omnidev.screen import ScreenMapping, ScreenRect
from omnidev.sinks.xtest_sink import XtestSink, layout_from_display, open_xtest
from tests.xserver import (
    PointerListener,
    buttons_down,
    missing_x_tools,
    xdotool_location,
    xdotool_release_all,
    xvfb,
)

MISSING = missing_x_tools()
pytestmark = [pytest.mark.xserver, pytest.mark.skipif(MISSING is not None, reason=str(MISSING))]

SINGLE = ScreenMapping.single(1920, 1080)
RIGHT_OF_TWO = ScreenMapping(ScreenRect.parse("1920x1080+1920+0"), 3840, 1080)


@pytest.fixture(scope="module")
def single() -> Iterator[str]:
    """An X server with one 1920x1080 screen."""
    with xvfb(1920, 1080) as display:
        yield display


@pytest.fixture(scope="module")
def wide() -> Iterator[str]:
    """One 3840x1080 root window: two 1920x1080 monitors side by side."""
    with xvfb(3840, 1080) as display:
        yield display


# (normalized position, expected root pixel)
SINGLE_CASES = [
    ((0.0, 0.0), (0, 0)),
    ((1.0, 0.0), (1919, 0)),
    ((0.0, 1.0), (0, 1079)),
    ((1.0, 1.0), (1919, 1079)),
    ((0.5, 0.5), (960, 540)),  # 959.5, 539.5 rounded half to even
    ((0.1, 0.9), (192, 971)),  # 191.9, 971.1
    ((-0.2, 1.3), (0, 1079)),  # clamped
    ((7.0, -3.0), (1919, 0)),  # clamped
    ((math.nan, 0.25), (960, 270)),  # NaN -> 0.5; 269.75
]
RIGHT_CASES = [
    ((0.0, 0.0), (1920, 0)),
    ((1.0, 0.0), (3839, 0)),
    ((0.0, 1.0), (1920, 1079)),
    ((1.0, 1.0), (3839, 1079)),
    ((0.5, 0.5), (2880, 540)),  # 1920 + 959.5, 539.5
    ((0.25, 0.75), (2400, 809)),  # 1920 + 479.75, 809.25
    ((-1.0, 0.5), (1920, 540)),  # clamped to the right monitor's left edge
    ((2.0, -0.5), (3839, 0)),  # clamped
]


@pytest.mark.parametrize(("pos", "pixel"), SINGLE_CASES)
def test_moves_land_on_expected_pixel_single_screen(single, pos, pixel):
    with open_xtest({"display": single}, SINGLE) as sink:
        sink.move(0.3, 0.3)  # start elsewhere so a stale position cannot pass
        sink.move(*pos)
        assert xdotool_location(single) == (*pixel, 0)


@pytest.mark.parametrize(("pos", "pixel"), RIGHT_CASES)
def test_moves_land_on_right_monitor_of_layout(wide, pos, pixel):
    with open_xtest({"display": wide}, RIGHT_OF_TWO) as sink:
        sink.move(0.3, 0.3)
        sink.move(*pos)
        assert xdotool_location(wide) == (*pixel, 0)


def test_every_move_reaches_the_server_in_order(wide):
    """The root window sees one MotionNotify per move, at the expected pixels."""
    with PointerListener(wide) as listener, open_xtest({"display": wide}, RIGHT_OF_TWO) as sink:
        listener.events()
        for pos, _ in RIGHT_CASES[:6]:
            sink.move(*pos)
        assert listener.events() == [("move", *pixel) for _, pixel in RIGHT_CASES[:6]]


def test_layout_from_display_reads_root_size(single, wide):
    assert layout_from_display(single) == (1920, 1080)
    assert layout_from_display(wide) == (3840, 1080)


def test_default_display_from_environment(single, monkeypatch):
    monkeypatch.setenv("DISPLAY", single)
    assert layout_from_display() == (1920, 1080)
    sink = open_xtest({}, SINGLE)
    assert sink.display_name == single
    assert sink.stats()["root"] == [1920, 1080]
    with sink:
        sink.move(1.0, 1.0)
    assert xdotool_location(single)[:2] == (1919, 1079)


def test_screen_option_moves_on_that_x_screen():
    with xvfb(1920, 1080, more_screens=[(800, 600)]) as display:
        assert layout_from_display(display, screen=1) == (800, 600)
        assert xdotool_location(display)[2] == 0  # the pointer starts on screen 0
        with open_xtest({"display": display, "screen": 1}, ScreenMapping.single(800, 600)) as sink:
            sink.move(1.0, 0.5)  # 799, 299.5 -> 300
            assert xdotool_location(display) == (799, 300, 1)
            sink.move(0.0, 1.0)
            assert xdotool_location(display) == (0, 599, 1)
        with pytest.raises(SinkError, match=r"has screens 0\.\.1, not screen 2"):
            open_xtest({"display": display, "screen": 2}, ScreenMapping.single(800, 600))


def test_buttons_seen_in_server_mask(single):
    with PointerListener(single) as listener:
        sink = open_xtest({"display": single}, SINGLE)
        sink.move(0.5, 0.5)
        listener.events()
        sink.press("left")
        assert buttons_down(single) == {"left"}
        sink.press("right")
        assert buttons_down(single) == {"left", "right"}
        sink.press("middle")
        assert buttons_down(single) == {"left", "right", "middle"}
        sink.release("right")
        assert buttons_down(single) == {"left", "middle"}
        sink.close()
        assert buttons_down(single) == set()
        assert listener.events() == [
            ("press", "left"),
            ("press", "right"),
            ("press", "middle"),
            ("release", "right"),
            ("release", "left"),  # close releases what is down, in name order
            ("release", "middle"),
        ]


def test_click_is_press_then_release(single):
    with PointerListener(single) as listener, open_xtest({"display": single}, SINGLE) as sink:
        sink.move(0.0, 0.0)
        listener.events()
        sink.click("right")
        assert listener.events() == [("press", "right"), ("release", "right")]
        assert buttons_down(single) == set()


HOLDER = """
import sys, time
from omnidev.screen import ScreenMapping
from omnidev.sinks import release_on_signals
from omnidev.sinks.xtest_sink import open_xtest

sink = open_xtest({"display": sys.argv[1]}, ScreenMapping.single(1920, 1080))
with release_on_signals(sink):
    sink.move(0.5, 0.5)
    sink.press("left")
    sink.press("right")
    print("held", flush=True)
    time.sleep(60)
"""


def _holder(display: str) -> subprocess.Popen[str]:
    """A process holding left+right down through its own xtest sink."""
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLDER, display],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=Path(__file__).resolve().parents[1],
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if line.strip() != "held":
        proc.kill()
        raise AssertionError(f"holder did not start: {line!r} {proc.stderr.read()}")  # type: ignore[union-attr]
    return proc


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_stuck_buttons_released_on_signal(single, signum):
    proc = _holder(single)
    try:
        assert buttons_down(single) == {"left", "right"}
        proc.send_signal(signum)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    # SIGTERM: SystemExit(128 + 15); SIGINT: KeyboardInterrupt, which Python ends
    # by re-raising SIGINT on itself.
    assert proc.returncode == (128 + signum if signum == signal.SIGTERM else -signum)
    assert buttons_down(single) == set()


def test_sigkill_leaves_buttons_stuck_in_the_server(single):
    """Control: the X server keeps XTest buttons down when the client dies without
    releasing, so the signal test above would see a sink that forgot to release."""
    proc = _holder(single)
    try:
        proc.kill()
        proc.wait(10)
        assert buttons_down(single) == {"left", "right"}
    finally:
        xdotool_release_all(single)
    assert buttons_down(single) == set()


def test_buttons_a_killed_sink_left_down_are_released_when_the_next_opens(single):
    proc = _holder(single)
    proc.kill()
    proc.wait(10)
    try:
        assert buttons_down(single) == {"left", "right"}  # as the control test above
        sink = XtestSink(SINGLE, display=single)
        try:
            assert buttons_down(single) == set()
            assert sink.stats()["released_at_start"] == ["left", "right"]
        finally:
            sink.close()
        sink = XtestSink(SINGLE, display=single)  # nothing down: nothing released
        sink.close()
        assert sink.stats()["released_at_start"] == []
    finally:
        xdotool_release_all(single)


def test_cannot_open_display_names_it():
    unused = next(n for n in range(4242, 4342) if not Path(f"/tmp/.X11-unix/X{n}").exists())
    with pytest.raises(SinkError) as info:
        open_xtest({"display": f":{unused}"}, SINGLE)
    msg = str(info.value)
    assert f"':{unused}'" in msg and "DISPLAY" in msg and "xauth" in msg.lower()
    assert "\n" not in msg


def test_no_display_at_all(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(SinkError, match="no X display: set option 'display'"):
        open_xtest({}, SINGLE)


def test_server_without_xtest_is_a_clear_error():
    with xvfb(640, 480, args=["-tst"]) as display:
        with pytest.raises(SinkError, match="has no XTEST extension"):
            open_xtest({"display": display}, ScreenMapping.single(640, 480))


def test_target_screen_outside_root_window(single):
    with pytest.raises(SinkError, match=r"1920x1080\+1920\+0 lies outside the 1920x1080 root"):
        open_xtest({"display": single}, RIGHT_OF_TWO)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"display": ":0", "device": "x"}, "unknown option 'device'"),
        ({"display": 0}, "option 'display' must be a display name"),
        ({"display": ":0", "screen": -1}, "option 'screen' must be a screen number"),
        ({"display": ":0", "screen": "1"}, "option 'screen' must be a screen number"),
    ],
)
def test_bad_options(options, message):
    with pytest.raises(SinkError, match=message):
        open_xtest(options, SINGLE)


def test_lost_server_is_a_sink_error():
    with xvfb(640, 480) as display:
        sink = XtestSink(ScreenMapping.single(640, 480), display=display)
        sink.move(0.5, 0.5)
    with pytest.raises(SinkError, match="xtest sink: .*lost|failed"):
        sink.move(0.1, 0.1)
    sink.close()  # still safe after the server is gone
    assert sink.closed


def test_cost_per_event(single):
    """Measured and printed (not asserted): wall time of move() including its XSync."""
    n = 3000
    with open_xtest({"display": single}, SINGLE) as sink:
        sink.move(0.0, 0.0)
        t0 = time.perf_counter_ns()
        for i in range(n):
            sink.move(i / n, 1.0 - i / n)
        moves_us = (time.perf_counter_ns() - t0) / n / 1e3
        t0 = time.perf_counter_ns()
        for _ in range(n // 2):
            sink.press("left")
            sink.release("left")
        buttons_us = (time.perf_counter_ns() - t0) / n / 1e3
    assert xdotool_location(single)[:2] == (1918, 0)  # last move (2999/3000, 1/3000): 1918.36, 0.36
    print(f"\nxtest sink: {moves_us:.1f} us per move, {buttons_us:.1f} us per button event")


def test_missing_python_xlib_says_what_to_install(monkeypatch):
    """The module imports without python-xlib; opening the sink then names the package."""
    monkeypatch.setitem(sys.modules, "Xlib", None)  # import Xlib now raises ImportError
    with pytest.raises(SinkError, match=r"python-xlib is not installed \(pip install"):
        open_xtest({"display": ":0"}, SINGLE)
    with pytest.raises(SinkError, match="python-xlib is not installed"):
        layout_from_display(":0")
