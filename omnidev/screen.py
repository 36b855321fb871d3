"""Where a normalized pointer position lands: target screen, desktop layout, device range.

Frames (all pixel coordinates have x right, y down, origin at the top-left pixel's
center):

- *normalized*: (0, 0) the target screen's top-left pixel, (1, 1) its
  bottom-right pixel; what trackers produce (:class:`~omnidev.frame.PointerSample`).
- *layout*: pixels of the whole desktop (all monitors side by side, as X11's root
  window or a Wayland compositor's global space); a target screen is a
  :class:`ScreenRect` in it.
- *device*: the integer range an absolute device reports (0 .. 32767 for the
  uinput and hidg sinks), spanning the whole layout, so one device can reach
  every monitor: layout pixel p maps to round(p * max / (layout size - 1)).
"""

from __future__ import annotations

from dataclasses import dataclass

ABS_MAX = 32767  # the absolute range of omnidev's uinput and HID devices: 0 .. ABS_MAX


MAX_LAYOUT = 65535
"""Largest screen side and offset in pixels (X11 and uinput address 16 bits)."""


@dataclass(frozen=True, slots=True)
class ScreenRect:
    """A rectangle of the desktop layout, in layout pixels (x, y of its top-left pixel)."""

    x: int
    y: int
    width: int
    height: int

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ValueError(f"screen rectangle {self.width}x{self.height} is empty")
        if self.x < 0 or self.y < 0:
            raise ValueError(f"screen rectangle origin ({self.x}, {self.y}) is negative")

    @classmethod
    def parse(cls, text: str) -> ScreenRect:
        """``WxH+X+Y`` (X11 geometry) or ``WxH`` (at 0, 0).

        >>> ScreenRect.parse("1920x1080+2560+0")
        ScreenRect(x=2560, y=0, width=1920, height=1080)
        """
        size, _, offset = text.strip().partition("+")
        try:
            w, h = (int(s) for s in size.lower().split("x"))
            x, y = (int(s) for s in offset.split("+")) if offset else (0, 0)
        except ValueError:
            raise ValueError(f"screen {text!r} is not WxH+X+Y (e.g. 1920x1080+0+0)") from None
        if not (
            0 < w <= MAX_LAYOUT
            and 0 < h <= MAX_LAYOUT
            and 0 <= x <= MAX_LAYOUT
            and 0 <= y <= MAX_LAYOUT
        ):
            raise ValueError(
                f"screen {text!r}: sizes 1..{MAX_LAYOUT} px and offsets 0..{MAX_LAYOUT} px"
            )
        return cls(x, y, w, h)


@dataclass(frozen=True, slots=True)
class ScreenMapping:
    """The target screen inside the desktop layout.

    Attributes:
        screen: the target screen's rectangle in layout pixels.
        layout_width, layout_height: the whole desktop in pixels.
    """

    screen: ScreenRect
    layout_width: int
    layout_height: int

    def __post_init__(self) -> None:
        s = self.screen
        if s.x + s.width > self.layout_width or s.y + s.height > self.layout_height:
            raise ValueError(
                f"screen {s.width}x{s.height}+{s.x}+{s.y} does not fit in the "
                f"{self.layout_width}x{self.layout_height} desktop layout"
            )

    @classmethod
    def single(cls, width: int, height: int) -> ScreenMapping:
        """One monitor that is the whole layout."""
        return cls(ScreenRect(0, 0, width, height), width, height)

    def to_layout(self, nx: float, ny: float) -> tuple[float, float]:
        """Layout pixel of a normalized position, clamped to the target screen."""
        s = self.screen
        return s.x + clamp01(nx) * (s.width - 1), s.y + clamp01(ny) * (s.height - 1)

    def to_pixel(self, nx: float, ny: float) -> tuple[int, int]:
        """Nearest layout pixel (for pixel-addressed outputs such as XTest)."""
        px, py = self.to_layout(nx, ny)
        return round(px), round(py)

    def to_device(self, nx: float, ny: float, maximum: int = ABS_MAX) -> tuple[int, int]:
        """Absolute device value 0 .. ``maximum`` spanning the whole layout.

        >>> ScreenMapping.single(1920, 1080).to_device(1.0, 0.5)
        (32767, 16384)
        """
        px, py = self.to_layout(nx, ny)
        dx = round(px * maximum / max(self.layout_width - 1, 1))
        dy = round(py * maximum / max(self.layout_height - 1, 1))
        return min(max(dx, 0), maximum), min(max(dy, 0), maximum)


def clamp01(v: float) -> float:
    """``v`` limited to [0, 1]; NaN becomes 0.5 (the screen's middle) rather than a corner."""
    if v != v:  # NaN
        return 0.5
    return 0.0 if v < 0.0 else 1.0 if v > 1.0 else float(v)
