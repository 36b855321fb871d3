"""The hidg sink on a real kernel: the gadget made by udev/omnidev-gadget.sh, read back
on the USB host side of dummy_hcd (runs inside the VM, as root).

dummy_hcd loops a USB device controller (dummy_udc.0) back to a host controller in
the same kernel, so the gadget the script binds is enumerated by the same kernel's
usbhid and hid-generic, exactly as a host computer would. The host side is read with
hidapi (listing through its libusb backend, reading through its hidraw backend),
pyusb, the hidraw ioctls and evdev.

Truth: a normalized position n on a target screen at layout x0 with width w maps
to the layout pixel x0 + n * (w - 1), and the device value is
round(pixel * 32767 / (layout width - 1)) (omnidev.screen). The expected values
below were computed by hand from that formula, not by calling the code under test.
"""

from __future__ import annotations

import array
import fcntl
import glob
import os
import re
import select
import signal
import statistics
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from omnidev import hid_reports as hr
from omnidev.errors import SinkError
from omnidev.screen import ScreenMapping, ScreenRect
from omnidev.sinks.hidg_sink import HidgSink, HostGoneError, open_hidg

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "udev" / "omnidev-gadget.sh"
UDC = "dummy_udc.0"
VID, PID = 0x1D6B, 0x0104
GADGET = Path("/sys/kernel/config/usb_gadget/omnidev")
PRODUCT = {"absolute": "omnidev absolute pointer", "relative": "omnidev relative pointer"}
ENUM_TIMEOUT_S = 120.0  # enumeration through dummy_hcd under TCG took ~6 s

SINGLE = ScreenMapping.single(1920, 1080)
# (nx, ny) -> (X, Y) on SINGLE: round(n * 1919 * 32767 / 1919), ties to even.
SINGLE_CASES = [
    ((0.5, 0.5), (16384, 16384)),  # 16383.5 -> 16384
    ((0.0, 0.0), (0, 0)),
    ((1.0, 1.0), (32767, 32767)),
    ((0.25, 0.75), (8192, 24575)),  # 8191.75, 24575.25
    ((0.1, 0.9), (3277, 29490)),  # 3276.7, 29490.3
    ((1.7, -3.0), (32767, 0)),  # out of range: clamped to (1, 0)
    ((-0.2, 2.0), (0, 32767)),  # clamped to (0, 1)
]
# A 1280x1024 monitor right of a 1920x1080 one: layout 3200x1080, screen at +1920+0.
RIGHT_MONITOR = ScreenMapping(ScreenRect(1920, 0, 1280, 1024), 3200, 1080)
# x pixel 1920 + nx * 1279 -> round(px * 32767 / 3199); y pixel ny * 1023 -> * 32767 / 1079
RIGHT_CASES = [
    ((0.0, 0.0), (19666, 0)),  # 1920 * 32767 / 3199 = 19666.42
    ((1.0, 1.0), (32767, 31066)),  # 3199 -> 32767; 1023 * 32767 / 1079 = 31066.35
    ((0.5, 0.5), (26217, 15533)),  # 2559.5 -> 26216.67; 511.5 -> 15533.17
]

_state: dict[str, Any] = {"mode": None, "node": None}


# -- helpers ---------------------------------------------------------------------------


def run_script(*args: str, udc: str | None = UDC) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    if udc is not None:
        env["UDC"] = udc
    return subprocess.run(
        [str(SCRIPT), *args], env=env, capture_output=True, text=True, timeout=120
    )


def hid_devices() -> list[dict[str, Any]]:
    import hid

    return list(hid.enumerate(VID, PID))


def hid_sysfs() -> list[Path]:
    """The host side's HID devices of the gadget (/sys/bus/hid/devices/0003:1D6B:0104.*)."""
    return [Path(p) for p in sorted(glob.glob("/sys/bus/hid/devices/0003:1D6B:0104.*"))]


