"""udev/60-omnidev.rules applied by the real udevd (run-in-vm.sh installs it in
/run/udev/rules.d): /dev/uinput and the gadget's /dev/hidgN belong to group input, 0660."""

from __future__ import annotations

import grp
import os
import stat
import subprocess
from pathlib import Path


def _owner_mode(path: str) -> tuple[str, int]:
    st = os.stat(path)
    return grp.getgrgid(st.st_gid).gr_name, stat.S_IMODE(st.st_mode)


def test_uinput_node_is_group_input_0660():
    subprocess.run(["udevadm", "trigger", "--sysname-match=uinput"], check=True)
    subprocess.run(["udevadm", "settle", "--timeout=30"], check=True)
    assert _owner_mode("/dev/uinput") == ("input", 0o660)


def test_hidg_nodes_are_group_input_0660():
    nodes = sorted(Path("/dev").glob("hidg*"))
    if not nodes:  # the gadget tests tear theirs down; make one with the shipped script
        script = Path(__file__).resolve().parents[2] / "udev" / "omnidev-gadget.sh"
        subprocess.run(["sh", str(script)], check=True, env={**os.environ, "UDC": "dummy_udc.0"})
        subprocess.run(["udevadm", "settle", "--timeout=30"], check=True)
        nodes = sorted(Path("/dev").glob("hidg*"))
        try:
            assert nodes, "the gadget script made no /dev/hidgN"
            assert _owner_mode(str(nodes[0])) == ("input", 0o660)
        finally:
            subprocess.run(["sh", str(script), "--remove"], check=False)
    else:
        assert _owner_mode(str(nodes[0])) == ("input", 0o660)
