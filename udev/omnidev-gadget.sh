#!/bin/sh
# omnidev-gadget.sh: make this board a USB mouse for the computer its USB device
# port is plugged into (Linux USB HID gadget through configfs). omnidev's `hidg`
# sink then writes pointer reports to the /dev/hidgN node this creates.
#
# Usage (as root):
#   omnidev-gadget.sh [--mode absolute|relative] [--udc NAME]   set up and bind
#   omnidev-gadget.sh --remove                                  unbind and tear down
#   omnidev-gadget.sh --status                                  print what is set up
#
# Environment: UDC (same as --udc; default: the first controller in /sys/class/udc),
# OMNIDEV_GADGET_MODE (same as --mode; default absolute), SERIAL (USB serial string;
# default: from /etc/machine-id), CONFIGFS (default /sys/kernel/config).
#
# Idempotent: running it again with the same mode and UDC changes nothing; with
# another mode or UDC it tears the gadget down and builds it again.
# Installed as /usr/local/lib/omnidev/omnidev-gadget.sh and run by
# omnidev-gadget.service (see docs/hid-gadget.md).
#
# USB identity: 0x1d6b:0x0104 is the Linux Foundation's "Multifunction Composite
# Gadget" ID, which the kernel documentation uses for configfs gadgets; hosts
# identify the mouse by its HID class and report descriptor, not by this ID.
#
# The report descriptors below are generated from omnidev/hid_reports.py, the one
# source of truth (tests/test_hid_reports.py fails when they differ):
#   python -m omnidev.hid_reports --descriptor absolute --hex
#   python -m omnidev.hid_reports --descriptor relative --hex

# POSIX sh (dash runs it as well as bash).
set -eu

# absolute: 3 buttons + 5 bits padding, X/Y 16-bit 0..32767; 5-byte reports, subclass 0
ABSOLUTE_DESC_HEX=05010902a1010901a10005091901290315002501950375018102950175058103050109300931150026ff7f751095028102c0c0
ABSOLUTE_REPORT_LENGTH=5
ABSOLUTE_SUBCLASS=0
# relative: 3 buttons + 5 bits padding, X/Y/wheel int8 deltas; 4-byte reports,
# boot-protocol compatible, subclass 1 (boot interface)
RELATIVE_DESC_HEX=05010902a1010901a1000509190129031500250195037501810295017505810305010930093109381581257f750895038106c0c0
RELATIVE_REPORT_LENGTH=4
RELATIVE_SUBCLASS=1

VENDOR=0x1d6b
PRODUCT=0x0104
MANUFACTURER="omnidev"
PRODUCT_STRING="omnidev absolute pointer"
GADGET_NAME=omnidev
FUNCTION=hid.usb0
CONFIG=c.1

CONFIGFS=${CONFIGFS:-/sys/kernel/config}
GADGET=$CONFIGFS/usb_gadget/$GADGET_NAME

die() { echo "omnidev-gadget: $*" >&2; exit 1; }
say() { echo "omnidev-gadget: $*"; }

usage() {
    sed -n '5,13p' "$0" | sed 's/^# \{0,1\}//'
}

mode=${OMNIDEV_GADGET_MODE:-absolute}
udc=${UDC:-}
action=setup
while [ $# -gt 0 ]; do
    case $1 in
        --mode) [ $# -ge 2 ] || die "--mode needs absolute or relative"; mode=$2; shift 2 ;;
        --mode=*) mode=${1#--mode=}; shift ;;
        --udc) [ $# -ge 2 ] || die "--udc needs a controller name from /sys/class/udc"; udc=$2; shift 2 ;;
        --udc=*) udc=${1#--udc=}; shift ;;
        UDC=*) udc=${1#UDC=}; shift ;;
        --remove) action=remove; shift ;;
        --status) action=status; shift ;;
        -h|--help) usage; exit 0 ;;
        *) die "unknown argument '$1' (try --help)" ;;
    esac
done

case $mode in
    absolute) desc_hex=$ABSOLUTE_DESC_HEX; report_length=$ABSOLUTE_REPORT_LENGTH
              subclass=$ABSOLUTE_SUBCLASS; product_string=$PRODUCT_STRING ;;
    relative) desc_hex=$RELATIVE_DESC_HEX; report_length=$RELATIVE_REPORT_LENGTH
              subclass=$RELATIVE_SUBCLASS; product_string="omnidev relative pointer" ;;
    *) die "mode '$mode' is not absolute or relative" ;;
esac

[ "$(id -u)" -eq 0 ] || die "must run as root (configfs and modprobe need it)"

ensure_configfs() {
    modprobe -q libcomposite 2>/dev/null || true
    if [ ! -d "$CONFIGFS/usb_gadget" ]; then
        if ! grep -qs " $CONFIGFS configfs " /proc/mounts; then
            modprobe -q configfs 2>/dev/null || true
            mount -t configfs none "$CONFIGFS" \
                || die "cannot mount configfs on $CONFIGFS"
        fi
    fi
    [ -d "$CONFIGFS/usb_gadget" ] \
        || die "$CONFIGFS/usb_gadget is missing: this kernel lacks libcomposite (CONFIG_USB_LIBCOMPOSITE) or USB gadget configfs support"
}

# The current report descriptor of the gadget's HID function, as hex (empty if none).
current_desc_hex() {
    local f=$GADGET/functions/$FUNCTION/report_desc
    if [ -r "$f" ]; then od -An -v -tx1 "$f" | tr -d ' \n'; fi
}

current_udc() {
    if [ -r "$GADGET/UDC" ]; then cat "$GADGET/UDC"; fi
}