def hidraw_node() -> str | None:
    for dev in hid_sysfs():
        nodes = sorted((dev / "hidraw").glob("hidraw*")) if (dev / "hidraw").is_dir() else []
        if nodes and os.path.exists(f"/dev/{nodes[0].name}"):
            return f"/dev/{nodes[0].name}"
    return None


def wait_for_host(product: str) -> None:
    """Until the host lists the gadget (hidapi) and hid-generic has made its hidraw node."""
    deadline = time.monotonic() + ENUM_TIMEOUT_S
    while time.monotonic() < deadline:
        if any(d["product_string"] == product for d in hid_devices()) and hidraw_node():
            return
        time.sleep(0.2)
    raise AssertionError(
        f"the host did not enumerate {product!r} within {ENUM_TIMEOUT_S} s: hidapi lists "
        f"{hid_devices()}, hid devices {hid_sysfs()}"
    )


def ensure_gadget(mode: str) -> str:
    """Set the gadget up in ``mode`` with the script (once per mode); its /dev/hidgN."""
    if _state["mode"] != mode:
        res = run_script("--mode", mode)
        assert res.returncode == 0, f"omnidev-gadget.sh --mode {mode} failed: {res.stderr}"
        m = re.search(r"(/dev/hidg\d+)", res.stdout)
        assert m, f"the script did not name the device node: {res.stdout!r}"
        wait_for_host(PRODUCT[mode])
        _state.update(mode=mode, node=m.group(1))
    node: str = _state["node"]
    return node


class HostReader:
    """The USB host reading the gadget's reports: hidapi's hidraw backend on usbhid.

    This is the path of a Linux host computer (usbhid polls the interrupt endpoint
    while a hidraw or evdev reader has the device open). hidapi's libusb backend
    (module ``hid``) is used only to list the device: through dummy_hcd its reads
    returned an empty report after every real one, one read behind.
    """

    def __init__(self) -> None:
        import hidraw

        self.dev = hidraw.device()
        deadline = time.monotonic() + 30
        while True:  # the node may be re-created after a reconnect; retry meanwhile
            try:
                self.dev.open(VID, PID)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.2)

    def read(self, timeout_ms: int = 5000) -> list[int]:
        data: list[int] = self.dev.read(64, timeout_ms)
        return data

    def drain(self, quiet_ms: int = 300) -> list[list[int]]:
        """Every report already on its way (e.g. one the kernel held while nobody read)."""
        out = []
        while data := self.read(quiet_ms):
            out.append(data)
        return out

    def close(self) -> None:
        self.dev.close()

    def __enter__(self) -> HostReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def xy(report: list[int]) -> tuple[int, int]:
    v = hr.decode_report(hr.ABSOLUTE_DESCRIPTOR, bytes(report))
    return v[(1, 0x30)], v[(1, 0x31)]


@pytest.fixture(scope="module", autouse=True)
def gadget_torn_down_at_the_end() -> Iterator[None]:
    """Leave no gadget behind for the other in-VM tests."""
    yield
    run_script("--remove", udc=None)


@pytest.fixture
def absolute_node() -> str:
    return ensure_gadget("absolute")


# -- the script and what the host sees -----------------------------------------------------


def test_script_binds_the_gadget_idempotently() -> None:
    # A clean start: configfs may or may not be mounted yet (the script mounts it).
    run_script("--remove", udc=None)
    _state["mode"] = None
    node = ensure_gadget("absolute")
    assert os.path.exists(node)
    assert (GADGET / "UDC").read_text().strip() == UDC
    fn = GADGET / "functions" / "hid.usb0"
    assert (fn / "report_desc").read_bytes() == hr.ABSOLUTE_DESCRIPTOR
    assert int((fn / "report_length").read_text()) == 5
    assert int((fn / "protocol").read_text()) == 2
    again = run_script()
    assert again.returncode == 0 and "already set up" in again.stdout, again.stdout
    status = run_script("--status")
    assert f"absolute mode, UDC '{UDC}', {node}" in status.stdout


