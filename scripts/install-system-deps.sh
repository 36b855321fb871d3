#!/bin/sh
# Install the Debian packages omnidev's tests and hardware adapters need, if missing.
#   qemu-system-x86 linux-image-amd64 busybox-static  a real kernel for tests/vm (virtme-ng)
#   libinput-tools udev kmod                          libinput as the real client, inside the VM
#   v4l-utils                                         v4l2-ctl for vivid's video loop
#   xvfb xdotool                                      a real X server for the xtest sink
#   ffmpeg                                            the anchor of the video benchmarks; H.264 in the scene renderers
#   dkms v4l2loopback-dkms linux-headers-KERNEL       v4l2loopback built for the VM's kernel (the v4l2: output's tests)
#   libudev-dev libusb-1.0-0-dev                      build python-uinput and hidapi
# Needs root (or sudo). OMNIDEV_NO_APT=1 skips it (then the tests say what is missing).
set -eu
PKGS="qemu-system-x86 linux-image-amd64 busybox-static libinput-tools udev kmod v4l-utils \
xvfb xdotool ffmpeg libudev-dev libusb-1.0-0-dev dkms v4l2loopback-dkms"
[ "${OMNIDEV_NO_APT:-0}" = 1 ] && exit 0
SUDO=""
[ "$(id -u)" = 0 ] || SUDO="sudo"
updated=0
install() {
    missing=""
    for p in "$@"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
    done
    [ -z "$missing" ] && return 0
    echo "installing Debian packages:$missing"
    [ "$updated" = 1 ] || { $SUDO apt-get update -qq; updated=1; }
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $missing >/dev/null
}
install $PKGS
# v4l2loopback for the kernel the test VM boots (tests/test_kernel_vm.py: the newest
# /boot/vmlinuz-*-amd64), which need not be the running one: its headers, then DKMS.
kernel=$(ls /boot/vmlinuz-*-amd64 2>/dev/null | sort | tail -n 1)
[ -n "$kernel" ] || exit 0
version=${kernel#/boot/vmlinuz-}
install "linux-headers-$version"
if ! find "/lib/modules/$version" -name 'v4l2loopback.ko*' 2>/dev/null | grep -q .; then
    module=$(dkms status v4l2loopback 2>/dev/null | head -n 1 | sed 's/[,:].*//')
    echo "building $module for kernel $version"
    $SUDO dkms install "$module" -k "$version" >/dev/null
fi
