"""udev rules, systemd units, modules-load.d and the install script, checked with real tools.

The install script runs into a DESTDIR (with a throwaway passwd/group database for
``useradd --prefix``); the installed units go through ``systemd-analyze verify``;
the rules through udev's own parser (``udevadm test`` in a private mount namespace,
as udev 252 has no ``udevadm verify``) and a small parser of ``KEY op "value"``
pairs; the example configuration through the daemon's validator; and the
documented no-camera trial runs the real omnidevd against a stand-in notify socket.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import pytest

from omnidev.daemon.config import DEFAULT_CONFIG, ButtonsConfig, parse_config
from omnidev.daemon.control import DEFAULT_SOCKET, request

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "scripts" / "install-system-files.sh"
UDEV = REPO / "udev"
UINPUT_RULE = (
    'KERNEL=="uinput", SUBSYSTEM=="misc", OPTIONS+="static_node=uinput", '
    'GROUP="input", MODE="0660", TAG+="uaccess"'
)
STATUS_KEYS = {
    "state",
    "source",
    "sink",
    "tracker",
    "fps",
    "latency_p50_ms",
    "latency_p99_ms",
    "frames",
    "dropped_frames",
    "events",
    "camera_retries",
    "uptime_s",
}


def fake_etc(root: Path) -> None:
    """A minimal passwd/group database below ``root`` for useradd --prefix (not the host's)."""
    etc = root / "etc"
    etc.mkdir(parents=True, exist_ok=True)
    (etc / "passwd").write_text("root:x:0:0:root:/root:/bin/sh\n")
    (etc / "shadow").write_text("root:*:19000:0:99999:7:::\n")
    (etc / "group").write_text("root:x:0:\ninput:x:105:\n")
    (etc / "gshadow").write_text("root:*::\ninput:!::\n")
    for name in ("shadow", "gshadow"):
        (etc / name).chmod(0o640)


def fake_bin(root: Path) -> Path:
    """A directory with an executable omnidevd for ExecStart to point at."""
    bindir = root / "opt" / "omnidev" / "bin"
    bindir.mkdir(parents=True)
    exe = bindir / "omnidevd"
    exe.write_text("#!/bin/sh\nexit 0\n")
    exe.chmod(0o755)
    return bindir


def install(destdir: Path, *args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run(
        ["sh", str(SCRIPT), *args],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "DESTDIR": str(destdir)},
    )
    if check:
        assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc


@pytest.fixture(scope="module")
def installed() -> tuple[Path, Path]:
    """One install into a temporary root with a camera rule; (destdir, bin dir)."""
    root = Path(tempfile.mkdtemp(prefix="omnidev-destdir-"))
    fake_etc(root)
    bindir = fake_bin(root)
    install(root, "--camera", "046D:0825", "--bin-dir", str(bindir))
    yield root, bindir
    shutil.rmtree(root, ignore_errors=True)


# -- where files land ------------------------------------------------------------

EXPECTED = {
    "etc/udev/rules.d/60-omnidev.rules": 0o644,
    "etc/udev/rules.d/61-omnidev-camera.rules": 0o644,
    "etc/modules-load.d/omnidev.conf": 0o644,
    "etc/systemd/system/omnidevd.service": 0o644,
    "etc/systemd/system/omnidev-gadget.service": 0o644,
    "usr/local/lib/omnidev/omnidev-gadget.sh": 0o755,
    "etc/omnidev/omnidev.toml": 0o644,
    "usr/local/share/doc/omnidev/omnidev.toml.example": 0o644,
    "usr/local/share/doc/omnidev/daemon.md": 0o644,
    "usr/local/share/omnidev/blob.avi": 0o644,
}


def test_files_land_where_the_docs_say(installed):
    root, _ = installed
    for rel, mode in EXPECTED.items():
        path = root / rel
        assert path.is_file(), f"{rel} not installed"
        assert stat.S_IMODE(path.stat().st_mode) == mode, rel
    docs = (REPO / "docs" / "daemon.md").read_text()
    for rel in EXPECTED:
        if "gadget" not in rel and not rel.startswith("usr/local/share/doc/"):
            assert "/" + rel in docs, f"docs/daemon.md does not mention /{rel}"
    assert (root / "etc/udev/rules.d/60-omnidev.rules").read_bytes() == (
        UDEV / "60-omnidev.rules"
    ).read_bytes()
    assert (root / "etc/omnidev/omnidev.toml").read_bytes() == (
        UDEV / "omnidev.toml.example"
    ).read_bytes()


def test_execstart_points_at_the_given_omnidevd(installed):
    root, bindir = installed
    unit = (root / "etc/systemd/system/omnidevd.service").read_text()
    assert f"\nExecStart={bindir}/omnidevd --config /etc/omnidev/omnidev.toml\n" in unit
    shipped = (UDEV / "omnidevd.service").read_text()
    assert "\nExecStart=/usr/local/bin/omnidevd --config /etc/omnidev/omnidev.toml\n" in shipped
    assert f"--config {DEFAULT_CONFIG}" in shipped


def test_system_user_is_created_in_input_and_video(installed):
    root, _ = installed
    lines = (root / "etc/passwd").read_text().splitlines()
    passwd = {line.split(":")[0]: line.split(":") for line in lines}
    assert "omnidev" in passwd
    entry = passwd["omnidev"]
    assert int(entry[2]) < 1000, "not a system user"
    assert entry[6].endswith("nologin")
    groups = {
        line.split(":")[0]: line.split(":")[3].split(",")
        for line in (root / "etc/group").read_text().splitlines()
    }
    assert "omnidev" in groups["input"]
    assert "omnidev" in groups["video"]  # video did not exist: created as a system group
    assert "omnidev" in groups


def test_camera_rule(installed):
    root, _ = installed
    text = (root / "etc/udev/rules.d/61-omnidev-camera.rules").read_text()
    rules = parse_rules(text, "61-omnidev-camera.rules")
    assert len(rules) == 1
    pairs = {(k, op): v for k, op, v in rules[0]}
    assert pairs[("SUBSYSTEM", "==")] == "video4linux"
    assert pairs[("ENV{ID_VENDOR_ID}", "==")] == "046d"  # lowercased as udev's usb_id writes it
    assert pairs[("ENV{ID_MODEL_ID}", "==")] == "0825"
    assert pairs[("TAG", "+=")] == "systemd"
    assert pairs[("ENV{SYSTEMD_WANTS}", "+=")] == "omnidevd.service"


def test_camera_rule_with_serial_and_bad_ids(tmp_path):
    install(tmp_path, "--camera", "1d6b:0104:AB-12", "--bin-dir", str(fake_bin(tmp_path)))
    text = (tmp_path / "etc/udev/rules.d/61-omnidev-camera.rules").read_text()
    assert 'ENV{ID_SERIAL_SHORT}=="AB-12"' in text
    for bad in ("46d:0825", "046d", "046d:08zz", "046d:0825:a b", 'x"y:0825'):
        proc = install(tmp_path, "--camera", bad, check=False)
        assert proc.returncode == 2, bad
        assert proc.stderr.count("\n") == 1 and "--camera" in proc.stderr, proc.stderr


def test_existing_config_is_never_overwritten(tmp_path):
    bindir = fake_bin(tmp_path)
    conf = tmp_path / "etc/omnidev/omnidev.toml"
    conf.parent.mkdir(parents=True)
    conf.write_text("# mine\n")
    proc = install(tmp_path, "--bin-dir", str(bindir))
    assert conf.read_text() == "# mine\n"
    assert "kept the existing /etc/omnidev/omnidev.toml" in proc.stdout
    assert "not creating the user" in proc.stdout  # no etc/passwd in this DESTDIR


def test_uninstall_removes_files_and_keeps_config(tmp_path):
    fake_etc(tmp_path)
    install(tmp_path, "--camera", "046d:0825", "--bin-dir", str(fake_bin(tmp_path)))
    install(tmp_path, "--bin-dir", str(tmp_path / "opt/omnidev/bin"))  # again: idempotent
    proc = install(tmp_path, "--uninstall")
    for rel in EXPECTED:
        if rel != "etc/omnidev/omnidev.toml":
            assert not (tmp_path / rel).exists(), f"{rel} left behind"
    assert (tmp_path / "etc/omnidev/omnidev.toml").is_file()
    assert not (tmp_path / "usr/local/lib/omnidev").exists()
    assert "kept /etc/omnidev/omnidev.toml and the user omnidev" in proc.stdout


def test_bad_arguments(tmp_path):
    proc = install(tmp_path, "--frobnicate", check=False)
    assert proc.returncode == 2 and "unknown argument '--frobnicate'" in proc.stderr
    proc = install(tmp_path, "--bin-dir", "/opt/my venv/bin", check=False)
    assert proc.returncode == 2 and "ExecStart" in proc.stderr
    proc = install(tmp_path, "--help")
    assert "--camera" in proc.stdout and "--uninstall" in proc.stdout


# -- systemd ---------------------------------------------------------------------


def unit_settings(text: str) -> dict[str, list[str]]:
    """``Key -> [values]`` of a unit file, all sections together."""
    out: dict[str, list[str]] = {}
    for line in text.splitlines():
        line = line.strip()
        if not line or line[0] in "#;[":
            continue
        key, _, value = line.partition("=")
        out.setdefault(key.strip(), []).append(value.strip())
    return out


def test_daemon_unit_settings():
    s = unit_settings((UDEV / "omnidevd.service").read_text())
    assert s["Type"] == ["notify"]
    assert s["NotifyAccess"] == ["main"]
    assert s["WatchdogSec"] == ["10"]
    assert s["User"] == ["omnidev"] and s["Group"] == ["omnidev"]
    assert s["SupplementaryGroups"] == ["input video"]
    assert s["RuntimeDirectory"] == [DEFAULT_SOCKET.parent.name]
    assert DEFAULT_SOCKET.parent == Path("/run") / s["RuntimeDirectory"][0]
    assert s["RuntimeDirectoryMode"] == ["0750"]
    assert s["Restart"] == ["on-failure"]
    assert s["KillSignal"] == ["SIGTERM"]
    assert s["NoNewPrivileges"] == ["yes"]
    assert s["ProtectSystem"] == ["strict"]
    assert s["ProtectHome"] == ["read-only"]
    assert s["PrivateTmp"] == ["yes"]
    # what the sinks and sources open must stay allowed under DevicePolicy=closed
    assert s["DevicePolicy"] == ["closed"]
    allowed = {v.split()[0]: v.split()[1] for v in s["DeviceAllow"]}
    assert allowed == {"/dev/uinput": "rw", "char-video4linux": "rw", "char-hidg": "rw"}
    assert "PrivateDevices" not in s and "PrivateNetwork" not in s  # would hide devices / X11
    assert "AF_UNIX" in s["RestrictAddressFamilies"][0]
    assert "modprobe@uinput.service" in " ".join(s["Wants"])
    assert "modprobe@videodev.service" in " ".join(s["Wants"])


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="systemd-analyze not installed")
def test_units_pass_systemd_analyze_verify(installed, tmp_path):
    root, _ = installed
    for unit in sorted((root / "etc/systemd/system").glob("*.service")):
        # systemd-analyze checks that ExecStart programs exist: point the gadget unit's
        # /usr/local/lib/omnidev at the DESTDIR copy (the only change made for verifying).
        text = unit.read_text().replace("/usr/local/lib/omnidev/", f"{root}/usr/local/lib/omnidev/")
        copy = tmp_path / unit.name
        copy.write_text(text)
        proc = subprocess.run(
            ["systemd-analyze", "verify", str(copy)], capture_output=True, text=True, timeout=60
        )
        assert proc.returncode == 0, f"{unit.name}: {proc.stderr}"
        assert proc.stderr.strip() == "", f"{unit.name}: {proc.stderr}"


