"""Find the /dev/input/eventN node of an input device through sysfs (stdlib only).

Input devices live in sysfs as ``/sys/class/input/inputN`` with the files
``name`` and ``phys`` and one ``eventM`` child per evdev handler; the node a
program opens is ``/dev/input/eventM``. The uinput sink names its device and
gives it a ``phys`` tag, so the daemon (and the tests) find it here by those.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

SYS_INPUT = Path("/sys/class/input")


@dataclass(frozen=True, slots=True)
class InputDeviceInfo:
    """One input device as sysfs shows it.

    Attributes:
        sysname: ``inputN``.
        name: the device name (``/sys/class/input/inputN/name``).
        phys: its physical path tag, ``""`` when it has none.
        event_node: ``/dev/input/eventM``, or None when no evdev handler is attached.
    """

    sysname: str
    name: str
    phys: str
    event_node: str | None


def _read(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8", errors="replace").strip()
    except OSError:
        return ""


def device_info(sysname: str, sys_input: Path = SYS_INPUT) -> InputDeviceInfo | None:
    """The device ``inputN`` (as returned by uinput's UI_GET_SYSNAME), or None if absent."""
    root = sys_input / sysname
    if not root.is_dir():
        return None
    events = sorted(
        (p.name for p in root.iterdir() if p.name.startswith("event")),
        key=lambda n: int(n[5:]) if n[5:].isdigit() else 0,
    )
    node = f"/dev/input/{events[0]}" if events else None
    return InputDeviceInfo(sysname, _read(root / "name"), _read(root / "phys"), node)


def list_devices(sys_input: Path = SYS_INPUT) -> list[InputDeviceInfo]:
    """Every ``inputN`` device, in order of N."""
    if not sys_input.is_dir():
        return []
    names = [p.name for p in sys_input.iterdir() if p.name.startswith("input")]
    names.sort(key=lambda n: int(n[5:]) if n[5:].isdigit() else 0)
    infos = (device_info(n, sys_input) for n in names)
    return [i for i in infos if i is not None]


def find_event_nodes(
    *, name: str | None = None, phys: str | None = None, sys_input: Path = SYS_INPUT
) -> list[str]:
    """The event nodes of the devices whose name and/or phys equal the given ones."""
    found = []
    for info in list_devices(sys_input):
        if name is not None and info.name != name:
            continue
        if phys is not None and info.phys != phys:
            continue
        if info.event_node is not None:
            found.append(info.event_node)
    return found
