"""Parse a button-input spec (pure: no devices); errors are one-line ConfigErrors.

Syntax (docs/buttons.md has examples)::

    evdev:/dev/input/eventN[?KEY=BUTTON&...][&grab=1]
    evdev:name=DEVICE NAME[?KEY=BUTTON&...][&grab=1]
    hid:VVVV:PPPP[?SOURCE=BUTTON&...][&report=ID][&keys_at=N][&interface=N]
                 [&serial=S][&backend=auto|hidraw|libusb]

- BUTTON is ``left``, ``right`` or ``middle``.
- evdev KEY is a Linux key name (``KEY_SPACE``, ``KEY_PAGEDOWN``, ``BTN_LEFT``) or
  a decimal key code; with no KEY given the map is ``KEY_SPACE=left``. ``grab=1``
  takes the device for omnidev alone (its keys then reach no other program).
- hid SOURCE is ``bN.M`` (byte N bit M of the report) or ``key.0xHH`` (a HID
  keyboard usage), see :mod:`omnidev.buttons.hidmap`; at least one is required.
- Values may be percent-encoded (``name=My%20Remote`` or ``name=My Remote``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from urllib.parse import unquote

from omnidev.buttons.dwell import BUTTONS
from omnidev.buttons.hidmap import BitSource, HidButtonMap, KeySource
from omnidev.errors import ConfigError

DEFAULT_EVDEV_KEYS: tuple[tuple[str, str], ...] = (("KEY_SPACE", "left"),)
HID_BACKENDS = ("auto", "hidraw", "libusb")
_KEY_NAME = re.compile(r"^(KEY|BTN)_[A-Z0-9_]+$")
_BIT = re.compile(r"^b(\d+)\.(\d+)$")
_USAGE = re.compile(r"^key\.(0[xX][0-9a-fA-F]+|\d+)$")
_ID = re.compile(r"^[0-9a-fA-F]{1,4}$")


@dataclass(frozen=True, slots=True)
class EvdevSpec:
    """An ``evdev:`` input: the node ``path`` or the device ``name``; key name -> button."""

    spec: str
    path: str | None
    name: str | None
    keys: tuple[tuple[str, str], ...]
    grab: bool


@dataclass(frozen=True, slots=True)
class HidSpec:
    """A ``hid:`` input: USB/Bluetooth vendor and product IDs, which device, the map."""

    spec: str
    vendor_id: int
    product_id: int
    serial: str | None
    interface: int | None
    backend: str
    map: HidButtonMap


def _bad(spec: str, what: str) -> ConfigError:
    return ConfigError(f"button input {spec!r}: {what}")


def _query(spec: str, query: str) -> list[tuple[str, str]]:
    items = []
    for part in query.split("&"):
        if not part:
            continue
        key, eq, value = part.partition("=")
        if not eq or not key:
            raise _bad(spec, f"{part!r} is not KEY=VALUE")
        items.append((unquote(key), unquote(value)))
    return items


def _button(spec: str, key: str, value: str) -> str:
    if value not in BUTTONS:
        raise _bad(spec, f"{key}={value!r}: the button must be one of {', '.join(BUTTONS)}")
    return value


def _int(spec: str, key: str, value: str, lo: int, hi: int) -> int:
    try:
        n = int(value, 0)
    except ValueError:
        raise _bad(spec, f"{key}={value!r} is not an integer") from None
    if not lo <= n <= hi:
        raise _bad(spec, f"{key}={value} is outside {lo}..{hi}")
    return n


def _flag(spec: str, key: str, value: str) -> bool:
    if value not in ("0", "1"):
        raise _bad(spec, f"{key}={value!r}: use {key}=1 or {key}=0")
    return value == "1"


def parse_evdev(spec: str, target: str, query: str) -> EvdevSpec:
    """The ``evdev:`` spec ``spec`` (``target`` before ``?``, ``query`` after)."""
    path = name = None
    if target.startswith("/"):
        path = target
    elif target.startswith("name="):
        name = unquote(target[5:])
        if not name:
            raise _bad(spec, "name= is empty")
    else:
        raise _bad(spec, "after evdev: give a node (/dev/input/eventN) or name=DEVICE NAME")
    keys: dict[str, str] = {}
    grab = False
    for key, value in _query(spec, query):
        if key == "grab":
            grab = _flag(spec, key, value)
        elif _KEY_NAME.match(key) or key.isdigit():
            if key in keys:
                raise _bad(spec, f"{key} is mapped twice")
            keys[key] = _button(spec, key, value)
        else:
            raise _bad(
                spec, f"{key!r} is neither a key name (KEY_SPACE, BTN_LEFT, a code) nor grab"
            )
    return EvdevSpec(spec, path, name, tuple(keys.items()) or DEFAULT_EVDEV_KEYS, grab)


def parse_hid(spec: str, target: str, query: str) -> HidSpec:
    """The ``hid:`` spec ``spec`` (``target`` = ``VVVV:PPPP`` before ``?``)."""
    vid, colon, pid = target.partition(":")
    if not (colon and _ID.match(vid) and _ID.match(pid)):
        raise _bad(spec, f"{target!r} is not VVVV:PPPP (hex vendor and product IDs)")
    bits: list[BitSource] = []
    keys: list[KeySource] = []
    seen: set[tuple[str, int, int]] = set()
    opts: dict[str, str] = {}
    for key, value in _query(spec, query):
        if m := _BIT.match(key):
            byte, bit = int(m.group(1)), int(m.group(2))
            if byte > 63 or bit > 7:
                raise _bad(spec, f"{key}: byte must be 0..63 and bit 0..7")
            if ("b", byte, bit) in seen:
                raise _bad(spec, f"{key} is mapped twice")
            seen.add(("b", byte, bit))
            bits.append(BitSource(byte, bit, _button(spec, key, value)))
        elif m := _USAGE.match(key):
            usage = int(m.group(1), 0)
            if not 0x04 <= usage <= 0xE7:
                raise _bad(spec, f"{key}: keyboard usages are 0x04..0xE7")
            if ("k", usage, 0) in seen:
                raise _bad(spec, f"{key} is mapped twice")
            seen.add(("k", usage, 0))
            keys.append(KeySource(usage, _button(spec, key, value)))
        elif key in ("report", "keys_at", "interface", "serial", "backend"):
            if key in opts:
                raise _bad(spec, f"{key} is given twice")
            opts[key] = value
        else:
            raise _bad(
                spec,
                f"{key!r} is not bN.M, key.0xHH, report, keys_at, interface, serial or backend",
            )
    if not bits and not keys:
        raise _bad(spec, "no button mapping: add e.g. key.0x4e=left (PageDown) or b0.0=left")
    report_id = _int(spec, "report", opts["report"], 1, 255) if "report" in opts else None
    keys_at = _int(spec, "keys_at", opts["keys_at"], 2, 63) if "keys_at" in opts else None
    interface = _int(spec, "interface", opts["interface"], 0, 255) if "interface" in opts else None
    backend = opts.get("backend", "auto")
    if backend not in HID_BACKENDS:
        raise _bad(spec, f"backend={backend!r}: use one of {', '.join(HID_BACKENDS)}")
    serial = opts.get("serial")
    if serial == "":
        raise _bad(spec, "serial= is empty")
    hmap = HidButtonMap(tuple(bits), tuple(keys), report_id, keys_at)
    return HidSpec(spec, int(vid, 16), int(pid, 16), serial, interface, backend, hmap)


def parse_spec(spec: str) -> EvdevSpec | HidSpec:
    """Parse ``spec``; raises ConfigError (one line naming the spec) when it is wrong.

    Example:
        >>> parse_spec("hid:046d:c538?key.0x4e=left&key.0x4b=right").map.buttons()
        ('left', 'right')
        >>> parse_spec("evdev:/dev/input/event3").keys
        (('KEY_SPACE', 'left'),)
    """
    if not isinstance(spec, str) or not spec.strip():
        raise ConfigError(f"button input {spec!r}: empty; use evdev:... or hid:VVVV:PPPP?...")
    kind, colon, rest = spec.strip().partition(":")
    target, _, query = rest.partition("?")
    if kind == "evdev" and colon:
        return parse_evdev(spec, target, query)
    if kind == "hid" and colon:
        return parse_hid(spec, target, query)
    raise _bad(spec, "unknown kind: use evdev:/dev/input/eventN?KEY=BUTTON or hid:VVVV:PPPP?...")
