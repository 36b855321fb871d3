"""``xtest`` sink: the X server's core pointer, moved and clicked through XTest.

For X11 desktops where /dev/uinput is not available to the user. Positions are
root-window pixels of one X screen: the :class:`~omnidev.screen.ScreenMapping`'s
layout is that root window (all monitors of the screen side by side, as
``xrandr`` arranges them), and its target screen a rectangle in it, e.g.
``1920x1080+1920+0`` for the right of two monitors.

Every move and button change is one ``XTestFakeInput`` request (MotionNotify
with absolute root coordinates; ButtonPress/ButtonRelease of buttons 1, 3, 2 for
left, right, middle), and each report ends with a round trip to the server
(``XSync``), so when a call returns the X server has processed the event: that
is the moment the sink has handed it to the OS.

python-xlib is imported only inside this module's functions.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Mapping
from typing import Any

from omnidev.errors import SinkError
from omnidev.screen import ScreenMapping
from omnidev.sinks.base import PointerSink

# X11 core pointer button numbers of omnidev's buttons.
X_BUTTONS = {"left": 1, "middle": 2, "right": 3}
OPTIONS = ("display", "screen")


def _xlib() -> Any:
    """The python-xlib modules this sink uses, imported on first use."""
    try:
        import Xlib.display
        import Xlib.error
        import Xlib.ext.xtest
        from Xlib import X
    except ImportError:
        raise SinkError(
            "xtest sink: python-xlib is not installed (pip install 'omnidev[hw]' "
            "or pip install python-xlib)"
        ) from None
    return Xlib, X


def _display_name(display: str | None) -> str:
    name = display if display is not None else os.environ.get("DISPLAY", "")
    if not name:
        raise SinkError("xtest sink: no X display: set option 'display' (e.g. \":0\") or DISPLAY")
    return name


def _open_display(name: str) -> Any:
    """An Xlib connection to ``name``, or a one-line SinkError saying why not."""
    xlib, _ = _xlib()
    try:
        return xlib.display.Display(name)
    except (
        xlib.error.DisplayError,
        xlib.error.XauthError,
        xlib.error.ConnectionClosedError,
        OSError,
    ) as exc:
        reason = str(exc).strip().replace("\n", " ") or type(exc).__name__
        raise SinkError(
            f"xtest sink: cannot open X display {name!r} ({reason}); check that the X "
            "server runs, DISPLAY names it, and XAUTHORITY/xauth gives this user its cookie"
        ) from None


def _screen(display: Any, name: str, screen: int | None) -> Any:
    count = display.screen_count()
    number = display.get_default_screen() if screen is None else screen
    if not 0 <= number < count:
        raise SinkError(
            f"xtest sink: X display {name!r} has screens 0..{count - 1}, not screen {number}"
        )
    return display.screen(number)


def layout_from_display(display: str | None = None, screen: int | None = None) -> tuple[int, int]:
    """The root window size (width, height) in pixels of an X screen.

    The whole desktop layout as XTest addresses it, for defaulting the layout to
    the X screen, e.g. ``ScreenMapping.single(*layout_from_display(":0"))``.

    Args:
        display: X display name; ``$DISPLAY`` when None.
        screen: screen number; the display's default screen when None.
    """
    name = _display_name(display)
    d = _open_display(name)
    try:
        s = _screen(d, name, screen)
        return int(s.width_in_pixels), int(s.height_in_pixels)
    finally:
        d.close()


class XtestSink(PointerSink):
    """The core pointer of one X screen, driven by XTest fake input.

    Args:
        mapping: the target screen in root-window pixels; it must lie inside the root.
        display: X display name; ``$DISPLAY`` when None.
        screen: X screen number; the display's default screen when None.

    Raises:
        SinkError: python-xlib missing, display not reachable, no XTEST extension,
            no such screen, or the target screen outside the root window.
    """

    name = "xtest"

    def __init__(
        self, mapping: ScreenMapping, display: str | None = None, screen: int | None = None
    ) -> None:
        super().__init__(mapping)
        xlib, x = _xlib()
        self.display_name = _display_name(display)
        self._display = _open_display(self.display_name)
        try:
            if self._display.query_extension("XTEST") is None:
                raise SinkError(
                    f"xtest sink: X display {self.display_name!r} has no XTEST extension "
                    "(enable it in the X server; Xvfb and Xorg have it unless started with -tst)"
                )
            s = _screen(self._display, self.display_name, screen)
            self.root = s.root
            if screen is not None and not self.root.query_pointer().same_screen:
                # XTest motion stays on the pointer's current screen: bring it over first.
                self.root.warp_pointer(s.width_in_pixels // 2, s.height_in_pixels // 2)
                self._display.sync()
            self.root_size = (int(s.width_in_pixels), int(s.height_in_pixels))
            r = mapping.screen
            if r.x + r.width > self.root_size[0] or r.y + r.height > self.root_size[1]:
                raise SinkError(
                    f"xtest sink: target screen {r.width}x{r.height}+{r.x}+{r.y} lies outside "
                    f"the {self.root_size[0]}x{self.root_size[1]} root window of "
                    f"{self.display_name!r}"
                )
        except BaseException:
            self.closed = True
            self._display.close()
            raise
        self._fake_input = xlib.ext.xtest.fake_input
        self._motion, self._press, self._release = x.MotionNotify, x.ButtonPress, x.ButtonRelease
        self._lost = (xlib.error.ConnectionClosedError, xlib.error.XError, OSError)
        self._unsynced = False  # requests sent since the last XSync
        try:
            self.released_at_start = self._release_stale(x)
        except BaseException:
            self.closed = True
            self._close()
            raise

    def _release_stale(self, x: Any) -> list[str]:
        """Release omnidev's buttons that the server holds down when the sink opens: a
        client killed with SIGKILL (an earlier omnidev among them) leaves its XTest
        presses down for good. Returns the buttons released."""
        masks = {"left": x.Button1Mask, "middle": x.Button2Mask, "right": x.Button3Mask}
        try:
            mask = int(self.root.query_pointer().mask)
        except self._lost as exc:
            raise SinkError(f"xtest sink: X display {self.display_name!r} lost: {exc}") from None
        stuck = [b for b, m in masks.items() if mask & m]
        for b in stuck:
            self._button(b, False)
        self._flush()
        return stuck

    def _call(self, what: str, *args: Any, **kwargs: Any) -> None:
        try:
            self._fake_input(self._display, *args, **kwargs)
            self._unsynced = True
        except self._lost as exc:
            raise SinkError(f"xtest sink: {what} on {self.display_name!r} failed: {exc}") from None

    def _move(self, nx: float, ny: float) -> None:
        px, py = self.mapping.to_pixel(nx, ny)
        self._call("motion", self._motion, root=self.root, x=px, y=py)

    def _button(self, button: str, down: bool) -> None:
        self._call("button", self._press if down else self._release, X_BUTTONS[button])

    def _flush(self) -> None:
        """XSync: returns once the server has processed every event sent (a round trip)."""
        if not self._unsynced:
            return
        self._unsynced = False  # a failed sync is not retried
        try:
            self._display.sync()
        except self._lost as exc:
            raise SinkError(f"xtest sink: X display {self.display_name!r} lost: {exc}") from None

    def _close(self) -> None:
        with contextlib.suppress(*self._lost):  # the connection may already be gone
            self._display.close()

    def stats(self) -> dict[str, Any]:
        """Counters, plus the display and its root window size (pixels)."""
        return {
            **super().stats(),
            "display": self.display_name,
            "root": list(self.root_size),
            "released_at_start": list(self.released_at_start),
        }


def open_xtest(options: Mapping[str, Any], mapping: ScreenMapping) -> XtestSink:
    """Entry point: options ``display`` (default ``$DISPLAY``), ``screen`` (X screen number)."""
    display, screen = _settings(options)
    return XtestSink(mapping, display=display, screen=screen)


def check_xtest(options: Mapping[str, Any], mapping: ScreenMapping) -> str:
    """What ``omnidev daemon --check`` checks: the options, and that the X display opens and
    has the screen (the connection is closed again; nothing moves)."""
    display, screen = _settings(options)
    name = _display_name(display)
    d = _open_display(name)
    try:
        s = _screen(d, name, screen)
        return f"xtest: X display {name} ({s.width_in_pixels}x{s.height_in_pixels})"
    finally:
        d.close()


open_xtest.check = check_xtest  # type: ignore[attr-defined]


def _settings(options: Mapping[str, Any]) -> tuple[str | None, int | None]:
    unknown = set(options) - set(OPTIONS)
    if unknown:
        raise SinkError(
            f"xtest sink: unknown option {sorted(unknown)[0]!r} (options: {', '.join(OPTIONS)})"
        )
    display = options.get("display")
    if display is not None and (not isinstance(display, str) or not display):
        raise SinkError(
            f"xtest sink: option 'display' must be a display name like \":0\", not {display!r}"
        )
    screen = options.get("screen")
    if screen is not None and (
        isinstance(screen, bool) or not isinstance(screen, int) or screen < 0
    ):
        raise SinkError(f"xtest sink: option 'screen' must be a screen number >= 0, not {screen!r}")
    return display, screen
