"""The hidg sink's report descriptors and report packing, checked item by item.

Reports are decoded through the descriptor (omnidev.hid_reports.decode_report),
not through the packing code, so a descriptor and a packer that disagree fail.
The kernel-side checks (the host reading these reports) are in tests/vm/test_hidg.py.
"""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from omnidev import hid_reports as hr
from omnidev.errors import SinkError
from omnidev.screen import ScreenMapping
from tests.conftest import REPO

GD, BTN = 0x01, 0x09  # usage pages: Generic Desktop, Button
X, Y, WHEEL = 0x30, 0x31, 0x38

# The absolute descriptor written out by hand from the HID 1.11 spec and HID Usage
# Tables 1.12 (Generic Desktop 0x01: Mouse 0x02, Pointer 0x01, X 0x30, Y 0x31).
ABSOLUTE_ITEMS = [
    ("Usage Page", GD),
    ("Usage", 0x02),
    ("Collection", 0x01),
    ("Usage", 0x01),
    ("Collection", 0x00),
    ("Usage Page", BTN),
    ("Usage Minimum", 1),
    ("Usage Maximum", 3),
    ("Logical Minimum", 0),
    ("Logical Maximum", 1),
    ("Report Count", 3),
    ("Report Size", 1),
    ("Input", 0x02),
    ("Report Count", 1),
    ("Report Size", 5),
    ("Input", 0x03),
    ("Usage Page", GD),
    ("Usage", X),
    ("Usage", Y),
    ("Logical Minimum", 0),
    ("Logical Maximum", 32767),
    ("Report Size", 16),
    ("Report Count", 2),
    ("Input", 0x02),
    ("End Collection", 0),
    ("End Collection", 0),
]

RELATIVE_ITEMS = [
    *ABSOLUTE_ITEMS[:16],
    ("Usage Page", GD),
    ("Usage", X),
    ("Usage", Y),
    ("Usage", WHEEL),
    ("Logical Minimum", -127),
    ("Logical Maximum", 127),
    ("Report Size", 8),
    ("Report Count", 3),
    ("Input", 0x06),
    ("End Collection", 0),
    ("End Collection", 0),
]


@pytest.mark.parametrize(
    ("mode", "expected"), [("absolute", ABSOLUTE_ITEMS), ("relative", RELATIVE_ITEMS)]
)
def test_descriptor_items(mode, expected):
    items = [(i.name, i.value) for i in hr.parse_items(hr.descriptor(mode))]
    assert items == expected


def test_absolute_layout():
    fields, length = hr.input_fields(hr.ABSOLUTE_DESCRIPTOR)
    assert length == hr.ABSOLUTE_REPORT_LENGTH == 5
    buttons, pad, xy = fields
    assert (buttons.usage_page, buttons.usages, buttons.bit_offset, buttons.size) == (
        BTN,
        (1, 2, 3),
        0,
        1,
    )
    assert pad.constant and pad.bit_offset == 3 and pad.size * pad.count == 5
    assert (xy.usage_page, xy.usages, xy.bit_offset, xy.size, xy.count) == (GD, (X, Y), 8, 16, 2)
    assert (xy.logical_min, xy.logical_max, xy.relative) == (0, 32767, False)


def test_relative_layout():
    fields, length = hr.input_fields(hr.RELATIVE_DESCRIPTOR)
    assert length == hr.RELATIVE_REPORT_LENGTH == 4
    motion = fields[2]
    assert (motion.usages, motion.bit_offset, motion.size) == ((X, Y, WHEEL), 8, 8)
    assert (motion.logical_min, motion.logical_max, motion.relative) == (-127, 127, True)
    # boot-protocol mouse: byte 0 buttons, byte 1 dx, byte 2 dy
    assert hr.SUBCLASSES == {"absolute": 0, "relative": 1}


def test_pack_absolute_golden():
    # Read back through hidapi from a real gadget (shared/VM-TESTING.md): buttons=1,
    # X=16000, Y=8000 arrived as [1, 128, 62, 64, 31].
    assert list(hr.pack_absolute(1, 16000, 8000)) == [1, 128, 62, 64, 31]
    assert hr.pack_absolute(0, 0, 0) == bytes(5)
    assert hr.pack_absolute(7, 32767, 32767) == bytes([7, 0xFF, 0x7F, 0xFF, 0x7F])


@pytest.mark.parametrize("buttons", range(8))
def test_pack_absolute_decodes_through_descriptor(buttons):
    for x, y in [(0, 0), (1, 32766), (255, 256), (12345, 23456), (32767, 0)]:
        v = hr.decode_report(hr.ABSOLUTE_DESCRIPTOR, hr.pack_absolute(buttons, x, y))
        assert (v[(GD, X)], v[(GD, Y)]) == (x, y)
        assert [v[(BTN, b)] for b in (1, 2, 3)] == [(buttons >> k) & 1 for k in range(3)]


def test_pack_absolute_clamps():
    v = hr.decode_report(hr.ABSOLUTE_DESCRIPTOR, hr.pack_absolute(0, -50, 99999))
    assert (v[(GD, X)], v[(GD, Y)]) == (0, 32767)