def _offline_security(unit: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["systemd-analyze", "security", "--offline=yes", "--no-pager", str(unit)],
        capture_output=True,
        text=True,
        timeout=60,
    )


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="systemd-analyze not installed")
def test_daemon_unit_exposure(installed):
    """systemd's own exposure score (0 = locked down, 10 = unprotected) of the installed unit."""
    root, _ = installed
    proc = _offline_security(root / "etc/systemd/system/omnidevd.service")
    if "--offline" in proc.stderr:
        pytest.skip(f"systemd-analyze security has no --offline here: {proc.stderr.strip()[:120]}")
    match = re.search(r"Overall exposure level for omnidevd\.service: ([0-9.]+)", proc.stdout)
    assert match, proc.stdout[-500:] + proc.stderr
    exposure = float(match.group(1))
    print(f"omnidevd.service exposure (systemd-analyze security --offline): {exposure}")
    assert exposure <= 2.0  # 1.6 "OK" as shipped; 9.2 "UNSAFE" with the hardening block removed


# -- udev ------------------------------------------------------------------------

MATCH_KEYS = {
    "ACTION", "DEVPATH", "KERNEL", "KERNELS", "NAME", "SYMLINK", "SUBSYSTEM", "SUBSYSTEMS",
    "DRIVER", "DRIVERS", "ATTR", "ATTRS", "SYSCTL", "TAG", "TAGS", "ENV", "CONST", "TEST",
    "PROGRAM", "RESULT",
}  # fmt: skip
ASSIGN_KEYS = {
    "NAME", "SYMLINK", "OWNER", "GROUP", "MODE", "TAG", "ENV", "ATTR", "SYSCTL", "RUN",
    "IMPORT", "OPTIONS", "LABEL", "GOTO", "SECLABEL", "PROGRAM",
}  # fmt: skip
_PAIR = re.compile(r'\s*([A-Z_]+)(\{[^}]*\})?\s*(==|!=|\+=|-=|:=|=)\s*"((?:[^"\\]|\\.)*)"\s*(,|$)')


