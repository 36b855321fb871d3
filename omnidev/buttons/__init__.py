"""Pointer buttons from other inputs: dwell clicks and keys / HID remotes.

- :class:`DwellClicker` (pure): one click when the cursor rests.
- :func:`open_buttons` (``evdev:...`` or ``hid:VVVV:PPPP?...``): a
  :class:`ButtonInput` polled for ``(button, down)`` events; see docs/buttons.md.
"""

from omnidev.buttons.dwell import BUTTONS, DwellClicker
from omnidev.buttons.inputs import ButtonEvent, ButtonInput, ButtonInputError, open_buttons
from omnidev.buttons.spec import parse_spec

__all__ = [
    "BUTTONS",
    "ButtonEvent",
    "ButtonInput",
    "ButtonInputError",
    "DwellClicker",
    "open_buttons",
    "parse_spec",
]