@pytest.mark.parametrize(
    ("dx", "dy"),
    [(0, 0), (5, -7), (127, -127), (128, 0), (-128, 1), (300, -10), (-1919, 1079), (4000, 4000)],
)
def test_pack_relative_sums_to_the_delta(dx, dy):
    reports = hr.pack_relative(3, dx, dy)
    assert len(reports) == max(1, -(-max(abs(dx), abs(dy)) // 127))
    decoded = [hr.decode_report(hr.RELATIVE_DESCRIPTOR, r) for r in reports]
    assert sum(v[(GD, X)] for v in decoded) == dx
    assert sum(v[(GD, Y)] for v in decoded) == dy
    for v in decoded:
        assert -127 <= v[(GD, X)] <= 127 and -127 <= v[(GD, Y)] <= 127
        assert (v[(BTN, 1)], v[(BTN, 2)], v[(BTN, 3)]) == (1, 1, 0)
        assert v[(GD, WHEEL)] == 0


def test_pack_relative_wheel_in_first_report():
    reports = hr.pack_relative(0, 200, 0, wheel=-3)
    wheels = [hr.decode_report(hr.RELATIVE_DESCRIPTOR, r)[(GD, WHEEL)] for r in reports]
    assert wheels == [-3, 0]


def test_button_mask():
    assert hr.buttons_mask({"left"}) == 1
    assert hr.buttons_mask({"right"}) == 2
    assert hr.buttons_mask({"left", "right", "middle"}) == 7
    with pytest.raises(ValueError, match="0..7"):
        hr.pack_absolute(8, 0, 0)


def test_parser_rejects_a_truncated_descriptor():
    with pytest.raises(ValueError, match="descriptor ends"):
        cut = hr.ABSOLUTE_DESCRIPTOR.index(b"\x26\xff\x7f") + 2  # Logical Maximum, 1 of 2 bytes
        hr.parse_items(hr.ABSOLUTE_DESCRIPTOR[:cut])
    with pytest.raises(ValueError, match="unknown item"):
        hr.parse_items(bytes([0xF4]))


def test_descriptor_unknown_mode():
    with pytest.raises(ValueError, match="absolute, relative"):
        hr.descriptor("tablet")


def test_cli_writes_the_binary_descriptor():
    for mode in hr.MODES:
        out = subprocess.run(
            [sys.executable, "-m", "omnidev.hid_reports", "--descriptor", mode],
            capture_output=True,
            check=True,
        ).stdout
        assert out == hr.descriptor(mode)


def test_gadget_script_embeds_the_same_descriptors():
    """udev/omnidev-gadget.sh carries the descriptors as hex; they must be these bytes."""
    script = (REPO / "udev" / "omnidev-gadget.sh").read_text()

    def var(name: str) -> str:
        m = re.search(rf"^{name}=(\S+)$", script, re.MULTILINE)
        assert m, f"{name} missing from omnidev-gadget.sh"
        return m.group(1)

    for mode in hr.MODES:
        up = mode.upper()
        assert bytes.fromhex(var(f"{up}_DESC_HEX")) == hr.descriptor(mode)
        assert int(var(f"{up}_REPORT_LENGTH")) == hr.REPORT_LENGTHS[mode]
        assert int(var(f"{up}_SUBCLASS")) == hr.SUBCLASSES[mode]


def test_gadget_service_runs_the_installed_script():
    unit = (REPO / "udev" / "omnidev-gadget.service").read_text()
    assert "Type=oneshot" in unit and "RemainAfterExit=yes" in unit
    assert "ExecStart=/usr/local/lib/omnidev/omnidev-gadget.sh\n" in unit
    assert "ExecStop=/usr/local/lib/omnidev/omnidev-gadget.sh --remove\n" in unit
    assert re.search(r"^After=.*sys-kernel-config\.mount", unit, re.MULTILINE)


# -- the adapter's errors, on this machine (no gadget here) ------------------------------


def test_sink_module_imports_without_a_gadget():
    import omnidev.sinks.hidg_sink as hs

    assert hs.open_hidg.__doc__


def test_missing_node_says_how_to_set_up_the_gadget(tmp_path):
    from omnidev.sinks.hidg_sink import open_hidg

    with pytest.raises(SinkError, match=r"does not exist: .*omnidev-gadget\.(sh|service)"):
        open_hidg({"device": str(tmp_path / "hidg9")}, ScreenMapping.single(1920, 1080))


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"speed": 1}, "unknown option 'speed'"),
        ({"mode": "tablet"}, "'mode' is 'tablet'"),
        ({"timeout_ms": -1}, "'timeout_ms' is -1"),
        ({"home": "yes"}, "'home' is 'yes'"),
    ],
)
def test_bad_options(options, message):
    from omnidev.sinks.hidg_sink import open_hidg

    with pytest.raises(SinkError, match=re.escape(message)):
        open_hidg(options, ScreenMapping.single(1920, 1080))