def parse_rules(text: str, name: str) -> list[list[tuple[str, str, str]]]:
    """udev rules as lists of (KEY{attr}, operator, value); raises on what udev would reject."""
    rules = []
    logical: list[tuple[int, str]] = []
    buf, start = "", 0
    for n, line in enumerate(text.splitlines(), 1):
        if not buf:
            start = n
        if line.endswith("\\"):
            buf += line[:-1]
            continue
        buf += line
        logical.append((start, buf))
        buf = ""
    for n, line in logical:
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        pos, pairs = 0, []
        while pos < len(line):
            m = _PAIR.match(line, pos)
            assert m, f"{name}:{n}: cannot parse at column {pos + 1}: {line[pos:]!r}"
            key, attr, op, value = m.group(1), m.group(2) or "", m.group(3), m.group(4)
            if op in ("==", "!="):
                assert key in MATCH_KEYS, f"{name}:{n}: {key} cannot be matched"
            else:
                assert key in ASSIGN_KEYS, f"{name}:{n}: {key} cannot be assigned"
            if key in ("ATTR", "ATTRS", "ENV", "SYSCTL"):
                assert attr, f"{name}:{n}: {key} needs {{name}}"
            pairs.append((key + attr, op, value))
            pos = m.end()
            if m.group(5) == "":
                break
        assert any(op in ("==", "!=") for _, op, _ in pairs), f"{name}:{n}: matches everything"
        assert not any(k == "RUN" for k, _, _ in pairs), f"{name}:{n}: no RUN+= in omnidev rules"
        rules.append(pairs)
    return rules


