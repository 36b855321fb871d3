"""``omnidev daemon --check``: resolve a configuration as the real start would, moving nothing.

The real start (:class:`omnidev.daemon.pipeline.Pipeline`) opens the tracker,
the button input and the sink, then the source. :func:`check_config` does each
of those steps with the same plugins and options, so that a configuration that
passes the check starts:

- tracker: the plugin is created with its options and calibration (a tracker
  only reads its calibration; nothing is opened);
- sink: the plugin's ``check(options, mapping)`` when it has one (every
  first-party sink does: options, then the device node, X display or file
  opened and closed again, no device created, no event sent); a sink without a
  ``check`` is opened and closed, which must not move the pointer;
- button input: opened and closed (it only reads);
- source: the scheme resolved and its options validated; a file source is
  opened and closed; a camera source's ``check(rest, options)`` validates its
  options, and a camera that is absent now is only reported (the daemon waits
  for it and starts when it appears);
- control socket: its folder exists or can be made, and the path is not taken
  by something other than a socket;
- each ``[[stream]]``: the calibration is loaded with its options, every view's
  maps are built (a view the camera cannot fill fails here), every output's
  plugin is found and the output opened for the view's size and aborted again
  (a file output leaves nothing behind; standard output is only named), and the
  source is checked as the pointer's is.

Each failure is a :class:`~omnidev.errors.ConfigError` naming the file and the key.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from omnidev import registry
from omnidev.daemon.config import DaemonConfig
from omnidev.daemon.streams import StreamConfig
from omnidev.errors import ConfigError, OmnidevError


@contextmanager
def _key(config: DaemonConfig, key: str) -> Iterator[None]:
    try:
        yield
    except ConfigError as exc:
        text = str(exc)
        raise ConfigError(
            text if text.startswith(str(config.path)) else f"{config.path}: {key}: {text}"
        ) from None
    except OmnidevError as exc:
        raise ConfigError(f"{config.path}: {key}: {exc}") from None


def check_config(config: DaemonConfig, socket: Path | None = None) -> list[str]:
    """Check every part of ``config`` as the start does; the lines say what was checked."""
    notes: list[str] = []
    if config.pointer:
        notes += _check_pointer(config)
    for stream in config.streams:
        notes += _check_stream(config, stream)
    path = socket or config.socket
    with _key(config, "daemon.socket"):
        _check_socket(path)
    notes.append(f"control socket {path}")
    return notes


def _check_source(uri: str) -> str:
    from omnidev.sources import FILE_SCHEMES, open_source, split_uri
    from omnidev.sources import GROUP as SOURCES

    scheme, rest, options = split_uri(uri)
    source_opener = registry.get(SOURCES, scheme)
    source_check: Callable[..., Any] | None = getattr(source_opener, "check", None)
    if scheme in FILE_SCHEMES or source_check is None:
        with open_source(uri) as src:
            return f"source {src.name}: opened and closed"
    return f"source {source_check(rest, options)}"


def _check_stream(config: DaemonConfig, stream: StreamConfig) -> list[str]:
    from omnidev.calibfile import load_camera
    from omnidev.camera import build_maps
    from omnidev.outputs import GROUP as OUTPUTS
    from omnidev.outputs import OutputSpec, open_output, split_output_uri, uses_stdout

    where = f"stream {stream.name!r}"
    notes: list[str] = []
    with _key(config, f"{where}.camera"):
        camera = load_camera(stream.camera, stream.camera_options)
    for v in stream.views:
        vwhere = f"{where}.view {v.name!r}"
        with _key(config, f"{vwhere}.view"):
            try:
                maps = build_maps(camera, v.view)
            except ValueError as exc:
                raise ConfigError(f"{stream.camera}: {exc}") from None
        h, w = maps.shape
        spec = OutputSpec((w, h), stream.fps or 30.0, ("bgr",), True, False, 1)
        for uri in v.outputs:
            with _key(config, f"{vwhere}.output"):
                registry.get(OUTPUTS, split_output_uri(uri)[0])
                if uses_stdout(uri):
                    notes.append(f"{where}: output {uri}: standard output")
                    continue
                open_output(uri, spec).abort()
            notes.append(f"{where}: view {v.name} {w}x{h} -> {uri}: opened and aborted")
    with _key(config, f"{where}.source"):
        notes.append(f"{where}: {_check_source(stream.source)}")
    return notes


def _check_pointer(config: DaemonConfig) -> list[str]:
    from omnidev.sinks import GROUP as SINKS
    from omnidev.tracking import GROUP as TRACKERS
    from omnidev.tracking import open_tracker

    notes: list[str] = []
    with _key(config, "tracker.name"):
        registry.get(TRACKERS, config.tracker)
    with _key(config, "tracker (its options and calibration)"):
        open_tracker(config.tracker, config.tracker_options, config.calibration)
    notes.append(f"tracker {config.tracker}: created with its options")

    with _key(config, "sink.name"):
        opener = registry.get(SINKS, config.sink)
    with _key(config, "sink.options"):
        check: Callable[..., Any] | None = getattr(opener, "check", None)
        if check is not None:
            notes.append(f"sink {check(dict(config.sink_options), config.screen)}")
        else:
            opener(dict(config.sink_options), config.screen).close()
            notes.append(f"sink {config.sink}: opened and closed (the plugin has no check)")

    if config.buttons.input:
        from omnidev.buttons import open_buttons

        with _key(config, "buttons.input"):
            open_buttons(config.buttons.input).close()
        from omnidev.daemon.unit import device_allow

        allow = ", ".join(device_allow(config))
        notes.append(
            f"buttons {config.buttons.input}: opened and closed (omnidevd.service needs "
            f"DeviceAllow {allow}: omnidev daemon --device-allow)"
        )

    with _key(config, "source.uri"):
        notes.append(_check_source(config.source))
    return notes


def _check_socket(path: Path) -> None:
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise ConfigError(f"{path}: {exc.strerror}") from None
    if st is not None and not stat.S_ISSOCK(st.st_mode):
        raise ConfigError(f"{path} exists and is not a socket")
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError(f"cannot create {path}: {parent} is not a writable folder")