# /dev/hidgN of the function, found through its major:minor.
device_node() {
    local dev f
    dev=$(cat "$GADGET/functions/$FUNCTION/dev" 2>/dev/null) || return 0
    for f in /sys/class/hidg/*/dev; do
        [ -r "$f" ] || continue
        if [ "$(cat "$f")" = "$dev" ]; then
            echo "/dev/$(basename "$(dirname "$f")")"
            return 0
        fi
    done
}

remove_gadget() {
    [ -d "$GADGET" ] || { say "no gadget at $GADGET, nothing to remove"; return 0; }
    if [ -n "$(current_udc)" ]; then
        echo "" > "$GADGET/UDC" || die "cannot unbind $GADGET from its UDC"
    fi
    local c f
    for c in "$GADGET"/configs/*/; do
        [ -d "$c" ] || continue
        for f in "$c"*; do
            if [ -L "$f" ]; then rm -f "$f"; fi
        done
        if [ -d "${c}strings/0x409" ]; then rmdir "${c}strings/0x409"; fi
        rmdir "$c"
    done
    for f in "$GADGET"/functions/*/; do
        if [ -d "$f" ]; then rmdir "$f"; fi
    done
    if [ -d "$GADGET/strings/0x409" ]; then rmdir "$GADGET/strings/0x409"; fi
    rmdir "$GADGET"
    say "removed $GADGET"
}

pick_udc() {
    if [ -n "$udc" ]; then
        [ -e "/sys/class/udc/$udc" ] \
            || die "USB device controller '$udc' is not in /sys/class/udc (present: $(ls /sys/class/udc 2>/dev/null | tr '\n' ' '))"
        return 0
    fi
    udc=$(ls /sys/class/udc 2>/dev/null | head -n 1 || true)
    [ -n "$udc" ] || die "no USB device controller in /sys/class/udc: the USB port must be in device (peripheral/OTG) mode, e.g. on a Raspberry Pi add dtoverlay=dwc2 to config.txt and load the dwc2 module (see docs/hid-gadget.md); for a test without hardware, modprobe dummy_hcd"
}

# Hex text to bytes, with POSIX printf only (octal escapes in the format).
write_hex() {
    fmt="" rest=$1
    while [ -n "$rest" ]; do
        fmt="$fmt$(printf '\\%03o' "0x$(printf '%.2s' "$rest")")"
        rest=${rest#??}
    done
    # shellcheck disable=SC2059  # the format is the descriptor's octal escapes
    printf "$fmt"
}

serial_number() {
    if [ -n "${SERIAL:-}" ]; then echo "$SERIAL"; return; fi
    local s
    s=$(tr -d '\0' 2>/dev/null < /proc/device-tree/serial-number || true)
    [ -n "$s" ] || s=$(head -c 16 /etc/machine-id 2>/dev/null || true)
    echo "${s:-0}"
}

setup_gadget() {
    pick_udc
    if [ -d "$GADGET" ]; then
        if [ "$(current_desc_hex)" = "$desc_hex" ] && [ "$(current_udc)" = "$udc" ]; then
            say "already set up: $mode mode on $udc, $(device_node)"
            return 0
        fi
        say "rebuilding $GADGET ($mode mode on $udc)"
        remove_gadget
    fi

    modprobe -q usb_f_hid 2>/dev/null || true
    mkdir "$GADGET"
    cd "$GADGET"
    echo "$VENDOR" > idVendor
    echo "$PRODUCT" > idProduct
    echo 0x0100 > bcdDevice
    echo 0x0200 > bcdUSB
    mkdir -p strings/0x409
    echo "$MANUFACTURER" > strings/0x409/manufacturer
    echo "$product_string" > strings/0x409/product
    serial_number > strings/0x409/serialnumber

    mkdir -p "configs/$CONFIG/strings/0x409"
    echo "omnidev pointer ($mode)" > "configs/$CONFIG/strings/0x409/configuration"
    echo 0x80 > "configs/$CONFIG/bmAttributes"    # bus powered
    echo 100 > "configs/$CONFIG/MaxPower"         # mA

    mkdir "functions/$FUNCTION" \
        || die "cannot create functions/$FUNCTION: is usb_f_hid available (CONFIG_USB_CONFIGFS_F_HID)?"
    echo 2 > "functions/$FUNCTION/protocol"        # mouse
    echo "$subclass" > "functions/$FUNCTION/subclass"
    echo "$report_length" > "functions/$FUNCTION/report_length"
    # A mouse receives nothing: no interrupt OUT endpoint (attribute since Linux 5.14).
    if [ -e "functions/$FUNCTION/no_out_endpoint" ]; then
        echo 1 > "functions/$FUNCTION/no_out_endpoint"
    fi
    write_hex "$desc_hex" > "functions/$FUNCTION/report_desc"
    [ "$(current_desc_hex)" = "$desc_hex" ] || die "report_desc did not read back as written"
    ln -s "functions/$FUNCTION" "configs/$CONFIG/"

    if ! echo "$udc" > UDC; then
        die "cannot bind to $udc (busy? another gadget may be bound to it: cat /sys/kernel/config/usb_gadget/*/UDC)"
    fi
    say "bound to $udc: $mode mode, $report_length-byte reports, $(device_node)"
}

case $action in
    remove) ensure_configfs; remove_gadget ;;
    status)
        ensure_configfs
        if [ -d "$GADGET" ]; then
            case $(current_desc_hex) in
                "$ABSOLUTE_DESC_HEX") m=absolute ;;
                "$RELATIVE_DESC_HEX") m=relative ;;
                *) m=unknown ;;
            esac
            say "$GADGET: $m mode, UDC '$(current_udc)', $(device_node)"
        else
            say "no gadget at $GADGET"
            exit 3
        fi ;;
    setup) ensure_configfs; setup_gadget ;;
esac
