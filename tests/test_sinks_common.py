"""What every pointer sink does the same way (omnidev.sinks.base), through two real sinks.

Each test runs on the ``record`` sink (read back from its JSON lines) and on the
``xtest`` sink (read back from a real Xvfb by another X client: the events the
server delivers to the root window, the core pointer's button mask, and
``xdotool getmouselocation``). Expected pixels follow the mapping's definition
for one 1920x1080 screen: normalized (nx, ny) -> (nx * 1919, ny * 1079), rounded
half to even, with nx, ny clamped to [0, 1] and NaN taken as 0.5.
"""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from omnidev.errors import SinkError
from omnidev.frame import PointerSample
from omnidev.screen import ScreenMapping
from omnidev.sinks import PointerSink
from omnidev.sinks.record import open_record, read_events, replay
from omnidev.sinks.xtest_sink import open_xtest
from tests.xserver import (
    PointerListener,
    buttons_down,
    missing_x_tools,
    xdotool_location,
    xvfb,
)

MAPPING = ScreenMapping.single(1920, 1080)
MISSING_X = missing_x_tools()
XTEST = pytest.param(
    "xtest",
    marks=[pytest.mark.xserver, pytest.mark.skipif(MISSING_X is not None, reason=str(MISSING_X))],
)
Event = tuple[object, ...]  # ("move", px, py) | ("press" | "release", button)


@dataclass
class SinkCase:
    """One sink under test and the independent way of reading back what it did."""

    name: str
    options: dict[str, object]
    open: Callable[[], PointerSink]
    events: Callable[[], list[Event]]  # what reached the output since the last call
    pressed: Callable[[], set[str]]  # buttons the output holds down now
    pixel: Callable[[], tuple[int, int]]  # where the output's pointer is now


@pytest.fixture(scope="module")
def x_display() -> Iterator[str]:
    with xvfb(1920, 1080) as display:
        yield display


def _record_case(path: Path) -> SinkCase:
    seen = [0]

    def all_events() -> list[Event]:
        out: list[Event] = []
        if path.exists():
            for e in read_events(path):
                if e["kind"] == "move":
                    out.append(("move", *e["pixel"]))
                elif e["kind"] == "button":
                    out.append(("press" if e["down"] else "release", e["button"]))
        return out

    def events() -> list[Event]:
        every = all_events()
        new, seen[0] = every[seen[0] :], len(every)
        return new

    def pressed() -> set[str]:
        down: set[str] = set()
        for kind, *rest in all_events():
            if kind == "press":
                down.add(str(rest[0]))
            elif kind == "release":
                down.discard(str(rest[0]))
        return down

    def pixel() -> tuple[int, int]:
        moves = [e for e in all_events() if e[0] == "move"]
        return int(moves[-1][1]), int(moves[-1][2])  # type: ignore[call-overload]

    options: dict[str, object] = {"path": str(path)}
    return SinkCase(
        "record", options, lambda: open_record(options, MAPPING), events, pressed, pixel
    )