def test_script_says_when_the_udc_is_missing() -> None:
    res = run_script("--mode", "absolute", udc="no_such_udc.7")
    assert res.returncode != 0
    assert "'no_such_udc.7' is not in /sys/class/udc" in res.stderr
    assert (GADGET / "UDC").read_text().strip() == UDC  # the bound gadget is untouched


def test_pyusb_finds_a_hid_mouse(absolute_node: str) -> None:
    import usb.core

    dev = usb.core.find(idVendor=VID, idProduct=PID)
    assert dev is not None, "pyusb does not list the gadget"
    assert dev.manufacturer == "omnidev" and dev.product == PRODUCT["absolute"]
    intf = dev.get_active_configuration()[(0, 0)]
    assert (intf.bInterfaceClass, intf.bInterfaceSubClass, intf.bInterfaceProtocol) == (3, 0, 2)
    # One interrupt IN endpoint; no OUT endpoint where the kernel can leave it out.
    eps = [(ep.bEndpointAddress & 0x80, ep.bmAttributes & 0x3) for ep in intf.endpoints()]
    no_out = (GADGET / "functions" / "hid.usb0" / "no_out_endpoint").exists()
    assert sorted(eps) == ([(0x80, 3)] if no_out else [(0, 3), (0x80, 3)]), eps


def test_hidapi_lists_the_product() -> None:
    ensure_gadget("absolute")
    (d,) = [d for d in hid_devices() if d["product_string"] == PRODUCT["absolute"]]
    assert d["manufacturer_string"] == "omnidev"
    assert d["interface_number"] == 0


def test_host_reads_omnidevs_report_descriptor(absolute_node: str) -> None:
    node = hidraw_node()
    assert node, "no hidraw node for the gadget on the host side"
    # HIDIOCGRDESCSIZE = _IOR('H', 1, int); HIDIOCGRDESC = _IOR('H', 2, struct {u32; u8[4096]})
    ioc_size = (2 << 30) | (4 << 16) | (ord("H") << 8) | 1
    ioc_desc = (2 << 30) | (4100 << 16) | (ord("H") << 8) | 2
    fd = os.open(node, os.O_RDONLY | os.O_NONBLOCK)
    try:
        size = array.array("i", [0])
        fcntl.ioctl(fd, ioc_size, size)
        buf = array.array("B", size[0].to_bytes(4, "little") + bytes(4096))
        fcntl.ioctl(fd, ioc_desc, buf)
    finally:
        os.close(fd)
    assert bytes(buf[4 : 4 + size[0]]) == hr.ABSOLUTE_DESCRIPTOR
    (dev,) = hid_sysfs()
    assert (dev / "report_descriptor").read_bytes() == hr.ABSOLUTE_DESCRIPTOR
    assert os.path.realpath(dev / "driver").endswith("/hid-generic")


def test_host_input_device_has_an_event_node(absolute_node: str) -> None:
    """hid-generic makes an input device; its /dev/input/eventN needs the evdev module.

    Debian builds evdev as a module (CONFIG_INPUT_EVDEV=m): without it loaded the
    input device exists (/proc/bus/input/devices) with only a mouseN handler.
    """
    import evdev
    from evdev import ecodes

    subprocess.run(["modprobe", "evdev"], check=True)
    (dev,) = hid_sysfs()
    deadline = time.monotonic() + 30
    nodes: list[str] = []
    while not nodes and time.monotonic() < deadline:
        nodes = sorted(glob.glob(str(dev / "input" / "input*" / "event*")))
        time.sleep(0.1)
    assert nodes, f"no event node under {dev}/input"
    path = "/dev/input/" + Path(nodes[0]).name
    while not os.path.exists(path) and time.monotonic() < deadline:
        time.sleep(0.1)
    ev = evdev.InputDevice(path)
    try:
        assert ev.name == f"omnidev {PRODUCT['absolute']}"
        caps = ev.capabilities()
        assert {ecodes.BTN_LEFT, ecodes.BTN_RIGHT, ecodes.BTN_MIDDLE} <= set(caps[ecodes.EV_KEY])
        for axis in (ecodes.ABS_X, ecodes.ABS_Y):
            info = ev.absinfo(axis)
            assert (info.min, info.max) == (0, 32767)
        assert ecodes.EV_REL not in caps
        # Reports from the sink arrive as ABS events (evdev open: usbhid polls).
        state = {ecodes.ABS_X: ev.absinfo(ecodes.ABS_X).value, ecodes.ABS_Y: 0}
        with HidgSink(SINGLE, device=absolute_node) as sink:
            sink.move(0.1, 0.9)
            want = (3277, 29490)
            while (state[ecodes.ABS_X], state[ecodes.ABS_Y]) != want:
                left = deadline - time.monotonic()
                assert left > 0 and select.select([ev.fd], [], [], left)[0], (
                    f"evdev never showed {want}, last {state}"
                )
                for e in ev.read():
                    if e.type == ecodes.EV_ABS and e.code in state:
                        state[e.code] = e.value
    finally:
        ev.close()


