"""omnidev.buttons on the host: dwell clicks on synthetic cursor paths with known
truth, the spec parser's errors, report decoding, and opening absent devices.

The devices themselves (a uinput keyboard, a USB HID gadget) are read in the VM:
tests/vm/test_buttons.py.
"""

from __future__ import annotations

import math
import os

import pytest

from omnidev.buttons import ButtonInputError, DwellClicker, open_buttons, parse_spec
from omnidev.buttons.hidmap import BitSource, HidButtonMap, KeySource
from omnidev.buttons.inputs import ButtonStates
from omnidev.buttons.spec import EvdevSpec, HidSpec
from omnidev.errors import ConfigError

DT = 1 / 32  # a 32 fps camera: every time below is exact in binary floating point


def clicks(d: DwellClicker, path: list[tuple[float, float, float]]) -> list[int]:
    """Indices of the samples at which the dwell clicker fired."""
    return [i for i, (t, x, y) in enumerate(path) if d.update(t, x, y)]


def still(t0: float, n: int, x: float, y: float) -> list[tuple[float, float, float]]:
    return [(t0 + i * DT, x, y) for i in range(n)]


# -- dwell --------------------------------------------------------------------------------


def test_dwell_still_cursor_clicks_once_at_dwell_time() -> None:
    d = DwellClicker(radius_px=12, dwell_s=0.8)
    path = still(0.0, 90, 500.0, 300.0)  # 2.8 s
    # Truth: the first sample with t >= 0.8 s is i = 26 (25/32 = 0.78, 26/32 = 0.81).
    assert clicks(d, path) == [26]


def test_dwell_slow_wander_inside_radius_clicks_once() -> None:
    d = DwellClicker(radius_px=12, dwell_s=0.5)
    # A circle of radius 10 px around the start point, hand tremor: never 12 px away.
    path = [
        (i * DT, 800 + 10 * math.sin(i / 7), 400 + 10 * (1 - math.cos(i / 7)) / 2)
        for i in range(120)
    ]
    assert max(math.hypot(x - 800, y - 400) for _, x, y in path) <= 12
    assert clicks(d, path) == [16]  # 16/32 = 0.5 s


def test_dwell_moving_cursor_never_clicks() -> None:
    d = DwellClicker(radius_px=12, dwell_s=0.3)
    path = [(i * DT, 100.0 + 13 * i, 200.0) for i in range(200)]  # 13 px per frame
    assert clicks(d, path) == []


def test_dwell_slow_drift_leaves_radius_and_re_anchors() -> None:
    d = DwellClicker(radius_px=12, dwell_s=1.0)
    # 5 px per frame: leaves the 12 px circle every 3rd frame (15 px > 12), never rests 1 s.
    path = [(i * DT, 100.0 + 5 * i, 200.0) for i in range(300)]
    assert clicks(d, path) == []


def test_dwell_leave_and_settle_again_clicks_again() -> None:
    d = DwellClicker(radius_px=12, dwell_s=0.8)
    first = still(0.0, 45, 500.0, 300.0)  # clicks at i = 26
    move = [(1.5 + i * DT, 500 + 40 * (i + 1), 300.0) for i in range(5)]  # 40 px steps
    second = still(1.5 + 5 * DT, 45, 700.0, 300.0)  # rests where the move ended
    path = first + move + second
    # Truth: the rest starts at the last move sample (700, 300) at t = 1.5 + 4 DT; the
    # click is at the first sample >= 0.8 s later: 26 samples after it.
    assert clicks(d, path) == [26, 45 + 4 + 26]


def test_dwell_staying_after_a_click_does_not_click_again() -> None:
    d = DwellClicker(radius_px=12, dwell_s=0.2)
    assert clicks(d, still(0.0, 300, 10.0, 10.0)) == [7]  # 7/32 = 0.22 >= 0.2 > 6/32


def test_dwell_reset_starts_a_new_rest() -> None:
    d = DwellClicker(radius_px=12, dwell_s=0.8)
    assert clicks(d, still(0.0, 20, 50.0, 50.0)) == []  # 19/32 = 0.59 s: not yet
    d.reset()  # tracking lost
    # The same place again: the rest restarts at t = 1.0, so the click is at t >= 1.8.
    assert clicks(d, still(1.0, 30, 50.0, 50.0)) == [26]
    d.reset()
    assert clicks(d, still(3.0, 30, 50.0, 50.0)) == [26]  # re-armed by the reset


def test_dwell_nan_position_counts_as_tracking_lost() -> None:
    d = DwellClicker(radius_px=12, dwell_s=0.5)
    path = [*still(0.0, 10, 5.0, 5.0), (10 * DT, math.nan, 5.0), *still(11 * DT, 30, 5.0, 5.0)]
    assert clicks(d, path) == [11 + 16]  # the rest restarts at sample 11


