#!/bin/sh
# Install the Debian packages omnidev's tests and hardware adapters need, if missing.
#   qemu-system-x86 linux-image-amd64 busybox-static  a real kernel for tests/vm (virtme-ng)
#   libinput-tools udev kmod                          libinput as the real client, inside the VM
#   v4l-utils                                         v4l2-ctl for vivid's video loop
#   xvfb xdotool                                      a real X server for the xtest sink
#   ffmpeg                                            the anchor of the video benchmarks; H.264 in the scene renderers
#   libudev-dev libusb-1.0-0-dev                      build python-uinput and hidapi
# Needs root (or sudo). OMNIDEV_NO_APT=1 skips it (then the tests say what is missing).
set -eu
PKGS="qemu-system-x86 linux-image-amd64 busybox-static libinput-tools udev kmod v4l-utils \
xvfb xdotool ffmpeg libudev-dev libusb-1.0-0-dev"
[ "${OMNIDEV_NO_APT:-0}" = 1 ] && exit 0
missing=""
for p in $PKGS; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
[ -z "$missing" ] && exit 0
SUDO=""
[ "$(id -u)" = 0 ] || SUDO="sudo"
echo "installing Debian packages:$missing"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $missing >/dev/null