def test_parser_rejects_what_udev_rejects():
    with pytest.raises(AssertionError, match="cannot parse"):
        parse_rules('KERNEL=="uinput" GROUP="input"\n', "t")  # missing comma
    with pytest.raises(AssertionError, match="cannot parse"):
        parse_rules("KERNEL==uinput\n", "t")  # unquoted
    with pytest.raises(AssertionError, match="cannot be matched"):
        parse_rules('MODE=="0660"\n', "t")
    with pytest.raises(AssertionError, match="needs"):
        parse_rules('ENV=="x", GROUP="input"\n', "t")
    assert parse_rules('KERNEL=="a", \\\n  GROUP="input"\n', "t") == [
        [("KERNEL", "==", "a"), ("GROUP", "=", "input")]
    ]


def test_shipped_rules_parse_and_say_what_the_issue_says():
    text = (UDEV / "60-omnidev.rules").read_text()
    rules = parse_rules(text, "60-omnidev.rules")
    lines = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    assert UINPUT_RULE in lines
    hidg = [dict(((k, op), v) for k, op, v in r) for r in rules if ("SUBSYSTEM", "==", "hidg") in r]
    assert len(hidg) == 1
    assert hidg[0][("KERNEL", "==")] == "hidg[0-9]*"
    assert hidg[0][("GROUP", "=")] == "input" and hidg[0][("MODE", "=")] == "0660"
    # the commented camera example is a valid rule once uncommented
    example = [ln[2:] for ln in text.splitlines() if ln.startswith("# SUBSYSTEM==")]
    assert len(example) == 1
    assert parse_rules(example[0], "example")[0][-1] == (
        "ENV{SYSTEMD_WANTS}",
        "+=",
        "omnidevd.service",
    )