# -- reports read back through hidapi ----------------------------------------------------


def test_exact_positions_and_clamping(absolute_node: str, vm_figures: dict[str, Any]) -> None:
    times_us = []
    with HostReader() as host, HidgSink(SINGLE, device=absolute_node) as sink:
        host.drain()
        for (nx, ny), want in SINGLE_CASES:
            t0 = time.perf_counter_ns()
            sink.move(nx, ny)
            times_us.append((time.perf_counter_ns() - t0) / 1000)
            report = host.read()
            assert report, f"no report for {(nx, ny)}: {sink.stats()}"
            assert len(report) == 5 and report[0] == 0
            assert xy(report) == want, f"{(nx, ny)}"
        # More moves for the figure: each one handed over while the host polls.
        for k in range(200):
            t0 = time.perf_counter_ns()
            sink.move((k % 100) / 100, 0.5)
            times_us.append((time.perf_counter_ns() - t0) / 1000)
            assert host.read()
        assert sink.stats()["dropped"] == 0
    vm_figures["vm_hidg_us_per_report"] = round(statistics.median(times_us), 1)


def test_multi_monitor_mapping(absolute_node: str) -> None:
    with HostReader() as host, HidgSink(RIGHT_MONITOR, device=absolute_node) as sink:
        host.drain()
        for (nx, ny), want in RIGHT_CASES:
            sink.move(nx, ny)
            assert xy(host.read()) == want, f"{(nx, ny)}"


def test_buttons_down_and_up(absolute_node: str) -> None:
    with HostReader() as host, HidgSink(SINGLE, device=absolute_node) as sink:
        host.drain()
        sink.move(0.25, 0.75)
        first = host.read()
        assert first[0] == 0 and xy(first) == (8192, 24575)
        seen = []
        for button, bit in (("left", 1), ("right", 2), ("middle", 4)):
            sink.press(button)
            r = host.read()
            seen.append(r[0])
            assert r[0] == bit and xy(r) == (8192, 24575)
            sink.release(button)
            assert host.read()[0] == 0
        sink.press("left")
        sink.press("middle")
        assert host.read()[0] == 1 and host.read()[0] == 5
        sink.close()  # releases both
        assert host.read()[0] == 0
        assert seen == [1, 2, 4]


def test_writes_do_not_block_when_the_host_is_not_reading(absolute_node: str) -> None:
    """Nobody has the device open on the host, so usbhid does not poll: reports are dropped."""
    n = 100
    with HidgSink(SINGLE, device=absolute_node, timeout_ms=20) as sink:
        for k in range(n):
            sink.move(k / n, 0.5)  # every position differs: one report per move
        stats = sink.stats()
        assert stats["reports"] + stats["dropped"] == n
        assert stats["reports"] <= 2, stats  # the kernel holds one report in flight
        assert stats["dropped"] >= n - 2
        # A host starts reading: it first gets the report the kernel held, then the
        # next write carries the latest state (the last move) with the new button.
        with HostReader() as host:
            stale = host.drain()
            assert len(stale) <= 1
            sink.press("left")
            report = host.read()
            assert report[0] == 1
            assert xy(report) == (32439, 16384)  # 0.99 * 1919 -> 1899.81 -> 32439.33
            assert sink.stats()["dropped"] == stats["dropped"]
            sink.release("left")
            assert host.read()[0] == 0


