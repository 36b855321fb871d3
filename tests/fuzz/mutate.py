"""Malformed variants of a valid input file, each with what the CLI must do with it.

Classes (the issue's list): empty, binary, non-UTF-8, NUL bytes, truncated,
NaN/inf, 1e308, negative, huge numbers, deeply nested, a folder, a symlink
loop, /dev/zero, a dangling symlink, unreadable to a non-root user, a 4 GiB
(sparse) file. A variant that can still be a valid file (a truncated CSV that
ends at a line break, a negative world coordinate) is ``expect="any"``: it may
be accepted, but never with a traceback, a hang or a memory blow-up.
"""

from __future__ import annotations

import random
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Literal

from tests.fuzz.harness import FileSpec, Unreadable

Expect = Literal["refuse", "any"]

NUMBER = re.compile(rb"(?<![\w.\-])-?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?(?![\w.])")
"""A number token (not one inside a word such as ``cam0`` or ``omni_0000``)."""

NON_FINITE: dict[str, bytes] = {"NaN": b"nan", "-inf": b"-inf", "1e400": b"1e400"}
"""Replacements that no reader may accept (1e400 overflows to inf)."""
EXTREME: dict[str, bytes] = {
    "1e308": b"1e308",
    "negative": b"-1",
    "huge int": b"123456789012345678901234567890",
    "denormal": b"5e-324",
}
"""Replacements a reader may accept where the value is legal."""


@dataclass(frozen=True)
class Variant:
    what: str
    spec: FileSpec
    expect: Expect


def nested(ext: str, depth: int = 50_000) -> bytes | None:
    """A document of the file's syntax nested ``depth`` levels deep (None: no nesting syntax)."""
    if ext in (".json", ".jsonl"):
        return b"[" * depth + b"]" * depth + b"\n"
    if ext == ".toml":
        return b"a = " + b"[" * depth + b"]" * depth + b"\n"
    if ext in (".yml", ".yaml"):
        return b"%YAML:1.0\n---\na: " + b"[" * depth + b"]" * depth + b"\n"
    if ext == ".xml":
        return (
            b'<?xml version="1.0"?>\n<opencv_storage>'
            + b"<a>" * depth
            + b"</a>" * depth
            + (b"</opencv_storage>\n")
        )
    return None


def _insert(seed: bytes, at: float, junk: bytes) -> bytes:
    """``junk`` inserted at the line start nearest ``at`` (a fraction of the length) + 2."""
    i = int(len(seed) * at)
    nl = seed.find(b"\n", i)
    i = nl + 3 if 0 <= nl < len(seed) - 3 else i
    return seed[:i] + junk + seed[i:]


TEXT_VALUE = re.compile(rb"^[A-Za-z_]\w*[ \t]*[:=][ \t]*\"?[A-Za-z][\w-]*", re.M)
"""The first ``key: word`` (YAML) or ``key = "word"`` (TOML) line's word."""


def number_positions(seed: bytes, count: int) -> list[re.Match[bytes]]:
    """``count`` number tokens spread evenly over the file."""
    found = list(NUMBER.finditer(seed))
    if len(found) <= count:
        return found
    step = len(found) / count
    return [found[int(k * step + step / 2)] for k in range(count)]


def variants(
    seed: bytes,
    ext: str,
    *,
    text: bool = True,
    numbers: int = 4,
    numbers_refuse: bool = True,
    seed_no: int = 0,
) -> Iterator[Variant]:
    """Every malformed variant of ``seed`` (a file of extension ``ext``)."""
    rng = random.Random(seed_no)
    yield Variant("empty", b"", "refuse")
    yield Variant("binary", bytes(rng.getrandbits(8) for _ in range(3000)), "refuse")
    yield Variant("folder", "dir", "refuse")
    yield Variant("symlink loop", "symlink-loop", "refuse")
    yield Variant("/dev/zero", "dev-zero", "refuse")
    yield Variant("dangling symlink", "dangling", "refuse")
    yield Variant("4 GiB sparse file", "sparse", "refuse")
    yield Variant("unreadable (mode 000, as nobody)", Unreadable(seed), "refuse")
    for k in (1, 2, 3):
        yield Variant(f"truncated to {k}/4", seed[: len(seed) * k // 4], "any")
    yield Variant("truncated to 1 byte", seed[:1], "refuse" if text else "any")
    deep = nested(ext)
    if deep is not None:
        yield Variant("deeply nested", deep, "refuse")
    if not text:
        mid = len(seed) // 2
        yield Variant("bytes flipped", seed[:mid] + bytes(b ^ 0xFF for b in seed[mid:]), "any")
        return
    yield Variant("non-UTF-8 byte", _insert(seed, 0.4, b"\xff\xfe"), "refuse")
    yield Variant("Latin-1 text", _insert(seed, 0.0, b"# caf\xe9\n"), "refuse")
    word = TEXT_VALUE.search(seed)
    if word is not None:  # inside a value the reader decodes (found by the full fuzz sweep)
        cut = word.end()
        yield Variant("non-UTF-8 byte in a text value", seed[:cut] + b"\xde" + seed[cut:], "refuse")
    yield Variant("NUL byte", _insert(seed, 0.5, b"\x00"), "refuse")
    for m in number_positions(seed, numbers):
        where = f"number {m.group().decode()!r} at byte {m.start()}"
        for name, value in NON_FINITE.items():
            v = seed[: m.start()] + value + seed[m.end() :]
            yield Variant(f"{where} -> {name}", v, "refuse" if numbers_refuse else "any")
        for name, value in EXTREME.items():
            yield Variant(f"{where} -> {name}", seed[: m.start()] + value + seed[m.end() :], "any")


KEY_LINE = re.compile(
    rb"^([ \t]*)([A-Za-z_][\w.]*)([ \t]*:[ \t]*)(-?[\d.]+(?:[eE][-+]?\d+)?)[ \t]*$", re.M
)
"""A ``key: number`` line of a YAML file (top level or indented)."""
KEY_VALUES: tuple[tuple[str, bytes, Expect], ...] = (
    ("NaN", b".nan", "refuse"),
    ("-1", b"-1", "any"),
    ("1e9", b"1.0e+9", "any"),
)
"""What every number key of a calibration file is set to (NaN must be refused)."""


INFORMATIONAL_KEYS = ("radial_rms_px", "reprojection_rms_px", "heldout_rms_px", "n", "tilt_deg")
"""Keys a loader does not read (fit figures for people; ``n`` of a format-2 screen file; a
generalized pano table's ``tilt_deg``, the angle of the ``tilt_rad`` it reads): any value may
be accepted there, as long as nothing crashes."""


def key_variants(seed: bytes, skip: tuple[str, ...] = ("rows", "cols")) -> Iterator[Variant]:
    """The seed with each ``key: number`` value replaced by each of :data:`KEY_VALUES`."""
    for m in KEY_LINE.finditer(seed):
        key = m.group(2).decode()
        if key in skip:
            continue
        for name, value, expect_ in KEY_VALUES:
            expect: Expect = "any" if key in INFORMATIONAL_KEYS else expect_
            blob = seed[: m.start(4)] + value + seed[m.end(4) :]
            yield Variant(f"key {key} -> {name}", blob, expect)
