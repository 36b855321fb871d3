"""Button inputs on a real kernel (runs inside the VM, as root).

(a) ``evdev:``: a python-evdev UInput keyboard whose key presses are read back by
    :func:`omnidev.buttons.open_buttons` from its /dev/input/eventN.
(b) ``hid:``: a USB keyboard made with the USB gadget (configfs, usb_f_hid bound to
    dummy_hcd's device controller): boot-keyboard reports written to its /dev/hidgN
    are enumerated and read on the host side of dummy_hcd by hidapi's hidraw backend.

Truth: the events written (key down/up, the report bytes) and the spec's map give
the expected button events, listed by hand in each test.
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from evdev import UInput, ecodes

from omnidev.buttons import ButtonInput, ButtonInputError, open_buttons

REPO = Path(__file__).resolve().parents[2]
KBD_NAME = "omnidev buttons test keyboard"
WAIT_S = 30.0  # a deadline against hanging, not a timing assertion
UDC = "dummy_udc.0"
VID, PID = 0x1D6B, 0x0105
GADGET = Path("/sys/kernel/config/usb_gadget/omnidev_buttons_test")
PRODUCT = "omnidev buttons test remote"
ENUM_TIMEOUT_S = 120.0
# The boot keyboard report descriptor of the kernel's Documentation/usb/gadget_hid.rst:
# 8 modifier bits, a reserved byte, 5 LED bits out + 3 padding, 6 key slots (0..0x65).
KEYBOARD_DESCRIPTOR = bytes.fromhex(
    "05010906a101050719e029e71500250175019508810295017508810395057501050819012905"
    "910295017503910395067508150025650507190029658100c0"
)


def poll_until(inp: ButtonInput, n: int) -> list[tuple[str, bool]]:
    """Poll until ``n`` events have come (or the deadline passed), then once more."""
    events: list[tuple[str, bool]] = []
    deadline = time.monotonic() + WAIT_S
    while len(events) < n and time.monotonic() < deadline:
        events += inp.poll()
        time.sleep(0.01)
    time.sleep(0.2)
    return events + inp.poll()


# -- (a) evdev -----------------------------------------------------------------------------


@pytest.fixture
def keyboard() -> Iterator[Any]:
    ui = UInput({ecodes.EV_KEY: [ecodes.KEY_SPACE, ecodes.KEY_B, ecodes.KEY_A]}, name=KBD_NAME)
    deadline = time.monotonic() + WAIT_S
    while not os.path.exists(ui.device.path) and time.monotonic() < deadline:
        time.sleep(0.02)
    yield ui
    ui.close()


def key(ui: Any, code: int, value: int) -> None:
    ui.write(ecodes.EV_KEY, code, value)
    ui.syn()


def test_evdev_keys_in_order(keyboard: Any) -> None:
    inp = open_buttons(f"evdev:{keyboard.device.path}?KEY_SPACE=left&KEY_B=right")
    try:
        assert inp.poll() == []
        key(keyboard, ecodes.KEY_SPACE, 1)
        key(keyboard, ecodes.KEY_SPACE, 0)
        key(keyboard, ecodes.KEY_B, 1)
        key(keyboard, ecodes.KEY_A, 1)  # not mapped
        key(keyboard, ecodes.KEY_SPACE, 1)
        key(keyboard, ecodes.KEY_SPACE, 2)  # autorepeat: ignored
        key(keyboard, ecodes.KEY_SPACE, 2)
        key(keyboard, ecodes.KEY_A, 0)
        key(keyboard, ecodes.KEY_B, 0)
        key(keyboard, ecodes.KEY_SPACE, 0)
        want = [
            ("left", True),
            ("left", False),
            ("right", True),
            ("left", True),
            ("right", False),
            ("left", False),
        ]
        assert poll_until(inp, len(want)) == want
    finally:
        assert inp.close() == []  # nothing left down


def test_evdev_two_keys_one_button_and_close_releases(keyboard: Any) -> None:
    inp = open_buttons(f"evdev:{keyboard.device.path}?KEY_SPACE=left&KEY_A=left&KEY_B=right")
    key(keyboard, ecodes.KEY_SPACE, 1)
    key(keyboard, ecodes.KEY_A, 1)  # left already down: no second press
    key(keyboard, ecodes.KEY_SPACE, 0)  # A still holds it
    key(keyboard, ecodes.KEY_B, 1)
    assert poll_until(inp, 2) == [("left", True), ("right", True)]
    assert inp.close() == [("left", False), ("right", False)]  # press order
    assert inp.poll() == [] and inp.close() == []


def test_evdev_by_name_with_default_map(keyboard: Any) -> None:
    inp = open_buttons(f"evdev:name={KBD_NAME}")
    try:
        assert getattr(inp, "path", None) == keyboard.device.path
        key(keyboard, ecodes.KEY_B, 1)  # not in the default map (KEY_SPACE=left)
        key(keyboard, ecodes.KEY_SPACE, 1)
        assert poll_until(inp, 1) == [("left", True)]
    finally:
        assert inp.close() == [("left", False)]


def test_evdev_grab_keeps_keys_from_other_readers(keyboard: Any) -> None:
    import evdev

    other = evdev.InputDevice(keyboard.device.path)
    try:
        inp = open_buttons(f"evdev:{keyboard.device.path}?KEY_SPACE=left&grab=1")
        key(keyboard, ecodes.KEY_SPACE, 1)
        key(keyboard, ecodes.KEY_SPACE, 0)
        assert poll_until(inp, 2) == [("left", True), ("left", False)]
        assert select.select([other.fd], [], [], 0.5)[0] == [], "the grab let events through"
        inp.close()  # ungrabs: the other reader gets keys again
        key(keyboard, ecodes.KEY_B, 1)
        assert select.select([other.fd], [], [], WAIT_S)[0], "no events after the ungrab"
        codes = [e.code for e in other.read() if e.type == ecodes.EV_KEY]
        assert codes == [ecodes.KEY_B]
    finally:
        other.close()


def test_evdev_device_gone_releases_then_raises() -> None:
    ui = UInput({ecodes.EV_KEY: [ecodes.KEY_SPACE]}, name=KBD_NAME + " 2")
    path = str(ui.device.path)
    while not os.path.exists(path):
        time.sleep(0.02)
    inp = open_buttons(f"evdev:{path}")
    key(ui, ecodes.KEY_SPACE, 1)
    assert poll_until(inp, 1) == [("left", True)]
    ui.close()
    events: list[tuple[str, bool]] = []
    deadline = time.monotonic() + WAIT_S
    while not events and time.monotonic() < deadline:
        events = inp.poll()
        time.sleep(0.01)
    assert events == [("left", False)]
    with pytest.raises(ButtonInputError, match=r"went away"):
        inp.poll()
    assert inp.close() == []


UNPRIVILEGED = textwrap.dedent(
    """
    import os, sys
    import evdev, hid, hidraw
    from omnidev.buttons import ButtonInputError, open_buttons
    import omnidev.buttons.evdev_keys, omnidev.buttons.hid_buttons
    # Imported as root (the interpreter's files may be unreadable to nobody); now
    # only the device is opened as nobody, without the input group.
    os.setgroups([]); os.setgid(65534); os.setuid(65534)
    try:
        open_buttons(sys.argv[1])
    except ButtonInputError as exc:
        print(exc)
    else:
        print("opened")
    """
)


def as_nobody(spec: str) -> str:
    res = subprocess.run(
        [sys.executable, "-c", UNPRIVILEGED, spec],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
    return res.stdout.strip()


def test_evdev_errors_name_the_node_and_the_fix(keyboard: Any) -> None:
    path = keyboard.device.path
    msg = as_nobody(f"evdev:{path}")
    assert msg == (
        f"evdev button input 'evdev:{path}': no permission to read {path}: add the user to "
        "group input (sudo usermod -aG input USER, then log in again; Debian's udev gives "
        "/dev/input/event* to group input, mode 0660) or run omnidevd with the groups and "
        "udev rule of udev/60-omnidev.rules and docs/daemon.md; under omnidevd.service the "
        "unit must allow char-input (sudo make install writes omnidevd.service.d/10-devices.conf "
        "from the configuration)"
    )
    with pytest.raises(ButtonInputError) as exc:
        open_buttons("evdev:/dev/input/event999")
    assert str(exc.value).startswith(
        "evdev button input 'evdev:/dev/input/event999': /dev/input/event999 does not exist"
    )
    with pytest.raises(ButtonInputError, match=r"no input device named 'no such keyboard'"):
        open_buttons("evdev:name=no such keyboard")
    with pytest.raises(ButtonInputError, match=r"has all the keys KEY_ENTER"):
        open_buttons(f"evdev:name={KBD_NAME}?KEY_ENTER=left")


# -- (b) hid, through a USB gadget keyboard ---------------------------------------------------


def write(path: Path, value: str | bytes) -> None:
    if isinstance(value, bytes):
        path.write_bytes(value)
    else:
        path.write_text(value + "\n")


def remove_gadget() -> None:
    if not GADGET.is_dir():
        return
    if (GADGET / "UDC").read_text().strip():
        write(GADGET / "UDC", "")
    cfg = GADGET / "configs" / "c.1"
    if (cfg / "hid.usb0").is_symlink():
        (cfg / "hid.usb0").unlink()
    for d in (cfg / "strings" / "0x409", cfg, GADGET / "functions" / "hid.usb0"):
        if d.is_dir():
            d.rmdir()
    (GADGET / "strings" / "0x409").rmdir()
    GADGET.rmdir()


def hidraw_listed() -> list[dict[str, Any]]:
    import hidraw

    return list(hidraw.enumerate(VID, PID))


@pytest.fixture(scope="module")
def gadget_keyboard() -> Iterator[str]:
    """A USB boot keyboard on dummy_udc.0; yields its device-side /dev/hidgN."""
    remove_gadget()
    busy = [p for p in Path("/sys/kernel/config/usb_gadget").glob("*/UDC") if p.read_text().strip()]
    assert not busy, f"{UDC} is already bound by {busy}"
    (GADGET / "strings" / "0x409").mkdir(parents=True)
    write(GADGET / "idVendor", f"{VID:#06x}")
    write(GADGET / "idProduct", f"{PID:#06x}")
    write(GADGET / "strings" / "0x409" / "manufacturer", "omnidev")
    write(GADGET / "strings" / "0x409" / "product", PRODUCT)
    write(GADGET / "strings" / "0x409" / "serialnumber", "btn0001")
    fn = GADGET / "functions" / "hid.usb0"
    fn.mkdir(parents=True)
    write(fn / "protocol", "1")  # keyboard
    write(fn / "subclass", "1")  # boot interface
    write(fn / "report_length", "8")
    write(fn / "report_desc", KEYBOARD_DESCRIPTOR)
    cfg = GADGET / "configs" / "c.1"
    (cfg / "strings" / "0x409").mkdir(parents=True)
    write(cfg / "strings" / "0x409" / "configuration", "buttons test")
    (cfg / "hid.usb0").symlink_to(fn)
    write(GADGET / "UDC", UDC)
    try:
        major_minor = (fn / "dev").read_text().strip()
        node = next(
            f"/dev/{p.parent.name}"
            for p in Path("/sys/class/hidg").glob("*/dev")
            if p.read_text().strip() == major_minor
        )
        deadline = time.monotonic() + ENUM_TIMEOUT_S
        while not hidraw_listed() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert hidraw_listed(), f"the host did not enumerate {VID:04x}:{PID:04x}"
        yield node
    finally:
        remove_gadget()


class GadgetSide:
    """The device side: writes 8-byte keyboard reports to /dev/hidgN, one at a time."""

    def __init__(self, node: str) -> None:
        self.fd = os.open(node, os.O_RDWR | os.O_NONBLOCK)

    def send(self, modifiers: int, *keys: int) -> None:
        report = bytes([modifiers, 0, *keys, *([0] * (6 - len(keys)))])
        # Writable once the host has taken the previous report (usbhid polls while
        # hidapi has the hidraw node open): no report is dropped.
        assert select.select([], [self.fd], [], WAIT_S)[1], "the host is not polling"
        assert os.write(self.fd, report) == 8

    def delivered(self) -> None:
        """Wait until the host has taken the last report written."""
        assert select.select([], [self.fd], [], WAIT_S)[1], "the host is not polling"

    def close(self) -> None:
        os.close(self.fd)


PAGE_DOWN, PAGE_UP, KEY_A, LEFT_SHIFT = 0x4E, 0x4B, 0x04, 0x02


def test_hid_keyboard_reports_to_buttons(gadget_keyboard: str, vm_figures: dict[str, Any]) -> None:
    spec = f"hid:{VID:04x}:{PID:04x}?key.0x4e=left&key.0x4b=right&b0.1=middle"
    inp = open_buttons(spec)
    assert getattr(inp, "backend", None) == "hidraw"
    assert getattr(inp, "product", None) == PRODUCT
    dev = GadgetSide(gadget_keyboard)
    try:
        assert inp.poll() == []
        dev.send(0, PAGE_DOWN)  # left down
        dev.send(0, PAGE_DOWN, PAGE_UP)  # right down
        dev.send(0, PAGE_UP)  # left up
        dev.send(LEFT_SHIFT, PAGE_UP)  # b0.1 (left Shift): middle down
        dev.send(0, KEY_A)  # right and middle up (releases in left/right/middle order)
        dev.send(0)  # nothing changes
        dev.send(0, PAGE_DOWN)  # left down, released by close()
        want = [
            ("left", True),
            ("right", True),
            ("left", False),
            ("middle", True),
            ("right", False),
            ("middle", False),
            ("left", True),
        ]
        got = poll_until(inp, len(want))
        assert got == want
        vm_figures["vm_buttons_hid_events"] = len(got)
    finally:
        dev.close()
        released = inp.close()
    assert released == [("left", False)]


def test_hid_report_id_filter_and_interface(gadget_keyboard: str) -> None:
    # The gadget's reports carry no ID: with report=1 none of them is for the map.
    inp = open_buttons(f"hid:{VID:04x}:{PID:04x}?key.0x4e=left&report=1&interface=0")
    dev = GadgetSide(gadget_keyboard)
    try:
        dev.send(0, PAGE_DOWN)
        dev.send(0)
        dev.send(0x01, PAGE_DOWN)  # byte 0 = 1 now: decoded, slots from byte 3 hold nothing
        dev.delivered()
        assert poll_until(inp, 0) == []
    finally:
        dev.close()
        assert inp.close() == []
    with pytest.raises(ButtonInputError, match=r"not with the serial/interface asked for"):
        open_buttons(f"hid:{VID:04x}:{PID:04x}?key.0x4e=left&interface=3")


def test_hid_errors(gadget_keyboard: str) -> None:
    spec = f"hid:{VID:04x}:{PID:04x}?key.0x4e=left"
    node = hidraw_listed()[0]["path"].decode()
    msg = as_nobody(spec)
    assert msg.startswith(f"hid button input '{spec}': no permission to open {node}: "), msg
    assert "udev rule" in msg and "\n" not in msg
    with pytest.raises(ButtonInputError) as exc:
        open_buttons("hid:1d6b:0fff?b0.0=left")
    assert str(exc.value).startswith(
        "hid button input 'hid:1d6b:0fff?b0.0=left': no HID device 1d6b:0fff is connected "
        "(hidraw backend lists: "
    )
    assert f"{VID:04x}:{PID:04x}" in str(exc.value)


def test_hid_unplugged_releases_then_raises(gadget_keyboard: str) -> None:
    """Runs last in this file: it unbinds the gadget (the USB cable pulled)."""
    inp = open_buttons(f"hid:{VID:04x}:{PID:04x}?key.0x4e=left")
    dev = GadgetSide(gadget_keyboard)
    try:
        dev.send(0, PAGE_DOWN)
        assert poll_until(inp, 1) == [("left", True)]
    finally:
        dev.close()
    write(GADGET / "UDC", "")
    events: list[tuple[str, bool]] = []
    deadline = time.monotonic() + WAIT_S
    while not events and time.monotonic() < deadline:
        events = inp.poll()
        time.sleep(0.05)
    assert events == [("left", False)]
    with pytest.raises(ButtonInputError, match=r"went away"):
        inp.poll()
    assert inp.close() == []


# -- (c) through the pointer pipeline ------------------------------------------------------


def test_pipeline_takes_key_presses_to_the_sink(keyboard: Any, tmp_path: Path) -> None:
    """omnidevd's pipeline with ``[buttons] input = "evdev:..."``: holding SPACE holds the
    left button in the sink while the blob tracker moves the pointer; releasing it
    releases the button; a key held when the pipeline stops is released."""
    from omnidev.daemon.config import parse_config
    from omnidev.daemon.pipeline import Pipeline
    from omnidev.sinks.record import read_events

    rec = tmp_path / "events.jsonl"
    blob = REPO / "fixtures" / "blob" / "blob.avi"
    doc = {
        "source": {"uri": f"video:{blob}?rate=60&loop=1"},
        "tracker": {"name": "bright-blob"},
        "filter": {"kind": "none"},
        "sink": {"name": "record", "options": {"path": str(rec)}},
        "buttons": {"input": f"evdev:{keyboard.device.path}?KEY_SPACE=left&KEY_B=right"},
        "daemon": {"socket": str(tmp_path / "control.sock")},
    }
    p = Pipeline(parse_config(doc, tmp_path / "omnidev.toml"))
    p.start()

    def moves() -> int:
        return int(p.status()["tracked"])

    def wait(pred: Any) -> bool:
        deadline = time.monotonic() + WAIT_S
        while time.monotonic() < deadline:
            if pred():
                return True
            time.sleep(0.01)
        return False

    try:
        assert wait(lambda: moves() > 5)
        key(keyboard, ecodes.KEY_SPACE, 1)
        assert wait(lambda: "left" in p.sink.pressed)
        n = moves()
        assert wait(lambda: moves() > n + 5)  # the pointer keeps moving: a drag
        assert "left" in p.sink.pressed
        key(keyboard, ecodes.KEY_SPACE, 0)
        assert wait(lambda: "left" not in p.sink.pressed)
        key(keyboard, ecodes.KEY_B, 1)
        assert wait(lambda: "right" in p.sink.pressed)
        assert p.status()["buttons_held"] == ["right"]
    finally:
        p.stop()  # B still held: the pipeline releases it
    events = list(read_events(rec))
    buttons = [(e["button"], e["down"]) for e in events if e["kind"] == "button"]
    assert buttons == [("left", True), ("left", False), ("right", True), ("right", False)]
    first_down = next(i for i, e in enumerate(events) if e["kind"] == "button")
    drag = [e for e in events[first_down:] if e["kind"] in ("move", "button")]
    assert sum(e["kind"] == "move" for e in drag[: drag.index(next(
        e for e in drag if e["kind"] == "button" and not e["down"]))]) >= 5  # fmt: skip
    assert events[-1]["kind"] == "close"
