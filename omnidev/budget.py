"""Memory before allocation: estimates for views, tables and images, checked against a limit.

Every large array a command is asked for (an unwarping view's maps, a
pano-mapping table, a decoded image or video frame) is estimated here first,
and refused with the estimate when it would take the process past its limit:
a typo such as ``panorama:32768x32768`` is a one-line error, not 66 GiB.

The limit is the peak resident memory a command may reach, in bytes: half of
the machine's physical memory (at least :data:`MIN_DEFAULT`) unless
``--max-memory SIZE`` (every command has it) or the environment variable
``OMNIDEV_MAX_MEMORY`` says otherwise (``512M``, ``4G``, ``0`` for no limit).

>>> parse_memory("1.5G")
1610612736
>>> format_bytes(3 * 2**30)
'3.0 GiB'
"""

from __future__ import annotations

import os
import resource

from omnidev.errors import OmnidevError

MIN_DEFAULT = 1 << 30
"""The default limit on a machine whose memory cannot be read, bytes."""
ENV = "OMNIDEV_MAX_MEMORY"
_UNITS = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}

_limit: int | None = None
_start: int | None = None  # resident bytes when the command started (see start_command)
HOST_ALLOWANCE = 200 << 20
"""What a command started inside a larger process (a test run, a notebook) is charged for
the memory that process already held: the interpreter's own share, not all of it."""


class MemoryLimitError(OmnidevError):
    """An allocation that would pass the memory limit; the message gives the estimate."""


def parse_memory(text: str) -> int:
    """``"512M"``, ``"4G"``, ``"1.5g"``, ``"800000000"`` -> bytes; ``"0"`` means no limit."""
    t = text.strip().lower().removesuffix("ib").removesuffix("b")
    unit = t[-1:] if t[-1:] in _UNITS else ""
    number = t[: len(t) - len(unit)]
    try:
        value = float(number)
    except ValueError:
        raise OmnidevError(
            f"memory size {text!r}: give a number with K, M or G (e.g. 4G)"
        ) from None
    if not value >= 0 or value == float("inf"):
        raise OmnidevError(f"memory size {text!r}: must be a finite number >= 0")
    return int(value * _UNITS[unit])


def format_bytes(n: float) -> str:
    """Bytes in the largest binary unit that keeps the number >= 1."""
    for unit, size in (("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= size:
            return f"{n / size:.1f} {unit}"
    return f"{n:.0f} bytes"


def set_max_memory(limit: int | None) -> None:
    """Set the limit in bytes for this process (None: back to the default / environment)."""
    global _limit
    _limit = limit


def start_command() -> None:
    """Mark the start of a command: memory held before it counts as at most HOST_ALLOWANCE."""
    global _start
    _start = resident_bytes()


def in_use() -> int:
    """Memory charged to the running command now, bytes."""
    now = resident_bytes()
    if _start is None:
        return now
    return max(now - _start, 0) + min(_start, HOST_ALLOWANCE)


def max_memory() -> int:
    """The limit in force, bytes (0: none)."""
    if _limit is not None:
        return _limit
    env = os.environ.get(ENV)
    if env:
        return parse_memory(env)
    return default_max_memory()


def default_max_memory() -> int:
    """Half the physical memory, bytes (:data:`MIN_DEFAULT` when it cannot be read)."""
    try:
        total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return MIN_DEFAULT
    return max(MIN_DEFAULT, total // 2)


def resident_bytes() -> int:
    """This process's resident memory now, bytes (0 where /proc is absent)."""
    try:
        with open("/proc/self/statm", "rb") as fh:
            return int(fh.read().split()[1]) * resource.getpagesize()
    except (OSError, ValueError, IndexError):
        return 0


def check_memory(nbytes: float, what: str) -> None:
    """Refuse an allocation of about ``nbytes`` that would take the process past the limit.

    ``what`` says what is allocated ("view panorama:32768x32768"); the error gives
    the estimate, the limit and how to raise it.
    """
    limit = max_memory()
    if limit <= 0:
        return
    now = in_use()
    if now + nbytes > limit:
        raise MemoryLimitError(
            f"{what} needs about {format_bytes(nbytes)} of memory; with the "
            f"{format_bytes(now)} in use that passes the limit of {format_bytes(limit)} "
            f"(raise it with --max-memory SIZE, e.g. --max-memory "
            f"{max(2, int((now + nbytes) / (1 << 30)) + 1)}G)"
        )


def check_pixels(width: int, height: int, bytes_per_pixel: float, what: str) -> None:
    """:func:`check_memory` for a ``width`` x ``height`` array of ``bytes_per_pixel``."""
    check_memory(float(width) * float(height) * bytes_per_pixel, what)