@pytest.fixture(params=["record", XTEST])
def case(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[SinkCase]:
    if request.param == "record":
        yield _record_case(tmp_path / "events.jsonl")
        return
    display = request.getfixturevalue("x_display")
    with PointerListener(display) as listener:
        options: dict[str, object] = {"display": display}
        yield SinkCase(
            "xtest",
            options,
            lambda: open_xtest(options, MAPPING),
            listener.events,
            lambda: buttons_down(display),
            lambda: xdotool_location(display)[:2],
        )
    assert buttons_down(display) == set(), "a test left a button down on the shared server"


def test_out_of_range_positions_are_clamped(case):
    with case.open() as sink:
        case.events()
        sink.move(-0.5, 1.5)
        assert case.pixel() == (0, 1079)
        assert sink.last_position == (0.0, 1.0)
        sink.move(3.0, -2.0)
        sink.move(0.25, 2.0)  # 479.75 -> 480
        assert case.events() == [("move", 0, 1079), ("move", 1919, 0), ("move", 480, 1079)]
        assert case.pixel() == (480, 1079)


def test_nan_goes_to_the_middle_and_infinity_to_the_edge(case):
    with case.open() as sink:
        sink.move(0.0, 0.0)
        case.events()
        sink.move(math.nan, math.nan)  # 959.5 -> 960, 539.5 -> 540
        assert sink.last_position == (0.5, 0.5)
        sink.move(math.inf, -math.inf)
        sink.move(0.25, math.nan)
        assert case.events() == [("move", 960, 540), ("move", 1919, 0), ("move", 480, 540)]


def test_close_releases_every_button(case):
    sink = case.open()
    sink.move(0.5, 0.5)
    case.events()
    for b in ("right", "middle", "left"):
        sink.press(b)
    sink.press("left")  # already down: no second press
    assert case.pressed() == {"left", "right", "middle"}
    sink.close()
    assert case.pressed() == set()
    assert sink.pressed == set() and sink.closed
    assert case.events() == [
        ("press", "right"),
        ("press", "middle"),
        ("press", "left"),
        ("release", "left"),
        ("release", "middle"),
        ("release", "right"),
    ]
    sink.close()  # twice is fine


def test_exception_in_with_block_releases(case):
    with pytest.raises(RuntimeError, match="tracker failed"), case.open() as sink:
        sink.move(0.1, 0.2)
        sink.press("right")
        sink.press("left")
        assert case.pressed() == {"left", "right"}
        raise RuntimeError("tracker failed")
    assert sink.closed
    assert case.pressed() == set()


def test_emit_makes_buttons_match_the_sample(case):
    with case.open() as sink:
        case.events()
        sink.emit(PointerSample(0.5, 0.5, timestamp_ns=1, buttons=frozenset({"left"})))
        assert case.pressed() == {"left"}
        sink.emit(PointerSample(1.0, 0.0, timestamp_ns=2, buttons=frozenset({"right"})))
        assert case.pressed() == {"right"}
        sink.emit(PointerSample(0.0, 1.0, timestamp_ns=3))
        assert case.pressed() == set()
        assert case.events() == [
            ("move", 960, 540),
            ("press", "left"),
            ("move", 1919, 0),
            ("release", "left"),
            ("press", "right"),
            ("move", 0, 1079),
            ("release", "right"),
        ]


HOLDER = """
import json, sys, time
from omnidev.screen import ScreenMapping
from omnidev.sinks import release_on_signals

name, options = sys.argv[1], json.loads(sys.argv[2])
if name == "record":
    from omnidev.sinks.record import open_record as opener
else:
    from omnidev.sinks.xtest_sink import open_xtest as opener
sink = opener(options, ScreenMapping.single(1920, 1080))
with release_on_signals(sink):
    sink.move(0.25, 0.75)
    sink.press("left")
    sink.press("right")
    print("held", flush=True)
    time.sleep(60)
"""


def test_sigterm_releases_buttons_held_by_another_process(case):
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLDER, case.name, json.dumps(case.options)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = proc.stdout.readline()  # type: ignore[union-attr]
        assert line.strip() == "held", proc.stderr.read()  # type: ignore[union-attr]
        assert case.pressed() == {"left", "right"}
        assert case.pixel() == (480, 809)  # 479.75, 809.25
        proc.send_signal(signal.SIGTERM)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 128 + signal.SIGTERM  # SystemExit from release_on_signals
    assert case.pressed() == set()
    assert case.events()[-2:] == [("release", "left"), ("release", "right")]


def test_unknown_button_is_an_error_and_sends_nothing(case):
    with case.open() as sink:
        sink.move(0.5, 0.5)
        case.events()
        count = sink.events
        for call in (sink.press, sink.release, sink.click):
            with pytest.raises(SinkError, match=r"unknown button 'back' \(buttons: left, right"):
                call("back")
        assert sink.events == count
        assert case.events() == []
        assert case.pressed() == set()


def test_closed_sink_refuses_events(case):
    sink = case.open()
    sink.close()
    calls: list[Callable[[], object]] = [
        lambda: sink.move(0.5, 0.5),
        lambda: sink.press("left"),
        lambda: sink.release("left"),
        lambda: sink.click(),
        lambda: sink.emit(PointerSample(0.5, 0.5, timestamp_ns=0)),
    ]
    for call in calls:
        with pytest.raises(SinkError, match=f"{case.name}: sink is closed"):
            call()
    assert case.events() == []


# -- record sink: its file, and replaying it into another sink ------------------------


def test_record_writes_one_json_line_per_event(tmp_path):
    path = tmp_path / "rec.jsonl"
    with open_record({"path": str(path)}, MAPPING) as sink:
        sink.move(2.0, 0.5)
        sink.press("middle")
        sink.emit(PointerSample(0.25, 0.75, timestamp_ns=123_456, frame_index=7))
        sink.emit(PointerSample(0.5, 0.5, 200_000, buttons=frozenset({"left"}), frame_index=8))
    lines = path.read_text().splitlines()
    events = [json.loads(line) for line in lines]
    assert all(" " not in line for line in lines)  # compact
    times = [e.pop("t_ns") for e in events]
    assert times == sorted(times) and all(isinstance(t, int) for t in times)
    assert events == [
        {"kind": "open", "format": 2, "screen": [0, 0, 1920, 1080], "layout": [1920, 1080]},
        {"kind": "move", "x": 1.0, "y": 0.5, "pixel": [1919, 540]},
        {"kind": "button", "button": "middle", "down": True},
        {
            "kind": "move",
            "x": 0.25,
            "y": 0.75,
            "pixel": [480, 809],
            "frame": 7,
            "frame_ns": 123_456,
        },
        {"kind": "button", "button": "middle", "down": False, "frame": 7, "frame_ns": 123_456},
        {"kind": "move", "x": 0.5, "y": 0.5, "pixel": [960, 540], "frame": 8, "frame_ns": 200_000},
        {"kind": "button", "button": "left", "down": True, "frame": 8, "frame_ns": 200_000},
        {"kind": "button", "button": "left", "down": False},
        {"kind": "close"},
    ]


def test_read_events_names_the_bad_line(tmp_path):
    path = tmp_path / "bad.jsonl"
    path.write_text('{"t_ns": 1, "kind": "open"}\n{"t_ns": 2, "kind": "move", \n')
    with pytest.raises(SinkError, match=r"bad\.jsonl: line 2: not JSON"):
        list(read_events(path))
    path.write_text('{"t_ns": 1, "kind": "button", "button": "back", "down": true}\n')
    with pytest.raises(SinkError, match=r"line 1: unknown button 'back'"):
        list(read_events(path))


def test_replay_reproduces_the_recording_in_another_sink(tmp_path, case):
    path = tmp_path / "session.jsonl"
    with open_record({"path": str(path)}, MAPPING) as rec:
        rec.move(0.1, 0.1)
        rec.press("left")
        rec.move(0.6, 0.4)
        rec.release("left")
        rec.move(-1.0, 0.5)
        rec.click("right")
        rec.move(0.9, 0.9)
        rec.press("middle")  # still down when the recording ends
        rec.release_all()
        rec.press("left")
    recorded = [
        ("move", *e["pixel"])
        if e["kind"] == "move"
        else ("press" if e["down"] else "release", e["button"])
        for e in read_events(path)
        if e["kind"] in ("move", "button")
    ]
    with case.open() as target:
        target.move(0.5, 0.5)  # a start away from the recording's first pixel
        case.events()
        sent = replay(path, target, realtime=True)
        assert sent == len(recorded) == 12
        assert case.events() == recorded  # the recording's own close released left
        assert case.pressed() == set()
        assert case.pixel() == (1727, 971)  # 0.9 * 1919 = 1727.1, 0.9 * 1079 = 971.1
