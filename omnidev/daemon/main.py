"""``omnidevd`` (also ``omnidev daemon``): run the pointer pipeline and video streams unattended.

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
from omnidev.daemon.config import DEFAULT_CONFIG, DaemonConfig, load_config
from omnidev.daemon.control import ControlError, ControlServer, check_free
from omnidev.daemon.pipeline import Pipeline
from omnidev.daemon.streams import Stream
from omnidev.errors import ConfigError, OmnidevError
from omnidev.ptz import parse_moves

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
    p.add_argument(
        "--device-allow",
        action="store_true",
        help="print the systemd drop-in (DeviceAllow=) that omnidevd.service needs for the "
        "configuration's [buttons] input, then exit (sudo make install writes it)",
    )


class Daemon:
    """The pipeline plus its control surface; :meth:`run` blocks until stopped."""

    def __init__(self, config_path: Path, socket: Path | None = None) -> None:
        self.config_path = config_path
        self.socket_override = socket
        self.config = load_config(config_path)
        check_free(self.socket)  # a second daemon stops here, before it opens anything
        self.pipeline: Pipeline | None = Pipeline(self.config) if self.config.pointer else None
        self.streams: list[Stream] = []
        try:
            self.streams = self._make_streams(self.config)
        except BaseException:
            if self.pipeline is not None:
                self.pipeline.stop()
            raise
        self._retired: list[tuple[float, ControlServer]] = []  # old sockets after a move
        self.stopping = threading.Event()
        self.reload_requested = threading.Event()
        self.server: ControlServer | None = None

    @property
    def socket(self) -> Path:
        return self.socket_override or self.config.socket

    def _make_streams(self, config: DaemonConfig) -> list[Stream]:
        return [Stream(s, config.retry_initial_s, config.retry_max_s) for s in config.streams]

    @property
    def state(self) -> str:
        if self.pipeline is not None:
            return self.pipeline.state
        states = {s.status()["state"] for s in self.streams}
        return states.pop() if len(states) == 1 else "running"

    def status(self) -> dict[str, Any]:
        """The pointer's figures (when there is a pointer) and each stream's under "streams"."""
        out: dict[str, Any] = {"ok": True}
        if self.pipeline is not None:
            out.update(self.pipeline.status())
        else:
            out.update({"state": self.state, "pointer": None})
        out["streams"] = [s.status() for s in self.streams]
        return out

    def steer(self, args: dict[str, Any]) -> dict[str, Any]:
        """``view``: move a perspective view ({"view": NAME, "moves": ["pan=+10", ...]})."""
        name = args.get("view")
        moves = args.get("moves")
        if not isinstance(name, str) or not isinstance(moves, list):
            raise OmnidevError('view: give {"view": NAME, "moves": ["pan=..", "tilt=..", ...]}')
        absolute, relative = parse_moves([str(m) for m in moves])
        for stream in self.streams:
            if stream.view(name) is not None:
                v = stream.steer(name, absolute, relative)
                assert v.controller is not None
                t = v.controller.target
                log.info("view %s: target pan %.2f tilt %.2f fov %.2f", name, t.pan, t.tilt, t.fov)
                return {
                    "ok": True,
                    "view": name,
                    "target": {"pan": t.pan, "tilt": t.tilt, "fov": t.fov},
                    "written": v.written,
                }
        names = [v.config.name for s in self.streams for v in s.views]
        raise OmnidevError(f"no view {name!r} (views: {', '.join(names) or 'none'})")

    def handle(self, cmd: str, args: dict[str, Any]) -> dict[str, Any]:
        """Control-socket commands: status, pause, resume, reload, view."""
        if cmd == "status":
            return self.status()
        if cmd == "view":
            return self.steer(args)
        if cmd == "pause":
            if self.pipeline is not None:
                self.pipeline.pause()
            for s in self.streams:
                s.pause()
            log.info("paused")
            return {"ok": True, "state": "paused"}
        if cmd == "resume":
            if self.pipeline is not None:
                self.pipeline.resume()
            for s in self.streams:
                s.resume()
            log.info("resumed")
            return {"ok": True, "state": self.state}
        if cmd == "reload":
            try:
                self.reload()
            except OmnidevError as exc:
                return {"ok": False, "error": str(exc)}
            return {"ok": True, "state": self.state, "socket": str(self.socket)}
        return {
            "ok": False,
            "error": f"unknown command {cmd!r} (status, pause, resume, reload, view)",
        }

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
            self._reload_parts(config)
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

    def _reload_parts(self, config: DaemonConfig) -> None:
        """The pointer reloads in place; streams whose sections changed are restarted
        (new ones opened first: if one cannot be, nothing changes)."""
        keep = {s.config: s for s in self.streams}
        fresh = [
            Stream(s, config.retry_initial_s, config.retry_max_s)
            for s in config.streams
            if s not in keep
        ]
        pipeline = self.pipeline
        try:
            if config.pointer and pipeline is not None:
                pipeline.reload(config)
            elif config.pointer:
                pipeline = Pipeline(config)
        except BaseException:
            for s in fresh:
                s.stop()
            raise
        if not config.pointer and self.pipeline is not None:
            self.pipeline.stop()
            pipeline = None
        if pipeline is not self.pipeline and pipeline is not None:
            pipeline.start()
        self.pipeline = pipeline
        wanted = set(config.streams)
        for s in self.streams:
            if s.config not in wanted:
                s.stop()
        by_config = {s.config: s for s in fresh}
        self.streams = [keep.get(c) or by_config[c] for c in config.streams]
        for s in fresh:
            s.start()

    def _finished(self) -> tuple[bool, int, str]:
        """(the run is over, exit status, why): every part ended, or one failed for good."""
        parts_done = []
        p = self.pipeline
        if p is not None:
            if p.ended.is_set():
                parts_done.append(True)
            elif p.finished.is_set() or not p.alive:
                why = p.fatal or "pipeline thread died"
                return True, EXIT_SOURCE_FAILED if p.source_failed else 1, why
            else:
                parts_done.append(False)
        for s in self.streams:
            if s.source_failed and all(x.finished.is_set() for x in self.streams) and p is None:
                return True, EXIT_SOURCE_FAILED, s.error or "stream failed"
            if not s.alive:
                return True, 1, f"stream {s.config.name}: a thread died"
            if s.output_failed:
                return True, 1, s.error or f"stream {s.config.name} failed"
            parts_done.append(s.finished.is_set())
        if parts_done and all(parts_done):
            failed = [s for s in self.streams if s.source_failed]
            if failed:
                return True, EXIT_SOURCE_FAILED, failed[0].error or "stream failed"
            return True, 0, "every source ended"
        return False, 0, ""

    def run(self) -> int:
        self.server = ControlServer(self.socket, self.handle)
        try:
            self.server.start()
        except BaseException:
            if self.pipeline is not None:
                self.pipeline.stop()  # closes the sink and button input it opened
            for stream in self.streams:
                stream.stop()
            raise
        if self.pipeline is not None:
            self.pipeline.start()
        for stream in self.streams:
            stream.start()
        sdnotify.ready()
        c = self.config
        log.info(
            "running: %s%s (control socket %s)",
            f"{c.source} -> {c.tracker} -> {c.sink}" if c.pointer else "no pointer",
            "".join(f"; stream {s.config.name}" for s in self.streams),
            self.socket,
        )
        period = min(sdnotify.watchdog_interval_s() or 1.0, 1.0)
        next_ping = 0.0
        try:
            while not self.stopping.is_set():
                # wakes at once when the pointer's run ends by itself (a file ended or failed)
                if self.pipeline is not None and not self.pipeline.finished.is_set():
                    self.pipeline.finished.wait(0.2 if not self.streams else 0.05)
                else:
                    self.stopping.wait(0.05)
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
                done, status, why = self._finished()
                if done:
                    if status == 0:
                        log.info("%s; exiting", "the file source ended" if self.pipeline else why)
                    elif status == EXIT_SOURCE_FAILED:  # the error is logged above
                        log.info("exiting with status %d, not restarted", EXIT_SOURCE_FAILED)
                    else:
                        log.error("%s; exiting so systemd restarts the daemon", why)
                    return status
                now = time.monotonic()
                if now < next_ping:
                    continue
                next_ping = now + period
                healthy = all(s.healthy() for s in self.streams)
                if self.pipeline is not None:
                    healthy = healthy and self.pipeline.healthy()
                if healthy:
                    sdnotify.watchdog()
                sdnotify.status(self._status_line())
        finally:
            sdnotify.stopping()
            if self.pipeline is not None:
                self.pipeline.stop()
            for stream in self.streams:
                stream.stop()
            for _, old in self._retired:
                old.close()
            if self.server is not None:
                self.server.close()
            if self.pipeline is not None:
                log.info("stopped: %s; all buttons released", self.pipeline.summary())
            for stream in self.streams:
                st = stream.status()
                log.info(
                    "stream %s stopped: %d frames, %d written, %d dropped",
                    stream.config.name, st["frames"], st["written"], st["dropped_frames"],
                )  # fmt: skip
        return 0

    def _status_line(self) -> str:
        parts = []
        if self.pipeline is not None:
            st = self.pipeline.status()
            parts.append(f"{st['state']}: {st['fps']} fps, {st['dropped_frames']} dropped")
        for stream in self.streams:
            st = stream.status()
            parts.append(
                f"{st['name']} {st['state']}: {st['fps']} fps, {st['dropped_frames']} dropped"
            )
        return "; ".join(parts)


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
    if args.device_allow:
        from omnidev.daemon.unit import dropin_text

        print(dropin_text(load_config(args.config)), end="")
        return 0
    if args.check:
        from omnidev.daemon.check import check_config

        config = load_config(args.config)
        for line in check_config(config, args.socket):
            print(f"  {line}")
        parts = [f"{config.source} -> {config.tracker} -> {config.sink}"] if config.pointer else []
        parts += [f"stream {s.name}" for s in config.streams]
        print(f"{args.config}: ok ({'; '.join(parts)})")
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