def test_dwell_progress() -> None:
    d = DwellClicker(radius_px=12, dwell_s=1.0)
    assert d.progress(0.0) == 0.0
    d.update(2.0, 1.0, 1.0)
    assert d.progress(2.25) == 0.25
    d.update(3.0, 1.0, 1.0)
    assert d.progress(3.0) == 1.0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"radius_px": 0}, "radius_px must be a finite number > 0, got 0"),
        ({"radius_px": -3.0}, "radius_px must be a finite number > 0, got -3.0"),
        ({"radius_px": math.inf}, "radius_px must be a finite number > 0, got inf"),
        ({"dwell_s": 0.0}, "dwell_s must be a finite number > 0 s, got 0.0"),
        ({"dwell_s": math.nan}, "dwell_s must be a finite number > 0 s, got nan"),
        ({"dwell_s": "1"}, "dwell_s must be a finite number > 0 s, got '1'"),
        ({"button": "back"}, "button must be one of left, right, middle, got 'back'"),
    ],
)
def test_dwell_bad_parameters(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError) as exc:
        DwellClicker(**kwargs)  # type: ignore[arg-type]
    assert str(exc.value) == f"dwell click: {message}"


def test_dwell_time_going_back_is_an_error() -> None:
    d = DwellClicker()
    d.update(5.0, 0, 0)
    with pytest.raises(ValueError, match=r"time went back from 5.0 s to 4.0 s"):
        d.update(4.0, 0, 0)


# -- specs --------------------------------------------------------------------------------


def test_evdev_spec_by_node_with_keys_and_grab() -> None:
    s = parse_spec("evdev:/dev/input/event7?KEY_SPACE=left&KEY_B=right&BTN_0=middle&grab=1")
    assert s == EvdevSpec(
        "evdev:/dev/input/event7?KEY_SPACE=left&KEY_B=right&BTN_0=middle&grab=1",
        "/dev/input/event7",
        None,
        (("KEY_SPACE", "left"), ("KEY_B", "right"), ("BTN_0", "middle")),
        True,
    )


def test_evdev_spec_by_name_default_map() -> None:
    s = parse_spec("evdev:name=Logitech USB Receiver")
    assert isinstance(s, EvdevSpec)
    assert (s.path, s.name, s.keys, s.grab) == (
        None,
        "Logitech USB Receiver",
        (("KEY_SPACE", "left"),),
        False,
    )
    s = parse_spec("evdev:name=My%20Remote%3F?KEY_PAGEDOWN=left&57=right")
    assert isinstance(s, EvdevSpec)
    assert s.name == "My Remote?" and s.keys == (("KEY_PAGEDOWN", "left"), ("57", "right"))


def test_hid_spec() -> None:
    s = parse_spec("hid:046D:c538?key.0x4e=left&key.75=right&b0.2=middle&report=2&interface=0")
    assert isinstance(s, HidSpec)
    assert (s.vendor_id, s.product_id, s.interface, s.serial, s.backend) == (
        0x046D,
        0xC538,
        0,
        None,
        "auto",
    )
    assert s.map == HidButtonMap(
        bits=(BitSource(0, 2, "middle"),),
        keys=(KeySource(0x4E, "left"), KeySource(0x4B, "right")),
        report_id=2,
    )
    assert s.map.key_offset == 3


@pytest.mark.parametrize(
    ("spec", "what"),
    [
        ("", "empty; use evdev:... or hid:VVVV:PPPP?..."),
        ("usb:/dev/x", "unknown kind: use evdev:/dev/input/eventN?KEY=BUTTON or hid:VVVV:PPPP?..."),
        ("evdev", "unknown kind: use evdev:/dev/input/eventN?KEY=BUTTON or hid:VVVV:PPPP?..."),
        ("evdev:event3", "after evdev: give a node (/dev/input/eventN) or name=DEVICE NAME"),
        ("evdev:name=", "name= is empty"),
        (
            "evdev:/dev/input/event3?KEY_SPACE=button4",
            "KEY_SPACE='button4': the button must be one of left, right, middle",
        ),
        ("evdev:/dev/input/event3?KEY_SPACE", "'KEY_SPACE' is not KEY=VALUE"),
        ("evdev:/dev/input/event3?KEY_A=left&KEY_A=right", "KEY_A is mapped twice"),
        (
            "evdev:/dev/input/event3?space=left",
            "'space' is neither a key name (KEY_SPACE, BTN_LEFT, a code) nor grab",
        ),
        ("evdev:/dev/input/event3?grab=yes", "grab='yes': use grab=1 or grab=0"),
        ("hid:046d?key.0x4e=left", "'046d' is not VVVV:PPPP (hex vendor and product IDs)"),
        (
            "hid:046g:c538?key.0x4e=left",
            "'046g:c538' is not VVVV:PPPP (hex vendor and product IDs)",
        ),
        ("hid:046d:c538", "no button mapping: add e.g. key.0x4e=left (PageDown) or b0.0=left"),
        ("hid:046d:c538?b1.8=left", "b1.8: byte must be 0..63 and bit 0..7"),
        ("hid:046d:c538?b64.0=left", "b64.0: byte must be 0..63 and bit 0..7"),
        ("hid:046d:c538?key.0x02=left", "key.0x02: keyboard usages are 0x04..0xE7"),
        ("hid:046d:c538?key.0x4e=left&key.78=right", "key.78 is mapped twice"),
        (
            "hid:046d:c538?key.0x4e=up",
            "key.0x4e='up': the button must be one of left, right, middle",
        ),
        (
            "hid:046d:c538?byte=1&mask=0x01=left",
            "'byte' is not bN.M, key.0xHH, report, keys_at, interface, serial or backend",
        ),
        ("hid:046d:c538?b1.0=left&report=0", "report=0 is outside 1..255"),
        ("hid:046d:c538?b1.0=left&report=x", "report='x' is not an integer"),
        ("hid:046d:c538?b1.0=left&backend=usb", "backend='usb': use one of auto, hidraw, libusb"),
        ("hid:046d:c538?b1.0=left&interface=1&interface=2", "interface is given twice"),
    ],
)
def test_bad_specs_say_what_is_wrong(spec: str, what: str) -> None:
    with pytest.raises(ConfigError) as exc:
        open_buttons(spec)
    assert str(exc.value) == f"button input {spec!r}: {what}"
    assert "\n" not in str(exc.value)