def test_modules_load_d():
    text = (UDEV / "modules-load.d" / "omnidev.conf").read_text()
    assert [ln for ln in text.splitlines() if ln and not ln.startswith("#")] == ["uinput"]


def _can_run_udevadm_test() -> str | None:
    """Why udev's own parser cannot be run here, or None."""
    if shutil.which("udevadm") is None:
        return "udevadm not installed"
    if shutil.which("unshare") is None:
        return "unshare (util-linux) not installed"
    if os.geteuid() != 0:
        return "needs root for a private mount namespace (udevadm test writes /dev and /run/udev)"
    if not Path("/sys/class/mem/null").exists():
        return "no /sys/class/mem/null to run udevadm test on"
    probe = subprocess.run(
        ["unshare", "--mount", "--propagation", "private", "true"], capture_output=True, timeout=30
    )
    if probe.returncode != 0:
        return f"unshare --mount is not permitted here: {probe.stderr.decode().strip()[:100]}"
    return None


def test_rules_pass_udevs_own_parser(installed, tmp_path):
    """``udevadm test`` loads every rules file and logs ``FILE:LINE <problem>`` for bad ones.

    It also applies permissions and writes /run/udev, so it runs in a private mount
    namespace with empty tmpfs over /dev and /run, and our rules bound over
    /etc/udev/rules.d: the host is not touched.
    """
    reason = _can_run_udevadm_test()
    if reason:
        pytest.skip(f"udev's parser cannot run: {reason}")
    root, _ = installed
    rules_dir = root / "etc/udev/rules.d"
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "60-bad.rules").write_text('KERNEL=="x", BOGUS="1"\n')

    def udevadm_test(directory: Path) -> str:
        script = (
            "set -e; mount -t tmpfs none /run; mount -t tmpfs none /dev; "
            f"mount --bind '{directory}' /etc/udev/rules.d; "
            "udevadm test --action=add /sys/class/mem/null 2>&1"
        )
        proc = subprocess.run(
            ["unshare", "--mount", "--propagation", "private", "sh", "-c", script],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert "Reading rules file: /etc/udev/rules.d/" in proc.stdout, proc.stdout[-2000:]
        return proc.stdout

    # the check can fail: udev names the bad file and line
    assert "/etc/udev/rules.d/60-bad.rules:1 Invalid key 'BOGUS'" in udevadm_test(bad)
    out = udevadm_test(rules_dir)
    for name in ("60-omnidev.rules", "61-omnidev-camera.rules", "62-omnidev-v4l2loopback.rules"):
        assert f"Reading rules file: /etc/udev/rules.d/{name}" in out
        problems = [ln for ln in out.splitlines() if ln.startswith(f"/etc/udev/rules.d/{name}:")]
        assert problems == [], problems


# -- configuration ---------------------------------------------------------------


def test_example_config_is_valid_and_complete():
    text = (UDEV / "omnidev.toml.example").read_text()
    doc = tomllib.loads(text)
    config = parse_config(doc, DEFAULT_CONFIG)
    assert config.source == "v4l2:/dev/video0?width=640&height=480&fps=30"
    assert config.tracker == "bright-blob" and config.sink == "uinput"
    assert config.socket == DEFAULT_SOCKET
    assert set(doc) == {"source", "tracker", "filter", "buttons", "sink", "screen", "daemon"}
    assert doc["buttons"] == {
        "input": "",
        "dwell": False,
        "dwell_s": 0.8,
        "dwell_radius_px": 12.0,
        "dwell_button": "left",
        "release_when_lost": True,
    }
    assert config.buttons == ButtonsConfig()  # every value shown is the default
    assert doc["filter"] == {"kind": "one-euro", "min_cutoff": 0.1, "beta": 20.0, "d_cutoff": 2.0}
    assert doc["daemon"] == {
        "socket": "/run/omnidev/control.sock",
        "queue": 1,
        "retry_initial_s": 0.5,
        "retry_max_s": 10,
    }
    assert doc["screen"] == {"rect": "1920x1080+0+0", "layout": "1920x1080"}


# -- the documented no-camera trial ------------------------------------------------


def _short_dir() -> Path:
    return Path(tempfile.mkdtemp(prefix="omd-"))


@pytest.mark.skipif(
    not (REPO / "fixtures" / "blob" / "blob.avi").is_file(), reason="fixtures/blob/blob.avi absent"
)
def test_fixture_trial_runs_the_daemon_as_systemd_would():
    """docs/daemon.md "Try it without a camera", record sink: READY, WATCHDOG, status, SIGTERM.

    A datagram socket stands in for systemd's notify socket ($NOTIFY_SOCKET,
    $WATCHDOG_USEC=2 s and $WATCHDOG_PID as systemd sets them for the main process).
    """
    from omnidev import registry

    if "bright-blob" not in {p.name for p in registry.plugins("omnidev.trackers")}:
        pytest.skip("the bright-blob tracker plugin (plugins/bright-blob) is not installed")
    work = _short_dir()
    try:
        example = (UDEV / "omnidev.toml.example").read_text()
        blob = REPO / "fixtures" / "blob" / "blob.avi"
        config = example.replace(
            'uri = "v4l2:/dev/video0?width=640&height=480&fps=30"',
            f'uri = "video:{blob}?loop=1&rate=realtime"',
        ).replace('name = "uinput"', 'name = "record"')
        config = config.replace(
            '# path = "/run/omnidev/events.jsonl"', f'path = "{work}/events.jsonl"'
        ).replace('socket = "/run/omnidev/control.sock"', f'socket = "{work}/control.sock"')
        conf = work / "omnidev.toml"
        conf.write_text(config)
        notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        notify.bind(str(work / "notify"))
        notify.settimeout(60.0)
        omnidevd = Path(sys.executable).parent / "omnidevd"
        if not omnidevd.exists():
            pytest.skip(f"{omnidevd} not installed (pip install -e . creates it)")
        env = {**os.environ, "NOTIFY_SOCKET": str(work / "notify"), "WATCHDOG_USEC": "2000000"}
        proc = subprocess.Popen(
            [str(omnidevd), "--config", str(conf)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            seen: list[str] = []
            while "WATCHDOG=1" not in seen:
                seen.extend(notify.recv(4096).decode().split("\n"))
            assert seen.index("READY=1") < seen.index("WATCHDOG=1")
            # wait (untimed) until frames have flowed, then read the status
            status = request(work / "control.sock", "status", timeout=10.0)
            while not status.get("events"):
                notify.recv(4096)  # the next status/watchdog datagram paces the loop
                status = request(work / "control.sock", "status", timeout=10.0)
            assert status["ok"] is True
            assert set(status) >= STATUS_KEYS, STATUS_KEYS - set(status)
            assert status["sink"] == "record" and status["tracker"] == "bright-blob"
            assert request(work / "control.sock", "pause")["state"] == "paused"
            assert request(work / "control.sock", "resume")["ok"] is True
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=60)
            assert proc.returncode == 0, err
            while "STOPPING=1" not in seen:
                seen.extend(notify.recv(4096).decode().split("\n"))
            assert not (work / "control.sock").exists()
            events = [json.loads(ln) for ln in (work / "events.jsonl").read_text().splitlines()]
            assert any(e.get("kind") == "move" for e in events), events[:3]
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            notify.close()
    finally:
        shutil.rmtree(work, ignore_errors=True)


# -- DeviceAllow for the configuration's button input (omnidev/daemon/unit.py) ----

EXAMPLE = REPO / "udev" / "omnidev.toml.example"


def _config_with_buttons(path: Path, spec: str) -> Path:
    text = EXAMPLE.read_text()
    assert '\ninput = ""\n' in text
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text.replace('\ninput = ""\n', f"\ninput = {spec!r}\n"))
    return path


@pytest.mark.parametrize(
    ("spec", "allow"),
    [
        ("", []),
        ("evdev:/dev/input/event3?KEY_SPACE=left", ["char-input r"]),
        ("evdev:name=My Remote", ["char-input r"]),
        ("hid:046d:c538?key.0x4e=left&backend=hidraw", ["char-hidraw rw"]),
        ("hid:046d:c538?key.0x4e=left&backend=libusb", ["char-usb_device rw"]),
        ("hid:046d:c538?key.0x4e=left", ["char-hidraw rw", "char-usb_device rw"]),
    ],
)
def test_device_allow_follows_the_button_input(tmp_path, spec, allow):
    from omnidev.daemon.config import load_config
    from omnidev.daemon.unit import device_allow, dropin_text

    config = load_config(_config_with_buttons(tmp_path / "omnidev.toml", spec))
    assert device_allow(config) == allow
    text = dropin_text(config)
    assert "[Service]" in text.splitlines()
    assert [ln[len("DeviceAllow=") :] for ln in text.splitlines() if "=" in ln and
            not ln.startswith("#")] == allow  # fmt: skip


def test_install_writes_the_dropin_the_configuration_needs(tmp_path):
    # the real omnidevd of this environment (not the fake one): it reads the config
    bindir = Path(sys.executable).parent
    if not (bindir / "omnidevd").is_file():
        pytest.skip(f"no omnidevd beside {sys.executable} (not installed in this environment)")
    conf = _config_with_buttons(tmp_path / "etc/omnidev/omnidev.toml", "evdev:name=My Remote")
    proc = install(tmp_path, "--bin-dir", str(bindir))
    dropin = tmp_path / "etc/systemd/system/omnidevd.service.d/10-devices.conf"
    assert "DeviceAllow: char-input r" in proc.stdout, proc.stdout + proc.stderr
    lines = dropin.read_text().splitlines()
    assert "[Service]" in lines and "DeviceAllow=char-input r" in lines
    assert oct(dropin.stat().st_mode & 0o777) == oct(0o644)
    conf.write_text(conf.read_text().replace("evdev:name=My Remote", ""))  # buttons removed
    install(tmp_path, "--bin-dir", str(bindir))
    assert not any(ln.startswith("DeviceAllow") for ln in dropin.read_text().splitlines())
    conf.write_text(conf.read_text() + "\n[bogus]\n")  # a config the daemon refuses
    proc = install(tmp_path, "--bin-dir", str(bindir))
    assert "did not write /etc/systemd/system/omnidevd.service.d/10-devices.conf" in proc.stderr
    assert "bogus" in proc.stderr
    install(tmp_path, "--uninstall")
    assert not dropin.parent.exists()
