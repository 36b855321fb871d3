"""Pointer-button inputs: the :class:`ButtonInput` protocol and :func:`open_buttons`.

A button input turns presses on another device (a keyboard key, a presenter
remote) into pointer button events ``(button, down)`` with ``button`` one of
``left``, ``right``, ``middle``. It is polled without blocking, e.g. once per
camera frame, and every button it reported down is reported up by ``close()``, so
nothing stays pressed when omnidev stops.

The adapters live in their own modules and import their OS binding only when
opened, so this module imports on any machine:

- ``evdev:...`` -> :mod:`omnidev.buttons.evdev_keys` (python-evdev)
- ``hid:...``   -> :mod:`omnidev.buttons.hid_buttons` (hidapi)

The spec syntax is in :mod:`omnidev.buttons.spec` and docs/buttons.md.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Protocol, runtime_checkable

from omnidev.buttons.dwell import BUTTONS
from omnidev.buttons.spec import EvdevSpec, parse_spec
from omnidev.errors import OmnidevError

ButtonEvent = tuple[str, bool]  # (button, down)


class ButtonInputError(OmnidevError):
    """A button input device that cannot be opened or read (missing, no permission, gone)."""


@runtime_checkable
class ButtonInput(Protocol):
    """A source of pointer button events."""

    def poll(self) -> list[ButtonEvent]:
        """Events since the last poll, in order; never blocks.

        When the device goes away, one poll returns the releases of the buttons
        still down and the next raises :class:`ButtonInputError`.
        """
        ...

    def close(self) -> list[ButtonEvent]:
        """Stop reading; returns the releases ``(button, False)`` of every button
        still reported down (in the order they were pressed). Idempotent."""
        ...


class ButtonStates:
    """Which pointer buttons are down, from which sources; turns changes into events.

    A button is down while any of its sources (keys, report bits) is down, so two
    keys mapped to one button give one press and one release.
    """

    def __init__(self) -> None:
        self.down: list[str] = []  # in press order

    def set_pressed(self, pressed: Iterable[str]) -> list[ButtonEvent]:
        """Make exactly ``pressed`` down: releases first, then presses, in BUTTONS order."""
        want = set(pressed)
        events: list[ButtonEvent] = [
            (b, False) for b in BUTTONS if b in self.down and b not in want
        ]
        events += [(b, True) for b in BUTTONS if b in want and b not in self.down]
        for b, down in events:
            if down:
                self.down.append(b)
            else:
                self.down.remove(b)
        return events

    def release_all(self) -> list[ButtonEvent]:
        """Release every button down, in press order."""
        events = [(b, False) for b in self.down]
        self.down.clear()
        return events


def open_buttons(spec: str) -> ButtonInput:
    """Open the button input ``spec`` (``evdev:...`` or ``hid:VVVV:PPPP?...``).

    Raises:
        omnidev.errors.ConfigError: the spec is malformed (one line naming it).
        ButtonInputError: the device is missing, unreadable, or its binding absent.
    """
    parsed = parse_spec(spec)
    if isinstance(parsed, EvdevSpec):
        from omnidev.buttons.evdev_keys import open_evdev_keys

        return open_evdev_keys(parsed)
    from omnidev.buttons.hid_buttons import open_hid_buttons

    return open_hid_buttons(parsed)