CHILD = textwrap.dedent(
    """
    import sys, time
    from omnidev.screen import ScreenMapping
    from omnidev.sinks import release_on_signals
    from omnidev.sinks.hidg_sink import open_hidg

    sink = open_hidg({"device": sys.argv[1]}, ScreenMapping.single(1920, 1080))
    with release_on_signals(sink):
        sink.move(0.5, 0.25)
        sink.press("left")
        print("pressed", flush=True)
        while True:
            time.sleep(1)
    """
)


def test_stuck_button_released_on_sigterm(absolute_node: str) -> None:
    with HostReader() as host:
        host.drain()
        child = subprocess.Popen(
            [sys.executable, "-c", CHILD, absolute_node],
            cwd=REPO,
            stdout=subprocess.PIPE,
            text=True,
        )
        try:
            assert child.stdout is not None and child.stdout.readline().strip() == "pressed"
            reports = host.drain()
            assert reports[-1][0] == 1 and xy(reports[-1]) == (16384, 8192)
            child.send_signal(signal.SIGTERM)
            assert child.wait(timeout=60) == 128 + signal.SIGTERM
        finally:
            if child.poll() is None:
                child.kill()
        final = host.drain()
        assert final, "no report after SIGTERM"
        assert final[-1][0] == 0 and xy(final[-1]) == (16384, 8192)


def test_host_gone_is_reported(absolute_node: str) -> None:
    """A soft disconnect (the host sees the cable pulled): writes say the host is gone."""
    soft = Path(f"/sys/class/udc/{UDC}/soft_connect")
    sink = HidgSink(SINGLE, device=absolute_node)
    sink.move(0.3, 0.3)
    sink.press("left")
    soft.write_text("disconnect\n")
    try:
        with pytest.raises(HostGoneError, match="USB host has not configured the gadget"):
            for k in range(50):  # the disconnect reaches the function at once
                sink.move(k / 50, 0.6)
        sink.close()  # a vanished host holds no buttons: closing does not fail
        assert sink.closed and not sink.pressed
    finally:
        soft.write_text("connect\n")
        # dummy_hcd (6.1) does not re-enumerate after a soft connect ("device
        # descriptor read/64, error -71"); unbinding and binding the gadget does.
        (GADGET / "UDC").write_text("\n")
        (GADGET / "UDC").write_text(UDC + "\n")
    wait_for_host(PRODUCT["absolute"])
    with HostReader() as host, HidgSink(SINGLE, device=absolute_node) as again:
        host.drain()
        again.move(0.0, 1.0)
        assert xy(host.read()) == (0, 32767)


def test_sink_refuses_the_other_mode(absolute_node: str) -> None:
    with pytest.raises(SinkError, match="set up in absolute mode but the sink's mode is relative"):
        open_hidg({"device": absolute_node, "mode": "relative"}, SINGLE)


# -- relative mode, end to end -------------------------------------------------------------


def read_deltas(host: HostReader) -> tuple[int, int, list[list[int]]]:
    reports = host.drain(quiet_ms=1000)  # a burst under TCG can pause longer than 300 ms
    vals = [hr.decode_report(hr.RELATIVE_DESCRIPTOR, bytes(r)) for r in reports]
    return sum(v[(1, 0x30)] for v in vals), sum(v[(1, 0x31)] for v in vals), reports


