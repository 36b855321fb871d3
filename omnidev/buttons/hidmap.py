"""Which pointer buttons one HID input report holds down (pure: no devices).

A ``hid:`` button input (see :mod:`omnidev.buttons.spec`) maps parts of the input
reports a HID device sends to pointer buttons, in two ways:

- **bits**: ``bN.M`` is bit M (0 = least significant) of byte N of the report as
  read (byte 0 is the report ID when the device numbers its reports). For a
  device with plain button bits (a vendor remote, a mouse-like device).
- **keyboard usages**: ``key.0xHH`` is the HID keyboard usage HH (HID Usage
  Tables, page 0x07: 0x4E PageDown, 0x4B PageUp, 0x3E F5, 0x29 Escape, 0x05 B,
  0x37 period) in a boot-keyboard style report: a modifier byte, a reserved byte,
  then key slots each holding the usage of one key down (0 = none). The key is
  down when any slot holds it; the modifiers 0xE0-0xE7 (left Ctrl .. right GUI)
  are the bits 0-7 of the modifier byte. Presenter remotes are usually keyboards
  and send exactly these reports.

A report whose first byte is not ``report_id`` (when one is set) is not for this
map; a keyboard report with every slot at 0x01 (ErrorRollOver: too many keys)
carries no key state. Both decode to None, meaning "no change".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

ROLLOVER = 0x01  # HID keyboard usage "ErrorRollOver", sent in every slot on phantom state
MODIFIER_FIRST, MODIFIER_LAST = 0xE0, 0xE7


@dataclass(frozen=True, slots=True)
class BitSource:
    """Bit ``bit`` (0..7) of byte ``byte`` of the report as read, held down = 1."""

    byte: int
    bit: int
    button: str


@dataclass(frozen=True, slots=True)
class KeySource:
    """HID keyboard usage ``usage`` (page 0x07) in a boot-keyboard style report."""

    usage: int
    button: str


@dataclass(frozen=True, slots=True)
class HidButtonMap:
    """Report bits and keyboard usages -> pointer buttons.

    Attributes:
        bits: the bit sources.
        keys: the keyboard-usage sources.
        report_id: decode only reports whose byte 0 is this ID (None: every report).
        keys_at: the byte index of the first key slot; the modifier byte is two
            before it. Default: 2, or 3 when ``report_id`` is set (the ID comes first).
    """

    bits: tuple[BitSource, ...] = ()
    keys: tuple[KeySource, ...] = ()
    report_id: int | None = None
    keys_at: int | None = None

    @property
    def key_offset(self) -> int:
        """Byte index of the first key slot in a report as read."""
        if self.keys_at is not None:
            return self.keys_at
        return 3 if self.report_id is not None else 2

    def buttons(self) -> tuple[str, ...]:
        """Every button this map can press, in the order the sources were given."""
        seen: dict[str, None] = {}
        for s in self.bits:
            seen.setdefault(s.button, None)
        for k in self.keys:
            seen.setdefault(k.button, None)
        return tuple(seen)

    def pressed(self, report: Sequence[int] | bytes) -> frozenset[str] | None:
        """The buttons ``report`` holds down, or None when the report is not for this map.

        Bytes a short report lacks count as 0 (nothing down).

        Example (a boot keyboard report: PageDown down, left Shift held):
            >>> m = HidButtonMap(keys=(KeySource(0x4E, "left"), KeySource(0xE1, "right")))
            >>> sorted(m.pressed([0x02, 0, 0x4E, 0, 0, 0, 0, 0]))
            ['left', 'right']
        """
        data = bytes(report)
        if self.report_id is not None and (not data or data[0] != self.report_id):
            return None
        down: set[str] = set()
        for b in self.bits:
            if b.byte < len(data) and data[b.byte] >> b.bit & 1:
                down.add(b.button)
        if self.keys:
            start = self.key_offset
            slots = data[start:]
            if slots and all(s == ROLLOVER for s in slots):
                return None
            mod_at = start - 2
            modifiers = data[mod_at] if 0 <= mod_at < len(data) else 0
            held = set(slots)
            for k in self.keys:
                if MODIFIER_FIRST <= k.usage <= MODIFIER_LAST:
                    if modifiers >> (k.usage - MODIFIER_FIRST) & 1:
                        down.add(k.button)
                elif k.usage in held:
                    down.add(k.button)
        return frozenset(down)
