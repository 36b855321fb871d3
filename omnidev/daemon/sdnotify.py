"""systemd's notification protocol (sd_notify), stdlib only.

A service started with ``Type=notify`` finds a datagram socket in
``$NOTIFY_SOCKET`` (a file-system path, or ``@name`` for the abstract namespace)
and sends it newline-separated ``KEY=VALUE`` assignments: ``READY=1`` once it
serves, ``STATUS=...`` a one-line human status, ``WATCHDOG=1`` keep-alive pings
at least every ``$WATCHDOG_USEC`` microseconds, ``STOPPING=1`` when it shuts down.
Outside systemd (no ``$NOTIFY_SOCKET``) every call is a no-op returning False,
so the daemon runs the same from a terminal.

Typical use in a daemon::

    sdnotify.ready()
    period = sdnotify.watchdog_interval_s()   # None: no watchdog armed
    ...                                       # every `period` s: sdnotify.watchdog()
    sdnotify.stopping()
"""

from __future__ import annotations

import logging
import os
import socket

log = logging.getLogger(__name__)

__all__ = [
    "notify",
    "ready",
    "reloading",
    "status",
    "stopping",
    "watchdog",
    "watchdog_interval_s",
]


def _address(value: str) -> str | None:
    """The AF_UNIX address for a ``$NOTIFY_SOCKET`` value, or None if unsupported.

    >>> _address("@omnidev/notify")
    '\\x00omnidev/notify'
    >>> _address("/run/systemd/notify")
    '/run/systemd/notify'
    """
    if value.startswith("@"):
        return "\0" + value[1:]  # abstract namespace
    if value.startswith("/"):
        return value
    return None  # e.g. vsock:... (VMs); not used by a local service


def notify(state: str) -> bool:
    """Send ``state`` (``KEY=VALUE`` lines) to systemd.

    Returns True when the datagram was sent, False when not running under systemd
    (no or unsupported ``$NOTIFY_SOCKET``) or when sending failed (logged, never
    raised: a notification must not stop the daemon).
    """
    value = os.environ.get("NOTIFY_SOCKET", "")
    if not value:
        return False
    address = _address(value)
    if address is None:
        log.debug("NOTIFY_SOCKET=%r is not a unix socket address; not notifying", value)
        return False
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC) as sock:
            sock.connect(address)
            sock.sendall(state.encode("utf-8"))
    except OSError as exc:
        log.warning("sd_notify to %s failed: %s", value, exc)
        return False
    return True


def ready() -> bool:
    """Tell systemd start-up is complete (``READY=1``); a Type=notify unit is then active."""
    return notify("READY=1")


def reloading() -> bool:
    """Tell systemd the configuration is being reloaded (``RELOADING=1``); send ready() after."""
    return notify("RELOADING=1")


def stopping() -> bool:
    """Tell systemd the daemon is shutting down (``STOPPING=1``)."""
    return notify("STOPPING=1")


def status(text: str) -> bool:
    """Set the status line ``systemctl status`` shows (``STATUS=text``, newlines become spaces)."""
    return notify("STATUS=" + " ".join(text.splitlines()))


def watchdog() -> bool:
    """Ping the service watchdog (``WATCHDOG=1``)."""
    return notify("WATCHDOG=1")


def watchdog_interval_s() -> float | None:
    """The recommended watchdog ping period in seconds, or None when no watchdog is armed.

    systemd sets ``$WATCHDOG_USEC`` (microseconds until it kills a silent service,
    from ``WatchdogSec=``) and ``$WATCHDOG_PID``; the watchdog is meant for this
    process only if ``$WATCHDOG_PID`` is unset or equals ``os.getpid()``. The
    returned period is half the timeout, as sd_watchdog_enabled(3) recommends
    (``WatchdogSec=10`` gives 5.0).
    """
    usec_text = os.environ.get("WATCHDOG_USEC", "")
    if not usec_text:
        return None
    try:
        usec = int(usec_text)
    except ValueError:
        log.warning("WATCHDOG_USEC=%r is not an integer; watchdog ignored", usec_text)
        return None
    if usec <= 0:
        return None
    pid_text = os.environ.get("WATCHDOG_PID", "")
    if pid_text:
        try:
            pid = int(pid_text)
        except ValueError:
            log.warning("WATCHDOG_PID=%r is not an integer; watchdog ignored", pid_text)
            return None
        if pid != os.getpid():
            return None
    return usec / 2e6
