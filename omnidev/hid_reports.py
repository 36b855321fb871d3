"""USB HID report descriptors and report packing for the ``hidg`` sink (pure: no devices).

omnidev's USB gadget is a mouse in one of two modes (one source of truth for both
the sink and ``udev/omnidev-gadget.sh``, whose embedded hex a test compares with
this module):

- *absolute* (the default): 3 buttons, 5 bits of padding, X and Y as 16-bit
  absolute values 0 .. :data:`~omnidev.screen.ABS_MAX` (32767) spanning the
  host's whole desktop layout. One report is 5 bytes, no report ID:
  ``[buttons, X lo, X hi, Y lo, Y hi]`` (little-endian, as HID requires). The
  layout is that of QEMU's ``usb-tablet`` without its wheel, which Linux,
  Windows and macOS hosts accept as an absolute pointer.
- *relative* (fallback for hosts, e.g. BIOS/UEFI setups or KVM switches, that
  reject absolute mice): 3 buttons, 5 bits of padding, X, Y and wheel as signed
  8-bit deltas -127 .. 127 in mouse counts. One report is 4 bytes; its first three
  bytes are the HID boot-protocol mouse report, so the gadget can declare the boot
  subclass.

Buttons are a bit mask: bit 0 left, bit 1 right, bit 2 middle (HID Button usages
1, 2, 3).

The small parser (:func:`parse_items`, :func:`input_fields`, :func:`decode_report`)
reads short items as the HID 1.11 specification (section 6.2.2) defines them, so
tests can check a descriptor item by item and decode packed reports through the
descriptor rather than through the packing code.

Command line (used to regenerate the hex embedded in the gadget script)::

    python -m omnidev.hid_reports --descriptor absolute > report_desc   # binary
    python -m omnidev.hid_reports --descriptor relative --hex           # hex text
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from omnidev.screen import ABS_MAX

Mode = Literal["absolute", "relative"]
MODES: tuple[Mode, ...] = ("absolute", "relative")

BUTTON_BITS = {"left": 0x01, "right": 0x02, "middle": 0x04}
REL_MAX = 127  # largest |delta| of one relative report, counts

# fmt: off
ABSOLUTE_DESCRIPTOR = bytes([
    0x05, 0x01,        # Usage Page (Generic Desktop)
    0x09, 0x02,        # Usage (Mouse)
    0xA1, 0x01,        # Collection (Application)
    0x09, 0x01,        #   Usage (Pointer)
    0xA1, 0x00,        #   Collection (Physical)
    0x05, 0x09,        #     Usage Page (Button)
    0x19, 0x01,        #     Usage Minimum (1)
    0x29, 0x03,        #     Usage Maximum (3)
    0x15, 0x00,        #     Logical Minimum (0)
    0x25, 0x01,        #     Logical Maximum (1)
    0x95, 0x03,        #     Report Count (3)
    0x75, 0x01,        #     Report Size (1)
    0x81, 0x02,        #     Input (Data, Variable, Absolute)
    0x95, 0x01,        #     Report Count (1)
    0x75, 0x05,        #     Report Size (5)
    0x81, 0x03,        #     Input (Constant, Variable, Absolute): padding
    0x05, 0x01,        #     Usage Page (Generic Desktop)
    0x09, 0x30,        #     Usage (X)
    0x09, 0x31,        #     Usage (Y)
    0x15, 0x00,        #     Logical Minimum (0)
    0x26, 0xFF, 0x7F,  #     Logical Maximum (32767)
    0x75, 0x10,        #     Report Size (16)
    0x95, 0x02,        #     Report Count (2)
    0x81, 0x02,        #     Input (Data, Variable, Absolute)
    0xC0,              #   End Collection
    0xC0,              # End Collection
])

RELATIVE_DESCRIPTOR = bytes([
    0x05, 0x01,        # Usage Page (Generic Desktop)
    0x09, 0x02,        # Usage (Mouse)
    0xA1, 0x01,        # Collection (Application)
    0x09, 0x01,        #   Usage (Pointer)
    0xA1, 0x00,        #   Collection (Physical)
    0x05, 0x09,        #     Usage Page (Button)
    0x19, 0x01,        #     Usage Minimum (1)
    0x29, 0x03,        #     Usage Maximum (3)
    0x15, 0x00,        #     Logical Minimum (0)
    0x25, 0x01,        #     Logical Maximum (1)
    0x95, 0x03,        #     Report Count (3)
    0x75, 0x01,        #     Report Size (1)
    0x81, 0x02,        #     Input (Data, Variable, Absolute)
    0x95, 0x01,        #     Report Count (1)
    0x75, 0x05,        #     Report Size (5)
    0x81, 0x03,        #     Input (Constant, Variable, Absolute): padding
    0x05, 0x01,        #     Usage Page (Generic Desktop)
    0x09, 0x30,        #     Usage (X)
    0x09, 0x31,        #     Usage (Y)
    0x09, 0x38,        #     Usage (Wheel)
    0x15, 0x81,        #     Logical Minimum (-127)
    0x25, 0x7F,        #     Logical Maximum (127)
    0x75, 0x08,        #     Report Size (8)
    0x95, 0x03,        #     Report Count (3)
    0x81, 0x06,        #     Input (Data, Variable, Relative)
    0xC0,              #   End Collection
    0xC0,              # End Collection
])
# fmt: on

ABSOLUTE_REPORT_LENGTH = 5  # bytes
RELATIVE_REPORT_LENGTH = 4  # bytes

DESCRIPTORS: dict[Mode, bytes] = {"absolute": ABSOLUTE_DESCRIPTOR, "relative": RELATIVE_DESCRIPTOR}
REPORT_LENGTHS: dict[Mode, int] = {
    "absolute": ABSOLUTE_REPORT_LENGTH,
    "relative": RELATIVE_REPORT_LENGTH,
}
# USB interface subclass the gadget declares: 1 (boot interface) only where the
# report starts with the boot-protocol mouse layout.
SUBCLASSES: dict[Mode, int] = {"absolute": 0, "relative": 1}
PROTOCOL_MOUSE = 2  # USB HID interface protocol: mouse


def descriptor(mode: str) -> bytes:
    """The report descriptor of ``mode`` (``absolute`` or ``relative``)."""
    for m in MODES:
        if m == mode:
            return DESCRIPTORS[m]
    raise ValueError(f"HID mode {mode!r} is not one of: {', '.join(MODES)}")


def buttons_mask(pressed: set[str] | frozenset[str]) -> int:
    """The report's button bits for a set of button names (left, right, middle).

    >>> buttons_mask({"left", "middle"})
    5
    """
    return sum(BUTTON_BITS[b] for b in pressed)


def pack_absolute(buttons: int, x: int, y: int) -> bytes:
    """One 5-byte absolute report; ``x``, ``y`` in device units, clamped to 0 .. 32767.

    >>> list(pack_absolute(1, 16000, 8000))
    [1, 128, 62, 64, 31]
    """
    _check_buttons(buttons)
    x = min(max(int(x), 0), ABS_MAX)
    y = min(max(int(y), 0), ABS_MAX)
    return bytes((buttons, x & 0xFF, x >> 8, y & 0xFF, y >> 8))


def pack_relative(buttons: int, dx: int, dy: int, wheel: int = 0) -> list[bytes]:
    """Relative reports (4 bytes each) that move by (``dx``, ``dy``) counts in total.

    A delta beyond ±127 is split over the fewest reports that fit, in equal steps
    along the straight line (integer steps whose sums are exactly ``dx``, ``dy``);
    every report carries ``buttons``. The wheel (clicks, clamped to ±127) goes in
    the first report. Zero motion still gives one report (a button change).

    >>> [list(r) for r in pack_relative(1, 300, -10)]
    [[1, 100, 252, 0], [1, 100, 253, 0], [1, 100, 253, 0]]
    """
    _check_buttons(buttons)
    dx, dy = int(dx), int(dy)
    n = max(1, -(-max(abs(dx), abs(dy)) // REL_MAX))  # ceil
    wheel = min(max(int(wheel), -REL_MAX), REL_MAX)
    reports = []
    for i in range(n):
        sx = dx * (i + 1) // n - dx * i // n
        sy = dy * (i + 1) // n - dy * i // n
        reports.append(bytes((buttons, sx & 0xFF, sy & 0xFF, wheel & 0xFF)))
        wheel = 0
    return reports


def _check_buttons(buttons: int) -> None:
    if not 0 <= buttons <= 7:
        raise ValueError(f"button mask {buttons} is not 0..7 (bit 0 left, 1 right, 2 middle)")


# -- a small report-descriptor parser (HID 1.11, 6.2.2: short items) -------------------

ITEM_NAMES = {
    # (type, tag): name; type 0 main, 1 global, 2 local
    (0, 0x8): "Input",
    (0, 0x9): "Output",
    (0, 0xB): "Feature",
    (0, 0xA): "Collection",
    (0, 0xC): "End Collection",
    (1, 0x0): "Usage Page",
    (1, 0x1): "Logical Minimum",
    (1, 0x2): "Logical Maximum",
    (1, 0x3): "Physical Minimum",
    (1, 0x4): "Physical Maximum",
    (1, 0x5): "Unit Exponent",
    (1, 0x6): "Unit",
    (1, 0x7): "Report Size",
    (1, 0x8): "Report ID",
    (1, 0x9): "Report Count",
    (1, 0xA): "Push",
    (1, 0xB): "Pop",
    (2, 0x0): "Usage",
    (2, 0x1): "Usage Minimum",
    (2, 0x2): "Usage Maximum",
}
_GLOBALS_USED = {"Usage Page", "Logical Minimum", "Logical Maximum", "Report Size", "Report Count"}
_SIGNED = {"Logical Minimum", "Logical Maximum", "Physical Minimum", "Physical Maximum"}


@dataclass(frozen=True, slots=True)
class Item:
    """One short item: its name, raw data bytes, and value.

    ``value`` is signed (two's complement of the data size) for logical and
    physical extents, unsigned otherwise, as the HID specification says.
    """

    name: str
    data: bytes
    value: int


def parse_items(desc: bytes) -> list[Item]:
    """The short items of a report descriptor, in order; long items are rejected."""
    items: list[Item] = []
    i = 0
    while i < len(desc):
        prefix = desc[i]
        if prefix == 0xFE:
            raise ValueError(f"long item at byte {i}: not used by omnidev's descriptors")
        size = (0, 1, 2, 4)[prefix & 0x3]
        kind, tag = (prefix >> 2) & 0x3, prefix >> 4
        data = desc[i + 1 : i + 1 + size]
        if len(data) != size:
            raise ValueError(f"item at byte {i} needs {size} data bytes, descriptor ends")
        name = ITEM_NAMES.get((kind, tag))
        if name is None:
            raise ValueError(f"unknown item 0x{prefix:02x} at byte {i}")
        signed = name in _SIGNED
        items.append(Item(name, bytes(data), int.from_bytes(data, "little", signed=signed)))
        i += 1 + size
    return items


@dataclass(frozen=True, slots=True)
class Field:
    """One Input main item: where its values lie in a report and what they mean.

    Attributes:
        usage_page: the usage page in force (1 Generic Desktop, 9 Button).
        usages: one usage per value (empty for padding).
        bit_offset: first bit in the report (bit 0 = least significant bit of byte 0).
        size: bits per value; count: number of values.
        logical_min, logical_max: the value range.
        constant, relative: the Input item's flags (bit 0, bit 2).
    """

    usage_page: int
    usages: tuple[int, ...]
    bit_offset: int
    size: int
    count: int
    logical_min: int
    logical_max: int
    constant: bool
    relative: bool


def input_fields(desc: bytes) -> tuple[list[Field], int]:
    """The Input fields of a descriptor without report IDs, and the report length in bytes."""
    glob: dict[str, int] = {}
    usages: list[int] = []
    umin: int | None = None
    fields: list[Field] = []
    bit = 0
    for item in parse_items(desc):
        if item.name == "Report ID":
            raise ValueError("report IDs are not used by omnidev's descriptors")
        if item.name in _GLOBALS_USED:
            glob[item.name] = item.value
        elif item.name == "Usage":
            usages.append(item.value)
        elif item.name == "Usage Minimum":
            umin = item.value
        elif item.name == "Usage Maximum":
            if umin is None:
                raise ValueError("Usage Maximum without Usage Minimum")
            usages.extend(range(umin, item.value + 1))
        elif item.name == "Input":
            size, count = glob["Report Size"], glob["Report Count"]
            constant = bool(item.value & 0x01)
            fields.append(
                Field(
                    usage_page=glob.get("Usage Page", 0),
                    usages=() if constant else tuple(usages[:count]),
                    bit_offset=bit,
                    size=size,
                    count=count,
                    logical_min=glob.get("Logical Minimum", 0),
                    logical_max=glob.get("Logical Maximum", 0),
                    constant=constant,
                    relative=bool(item.value & 0x04),
                )
            )
            bit += size * count
        if item.name in ("Input", "Output", "Feature", "Collection", "End Collection"):
            usages, umin = [], None  # local items end with each main item
    if bit % 8:
        raise ValueError(f"input report is {bit} bits, not a whole number of bytes")
    return fields, bit // 8


def decode_report(desc: bytes, report: bytes) -> dict[tuple[int, int], int]:
    """Values of one input report by (usage page, usage), read through the descriptor.

    Signed fields (negative logical minimum) are sign-extended.

    >>> decode_report(ABSOLUTE_DESCRIPTOR, pack_absolute(1, 16000, 8000))[(1, 0x30)]
    16000
    """
    fields, length = input_fields(desc)
    if len(report) != length:
        raise ValueError(f"report is {len(report)} bytes, the descriptor says {length}")
    bits = int.from_bytes(report, "little")
    values: dict[tuple[int, int], int] = {}
    for f in fields:
        for k, usage in enumerate(f.usages):
            raw = (bits >> (f.bit_offset + k * f.size)) & ((1 << f.size) - 1)
            if f.logical_min < 0 and raw >> (f.size - 1):
                raw -= 1 << f.size
            values[(f.usage_page, usage)] = raw
    return values


def main(argv: Sequence[str] | None = None) -> int:
    """Write a descriptor to standard output, as binary or as hex text."""
    ap = argparse.ArgumentParser(prog="python -m omnidev.hid_reports", description=main.__doc__)
    ap.add_argument("--descriptor", choices=MODES, required=True)
    ap.add_argument("--hex", action="store_true", help="hex text (one line) instead of binary")
    args = ap.parse_args(argv)
    desc = descriptor(args.descriptor)
    if args.hex:
        sys.stdout.write(desc.hex() + "\n")
    else:
        sys.stdout.buffer.write(desc)
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