# -- decoding and button state -------------------------------------------------------------


def test_hid_map_keyboard_reports() -> None:
    m = HidButtonMap(
        keys=(KeySource(0x4E, "left"), KeySource(0x4B, "right"), KeySource(0xE1, "middle"))
    )
    assert m.pressed([0, 0, 0, 0, 0, 0, 0, 0]) == frozenset()
    assert m.pressed([0, 0, 0x4E, 0, 0, 0, 0, 0]) == frozenset({"left"})
    assert m.pressed([0, 0, 0x05, 0, 0, 0, 0, 0x4B]) == frozenset({"right"})  # any slot
    assert m.pressed([0x02, 0, 0, 0, 0, 0, 0, 0]) == frozenset({"middle"})  # left Shift = bit 1
    assert m.pressed([0x20, 0, 0, 0, 0, 0, 0, 0]) == frozenset()  # right Shift: unmapped
    assert m.pressed([0, 0, 1, 1, 1, 1, 1, 1]) is None  # ErrorRollOver: no change
    assert m.pressed([0, 0]) == frozenset()  # a short report: nothing down


def test_hid_map_report_id_and_bits() -> None:
    m = HidButtonMap(
        bits=(BitSource(1, 0, "left"), BitSource(1, 7, "right")),
        keys=(KeySource(0x3E, "middle"),),
        report_id=3,
    )
    assert m.pressed([3, 0x81, 0, 0x3E, 0, 0, 0, 0, 0]) == frozenset({"left", "right", "middle"})
    assert m.pressed([3, 0x01, 0, 0, 0, 0, 0, 0, 0]) == frozenset({"left"})
    assert m.pressed([4, 0xFF, 0, 0x3E]) is None  # another report
    assert m.pressed([]) is None


def test_button_states_or_of_sources_and_release_order() -> None:
    st = ButtonStates()
    assert st.set_pressed({"right"}) == [("right", True)]
    assert st.set_pressed({"right", "left"}) == [("left", True)]
    assert st.set_pressed({"right", "left"}) == []
    assert st.set_pressed({"middle"}) == [("left", False), ("right", False), ("middle", True)]
    assert st.set_pressed({"middle", "left"}) == [("left", True)]
    assert st.release_all() == [("middle", False), ("left", False)]  # press order
    assert st.release_all() == []


# -- absent devices (this machine has none) ---------------------------------------------------


@pytest.mark.skipif(os.path.exists("/dev/input/event99"), reason="/dev/input/event99 exists here")
def test_missing_evdev_node_is_one_line() -> None:
    with pytest.raises(ButtonInputError) as exc:
        open_buttons("evdev:/dev/input/event99?KEY_SPACE=left")
    msg = str(exc.value)
    assert msg.startswith(
        "evdev button input 'evdev:/dev/input/event99?KEY_SPACE=left': /dev/input/event99 "
    )
    assert "does not exist" in msg and "\n" not in msg


def test_unknown_key_name_is_a_config_error() -> None:
    with pytest.raises(ConfigError) as exc:
        open_buttons("evdev:/dev/input/event99?KEY_NOPE=left")
    assert str(exc.value) == (
        "button input 'evdev:/dev/input/event99?KEY_NOPE=left': KEY_NOPE is not a Linux key "
        "name (see /usr/include/linux/input-event-codes.h)"
    )


def test_missing_hid_device_is_one_line() -> None:
    import hid

    if any((d["vendor_id"], d["product_id"]) == (0xDEAD, 0xBEEF) for d in hid.enumerate()):
        pytest.skip("a HID device dead:beef is connected here")
    with pytest.raises(ButtonInputError) as exc:
        open_buttons("hid:dead:beef?key.0x4e=left")
    msg = str(exc.value)
    assert msg.startswith(
        "hid button input 'hid:dead:beef?key.0x4e=left': no HID device dead:beef is connected ("
    )
    assert "\n" not in msg
