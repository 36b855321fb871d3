"""``omnidevd`` (also ``omnidev daemon``): run the pointer pipeline unattended.

Reads the configuration (``--config``, default /etc/omnidev/omnidev.toml),
opens tracker and sink, tells systemd it is ready (Type=notify), pings the
watchdog while the pipeline is healthy, answers the control socket, reloads
on SIGHUP or ``omnidev ctl reload``, and on SIGTERM/SIGINT stops with every
pointer button released.

Exit status: 0 after SIGTERM/SIGINT or when a file source ended; 1 when the
pipeline stopped by itself (systemd restarts it); 2 for a bad configuration;
:data:`EXIT_SOURCE_FAILED` (65) when a file source is missing, truncated or
corrupt (the unit's ``RestartPreventExitStatus`` keeps systemd from replaying it).
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from types import FrameType
from typing import Any

from omnidev.daemon import sdnotify
from omnidev.daemon.config import DEFAULT_CONFIG, load_config
from omnidev.daemon.control import ControlError, ControlServer, check_free
from omnidev.daemon.pipeline import Pipeline
from omnidev.errors import ConfigError, OmnidevError

log = logging.getLogger("omnidevd")

EXIT_SOURCE_FAILED = 65  # sysexits' EX_DATAERR: the input data is bad; restarting cannot help


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--config", type=Path, default=DEFAULT_CONFIG, help=f"TOML file (default {DEFAULT_CONFIG})"
    )
    p.add_argument("--socket", type=Path, help="control socket (overrides [daemon] socket)")
    p.add_argument(
        "--log-level", default="info", choices=("debug", "info", "warning", "error"), help="logging"
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="check the configuration as the start does (plugins, options, files, devices: "
        "opened and closed again, the pointer never moves), then exit: 0 if it would start",
    )


class Daemon:
    """The pipeline plus its control surface; :meth:`run` blocks until stopped."""

    def __init__(self, config_path: Path, socket: Path | None = None) -> None:
        self.config_path = config_path
        self.socket_override = socket
        self.config = load_config(config_path)
        check_free(self.socket)  # a second daemon stops here, before it opens anything
        self.pipeline = Pipeline(self.config)
        self._retired: list[tuple[float, ControlServer]] = []  # old sockets after a move
        self.stopping = threading.Event()
        self.reload_requested = threading.Event()
        self.server: ControlServer | None = None

    @property
    def socket(self) -> Path:
        return self.socket_override or self.config.socket

    def handle(self, cmd: str, args: dict[str, Any]) -> dict[str, Any]:
        """Control-socket commands: status, pause, resume, reload."""
        if cmd == "status":
            return {"ok": True, **self.pipeline.status()}
        if cmd == "pause":
            self.pipeline.pause()
            log.info("paused")
            return {"ok": True, "state": "paused"}
        if cmd == "resume":
            self.pipeline.resume()
            log.info("resumed")
            return {"ok": True, "state": self.pipeline.state}
        if cmd == "reload":
            try:
                self.reload()
            except OmnidevError as exc:
                return {"ok": False, "error": str(exc)}
            return {"ok": True, "state": self.pipeline.state, "socket": str(self.socket)}
        return {"ok": False, "error": f"unknown command {cmd!r} (status, pause, resume, reload)"}

    def reload(self) -> None:
        """Apply the configuration file again; a new [daemon] socket is bound first, and if
        it cannot be, nothing is applied (the error names the key)."""
        config = load_config(self.config_path)
        moved: ControlServer | None = None
        if (
            self.socket_override is None
            and self.server is not None
            and config.socket != self.config.socket
        ):
            moved = ControlServer(config.socket, self.handle)
            try:
                moved.start()
            except ControlError as exc:
                raise ConfigError(
                    f"{self.config_path}: daemon.socket: cannot move the control socket to "
                    f"{config.socket} ({exc}); the running configuration is kept"
                ) from None
        try:
            self.pipeline.reload(config)
        except BaseException:
            if moved is not None:
                moved.close()
            raise
        self.config = config
        if moved is not None and self.server is not None:
            # the old socket closes a moment later, so that this reload's reply gets out
            self._retired.append((time.monotonic() + 1.0, self.server))
            self.server = moved
            log.info("control socket moved to %s", config.socket)

    def run(self) -> int:
        self.server = ControlServer(self.socket, self.handle)
        try:
            self.server.start()
        except BaseException:
            self.pipeline.stop()  # closes the sink and button input it opened
            raise
        self.pipeline.start()
        sdnotify.ready()
        log.info(
            "running: %s -> %s -> %s (control socket %s)",
            self.config.source,
            self.config.tracker,
            self.config.sink,
            self.socket,
        )
        period = min(sdnotify.watchdog_interval_s() or 1.0, 1.0)
        next_ping = 0.0
        try:
            while not self.stopping.is_set():
                # wakes at once when the run ends by itself (a file ended or failed)
                self.pipeline.finished.wait(0.2)
                now = time.monotonic()
                for due, old in [r for r in self._retired if r[0] <= now]:
                    self._retired.remove((due, old))
                    old.close()
                if self.reload_requested.is_set():
                    self.reload_requested.clear()
                    try:
                        self.reload()
                    except OmnidevError as exc:
                        log.error("reload failed, keeping the running configuration: %s", exc)
                if self.pipeline.ended.is_set():
                    log.info("the file source ended; exiting")
                    return 0
                if self.pipeline.finished.is_set() or not self.pipeline.alive:
                    why = self.pipeline.fatal or "pipeline thread died"
                    if self.pipeline.source_failed:  # the error is logged above
                        log.info("exiting with status %d, not restarted", EXIT_SOURCE_FAILED)
                        return EXIT_SOURCE_FAILED
                    log.error("%s; exiting so systemd restarts the daemon", why)
                    return 1
                now = time.monotonic()
                if now < next_ping:
                    continue
                next_ping = now + period
                if self.pipeline.healthy():
                    sdnotify.watchdog()
                st = self.pipeline.status()
                sdnotify.status(f"{st['state']}: {st['fps']} fps, {st['dropped_frames']} dropped")
        finally:
            sdnotify.stopping()
            self.pipeline.stop()
            for _, old in self._retired:
                old.close()
            if self.server is not None:
                self.server.close()
            log.info("stopped: %s; all buttons released", self.pipeline.summary())
        return 0


def run_daemon(args: argparse.Namespace) -> int:
    # Under systemd the journal stamps every line itself.
    journal = bool(os.environ.get("JOURNAL_STREAM"))
    logging.basicConfig(
        level=args.log_level.upper(),
        format="%(levelname)s %(message)s"
        if journal
        else "%(asctime)s omnidevd %(levelname)s %(message)s",
        stream=sys.stderr,
    )
    if args.check:
        from omnidev.daemon.check import check_config

        config = load_config(args.config)
        for line in check_config(config, args.socket):
            print(f"  {line}")
        print(f"{args.config}: ok ({config.source} -> {config.tracker} -> {config.sink})")
        return 0
    daemon = Daemon(args.config, args.socket)

    def on_signal(signum: int, frame: FrameType | None) -> None:
        if signum == signal.SIGHUP:
            daemon.reload_requested.set()
        else:
            log.info("signal %d: stopping", signum)
            daemon.stopping.set()

    for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(sig, on_signal)
    return daemon.run()


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="omnidevd", description=__doc__.splitlines()[0])
    add_arguments(p)
    args = p.parse_args(argv)
    try:
        return run_daemon(args)
    except OmnidevError as exc:
        print(f"omnidevd: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
