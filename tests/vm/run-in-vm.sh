#!/bin/sh
# Runs INSIDE the virtme-ng VM (as root) that tests/test_kernel_vm.py boots:
# loads the kernel modules the real-kernel tests need, starts udev, and runs
# pytest on tests/vm. Usage: run-in-vm.sh OUTDIR [PYTHON [PYTEST-ARGS...]]
#   OUTDIR  a folder shared with the host (vng --rwdir): gets booted, junit.xml,
#           figures.json (measured figures) and pytest.log; the rest of the host
#           filesystem is read-only in here (write only to OUTDIR or /tmp).
#   PYTHON  the project's virtualenv python (default: REPO/.venv/bin/python).
#   PYTEST-ARGS  what to run instead of all of tests/vm (e.g. tests/vm/test_v4l2.py).
set -u
OUT=$1
REPO=$(cd "$(dirname "$0")/../.." && pwd)
PYTHON=${2:-$REPO/.venv/bin/python}
shift; [ $# -gt 0 ] && shift
[ $# -gt 0 ] || set -- tests/vm
echo "$(uname -r)" > "$OUT/booted"

log() { echo "run-in-vm [$(cut -d" " -f1 /proc/uptime) s]: $*" | tee -a "$OUT/stages.log"; }

log "booted"
# Each module is loaded on its own, so one that is missing does not stop the
# others; the tests that need it then fail and say so.
modprobe uinput || log "modprobe uinput failed"
# vivid: one instance, video capture (0x1) + video output (0x100) nodes.
modprobe vivid n_devs=1 node_types=0x101 || log "modprobe vivid failed"
# v4l2loopback (Debian's v4l2loopback-dkms, built for this kernel by
# scripts/install-system-deps.sh): /dev/video10 for omnidev's v4l2: output
# (tests/vm/test_v4l2_output.py), set up as docs/outputs.md tells users.
modprobe v4l2loopback video_nr=10 card_label="omnidev loopback" exclusive_caps=1 max_buffers=8 \
    || log "modprobe v4l2loopback failed"
for m in dummy_hcd libcomposite usb_f_hid usbhid hid_generic; do
    modprobe "$m" || log "modprobe $m failed"
done
mountpoint -q /sys/kernel/config || mount -t configfs none /sys/kernel/config \
    || log "mounting configfs failed"

log "modules loaded"
# The project's own udev rules, as `make install` would put them (tests/vm/test_udev_rules.py).
mkdir -p /run/udev/rules.d && cp "$REPO/udev/60-omnidev.rules" \
    "$REPO/udev/62-omnidev-v4l2loopback.rules" /run/udev/rules.d/
# udev gives input devices their ID_INPUT_* properties (libinput needs them).
/lib/systemd/systemd-udevd --daemon
log "udevd started"
udevadm trigger
udevadm settle --timeout=60

log "udev settled"
cd "$REPO" || exit 2
# The repository is read-only here: no bytecode, no pytest cache.
export PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1
export OMNIDEV_IN_VM=1 OMNIDEV_VM_OUT="$OUT/figures.json"
unset DISPLAY WAYLAND_DISPLAY
"$PYTHON" -m pytest -p no:cacheprovider -v -ra --durations=12 \
    --junitxml="$OUT/junit.xml" -o junit_family=xunit1 \
    "$@" 2>&1 | tee "$OUT/pytest.log"
log "pytest finished"