def test_relative_mode_end_to_end() -> None:
    node = ensure_gadget("relative")
    import usb.core

    dev = usb.core.find(idVendor=VID, idProduct=PID)
    assert dev is not None
    intf = dev.get_active_configuration()[(0, 0)]
    assert (intf.bInterfaceClass, intf.bInterfaceSubClass, intf.bInterfaceProtocol) == (3, 1, 2)
    (sysdev,) = hid_sysfs()
    assert (sysdev / "report_descriptor").read_bytes() == hr.RELATIVE_DESCRIPTOR
    with pytest.raises(SinkError, match="set up in relative mode"):
        open_hidg({"device": node}, SINGLE)

    # A burst of 24 reports, each waiting for the host's next poll: under TCG on a loaded
    # machine a poll can take longer than the default 20 ms, and a dropped report's motion
    # goes out only with the next move (tested below), so this test gives the host 2 s.
    with (
        HostReader() as host,
        HidgSink(SINGLE, device=node, mode="relative", timeout_ms=2000) as sink,
    ):
        host.drain()
        # First move: the homing push by minus the layout size (1920, 1080), then
        # the target pixel (0.5 * 1919 = 959.5 -> 960, 0.5 * 1079 = 539.5 -> 540).
        sink.move(0.5, 0.5)
        dx, dy, reports = read_deltas(host)
        assert (dx, dy) == (960 - 1920, 540 - 1080)
        assert len(reports) == -(-1920 // 127) + -(-960 // 127)  # 16 + 8
        for r in reports:
            assert len(r) == 4 and r[0] == 0
        # Next: from (960, 540) to (0.25 * 1919, 0.75 * 1079) = (479.75, 809.25) -> (480, 809)
        sink.move(0.25, 0.75)
        assert read_deltas(host)[:2] == (480 - 960, 809 - 540)
        # Buttons: zero motion, bit set, then cleared on close.
        sink.press("right")
        dx, dy, reports = read_deltas(host)
        assert (dx, dy) == (0, 0) and [r[0] for r in reports] == [2]
        # Far jump, clamped: to (1919, 0)
        sink.move(3.0, -1.0)
        assert read_deltas(host)[:2] == (1919 - 480, 0 - 809)
        assert sink.stats()["dropped"] == 0, sink.stats()
        sink.close()
        dx, dy, reports = read_deltas(host)
        assert (dx, dy) == (0, 0) and reports[-1][0] == 0


def test_relative_mode_dropped_motion_is_sent_later() -> None:
    """Deltas dropped while nobody reads are not lost: the next write carries them.

    Linux's usbhid discards what arrives in the first 50 ms after a reader opens the
    device ("events generated while nobody was listening"), which includes the one
    report the gadget held; so the truth is counted from the last move the sink
    handed over (its ``reports`` counter rose), not from what the reader saw then.
    """
    node = ensure_gadget("relative")
    with HidgSink(SINGLE, device=node, mode="relative", home=False) as sink:
        # home=False: the sink assumes the pointer starts at (0, 0).
        handed_over_at = (0, 0)
        for k in range(1, 41):
            before = sink.stats()["reports"]
            sink.move(k / 100, k / 200)  # pixel (k / 100 * 1919, k / 200 * 1079)
            if sink.stats()["reports"] > before:
                handed_over_at = (round(k / 100 * 1919), round(k / 200 * 1079))
        stats = sink.stats()
        assert stats["dropped"] >= 30 and stats["reports"] + stats["dropped"] == 40, stats
        with HostReader() as host:
            host.drain()
            sink.press("left")
            dx, dy, got = read_deltas(host)
            # The last move ends at (0.4 * 1919, 0.2 * 1079) = (767.6, 215.8) -> (768, 216).
            want = (768 - handed_over_at[0], 216 - handed_over_at[1])
            assert (dx, dy) == want, f"{got} {stats}"
            assert all(r[0] == 1 for r in got)


def test_remove_tears_the_gadget_down() -> None:
    ensure_gadget("relative")
    res = run_script("--remove", udc=None)
    assert res.returncode == 0 and "removed" in res.stdout
    _state["mode"] = None
    assert not GADGET.exists()
    again = run_script("--remove", udc=None)
    assert again.returncode == 0 and "nothing to remove" in again.stdout
    deadline = time.monotonic() + 30
    while hid_devices() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not hid_devices(), "the host still lists the gadget after --remove"
