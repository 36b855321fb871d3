#!/bin/sh
# install-system-files.sh: put omnidev's udev rules, systemd units, module list and
# example configuration in the standard places (the body of `sudo make install`).
#
# Usage (as root):
#   scripts/install-system-files.sh [--bin-dir DIR] [--camera VID:PID[:SERIAL]]
#   scripts/install-system-files.sh --uninstall
#
#   --bin-dir DIR   directory holding the omnidevd command the unit runs (default:
#                   where `omnidevd` is on PATH, else this checkout's .venv/bin,
#                   else /usr/local/bin). It must be readable by user omnidev, so a
#                   virtualenv under /opt suits better than one in a home directory.
#   --camera ID     also write 61-omnidev-camera.rules: start omnidevd when the USB
#                   camera VID:PID (lowercase hex, as `lsusb` shows; optional :SERIAL)
#                   appears. Without it a previously written camera rule is kept.
#   --uninstall     stop and disable the units, remove every installed file; keep
#                   /etc/omnidev/omnidev.toml and the user omnidev (says so).
#
# What goes where:
#   udev/*.rules                  -> /etc/udev/rules.d/
#   udev/modules-load.d/*.conf    -> /etc/modules-load.d/
#   udev/*.service                -> /etc/systemd/system/   (omnidevd: ExecStart rewritten)
#   omnidevd --device-allow       -> /etc/systemd/system/omnidevd.service.d/10-devices.conf
#                                    (DeviceAllow= for the configuration's [buttons] input)
#   udev/*.sh                     -> /usr/local/lib/omnidev/
#   udev/omnidev.toml.example     -> /etc/omnidev/omnidev.toml (only if absent) and
#                                    /usr/local/share/doc/omnidev/
#   docs/daemon.md, docs/hid-gadget.md -> /usr/local/share/doc/omnidev/
#   fixtures/blob/blob.avi        -> /usr/local/share/omnidev/ (the no-camera trial)
# then creates the system user omnidev (groups input, video), loads uinput, and
# reloads udev and systemd when they run.
#
# DESTDIR=/some/root installs below that directory instead and touches nothing of
# the running system (no udevadm/systemctl/modprobe); the user is then only created
# when DESTDIR/etc/passwd exists (useradd --prefix), which the tests use.
set -eu

SRC=$(cd "$(dirname "$0")/.." && pwd)
DESTDIR=${DESTDIR:-}
RULES_DIR=/etc/udev/rules.d
MODULES_DIR=/etc/modules-load.d
UNIT_DIR=/etc/systemd/system
CONF_DIR=/etc/omnidev
LIB_DIR=/usr/local/lib/omnidev
DOC_DIR=/usr/local/share/doc/omnidev
SHARE_DIR=/usr/local/share/omnidev
CAMERA_RULE=61-omnidev-camera.rules
USER_NAME=omnidev

say() { echo "omnidev install: $*"; }
warn() { echo "omnidev install: warning: $*" >&2; }
die() {
    echo "omnidev install: error: $*" >&2
    exit 2
}

uninstall=0
camera=""
bin_dir=""
while [ $# -gt 0 ]; do
    case "$1" in
    --uninstall) uninstall=1 ;;
    --camera)
        [ $# -ge 2 ] || die "--camera needs VID:PID[:SERIAL]"
        camera=$2
        shift
        ;;
    --camera=*) camera=${1#--camera=} ;;
    --bin-dir)
        [ $# -ge 2 ] || die "--bin-dir needs a directory"
        bin_dir=$2
        shift
        ;;
    --bin-dir=*) bin_dir=${1#--bin-dir=} ;;
    -h | --help)
        sed -n '2,/^set -eu/p' "$0" | sed '$d; s/^# \{0,1\}//'
        exit 0
        ;;
    *) die "unknown argument '$1' (see --help)" ;;
    esac
    shift
done

live=0 # 1: acting on the running system (no DESTDIR)
if [ -z "$DESTDIR" ]; then
    live=1
    [ "$(id -u)" = 0 ] || die "needs root: run 'sudo $0' (or set DESTDIR to install into a directory)"
fi

systemd_running() { [ "$live" = 1 ] && [ -d /run/systemd/system ] && command -v systemctl >/dev/null; }

# The files this script owns, as "source destination mode" lines (sources relative to SRC).
manifest() {
    for f in "$SRC"/udev/*.rules; do
        [ -e "$f" ] && echo "udev/${f##*/} $RULES_DIR/${f##*/} 0644"
    done
    for f in "$SRC"/udev/modules-load.d/*.conf; do
        [ -e "$f" ] && echo "udev/modules-load.d/${f##*/} $MODULES_DIR/${f##*/} 0644"
    done
    for f in "$SRC"/udev/*.service; do
        [ -e "$f" ] && echo "udev/${f##*/} $UNIT_DIR/${f##*/} 0644"
    done
    for f in "$SRC"/udev/*.sh; do
        [ -e "$f" ] && echo "udev/${f##*/} $LIB_DIR/${f##*/} 0755"
    done
    echo "udev/omnidev.toml.example $DOC_DIR/omnidev.toml.example 0644"
    for f in daemon.md hid-gadget.md; do
        [ -e "$SRC/docs/$f" ] && echo "docs/$f $DOC_DIR/$f 0644"
    done
    [ -e "$SRC/fixtures/blob/blob.avi" ] && echo "fixtures/blob/blob.avi $SHARE_DIR/blob.avi 0644"
    return 0
}

units() {
    for f in "$SRC"/udev/*.service; do
        [ -e "$f" ] && echo "${f##*/}"
    done
    return 0
}

reload_system() {
    if [ "$live" = 1 ] && command -v udevadm >/dev/null; then
        if udevadm control --reload 2>/dev/null; then
            # apply the new GROUP/MODE to nodes that already exist
            udevadm trigger --action=change --subsystem-match=misc --sysname-match=uinput || true
            udevadm trigger --action=change --subsystem-match=hidg || true
        else
            warn "udevadm control --reload failed (is systemd-udevd running?); the rules apply from the next boot"
        fi
    fi
    if systemd_running; then
        systemctl daemon-reload
    fi
    return 0
}

if [ "$uninstall" = 1 ]; then
    if systemd_running; then
        for u in $(units); do
            systemctl disable --now "$u" 2>/dev/null || true
        done
    fi
    manifest | while read -r src dest mode; do
        if [ -e "$DESTDIR$dest" ]; then
            rm -f "$DESTDIR$dest"
            say "removed $dest"
        fi
    done
    if [ -e "$DESTDIR$RULES_DIR/$CAMERA_RULE" ]; then
        rm -f "$DESTDIR$RULES_DIR/$CAMERA_RULE"
        say "removed $RULES_DIR/$CAMERA_RULE"
    fi
    if [ -e "$DESTDIR$UNIT_DIR/omnidevd.service.d/10-devices.conf" ]; then
        rm -f "$DESTDIR$UNIT_DIR/omnidevd.service.d/10-devices.conf"
        rmdir "$DESTDIR$UNIT_DIR/omnidevd.service.d" 2>/dev/null || true
        say "removed $UNIT_DIR/omnidevd.service.d/10-devices.conf"
    fi
    rmdir "$DESTDIR$LIB_DIR" "$DESTDIR$DOC_DIR" "$DESTDIR$SHARE_DIR" 2>/dev/null || true
    reload_system
    say "kept $CONF_DIR/omnidev.toml and the user $USER_NAME (remove them with: rm -r $CONF_DIR; userdel $USER_NAME)"
    exit 0
fi

# -- where omnidevd is -----------------------------------------------------------
if [ -z "$bin_dir" ]; then
    if command -v omnidevd >/dev/null 2>&1; then
        bin_dir=$(dirname "$(command -v omnidevd)")
    elif [ -x "$SRC/.venv/bin/omnidevd" ]; then
        bin_dir=$SRC/.venv/bin
    else
        bin_dir=/usr/local/bin
        warn "omnidevd not found on PATH nor in $SRC/.venv; the unit runs $bin_dir/omnidevd (use --bin-dir)"
    fi
fi
case "$bin_dir" in
/*) ;;
*) bin_dir=$(cd "$bin_dir" 2>/dev/null && pwd) || die "--bin-dir: no such directory" ;;
esac
case "$bin_dir" in
*[[:space:]\|\\\"\'%\$]*) die "--bin-dir '$bin_dir': systemd's ExecStart cannot take this path as it is; use a path without spaces or quotes" ;;
esac
[ -x "$bin_dir/omnidevd" ] || warn "$bin_dir/omnidevd is not an executable (yet)"

# -- camera rule -----------------------------------------------------------------
camera_rule=""
if [ -n "$camera" ]; then
    case "$camera" in
    *:*) ;;
    *) die "--camera '$camera': expected VID:PID[:SERIAL] (as lsusb shows)" ;;
    esac
    vid=$(echo "$camera" | cut -d: -f1 | tr 'A-F' 'a-f')
    pid=$(echo "$camera" | cut -d: -f2 | tr 'A-F' 'a-f')
    serial=$(echo "$camera" | cut -s -d: -f3-)
    echo "$vid" | grep -Eq '^[0-9a-f]{4}$' || die "--camera '$camera': vendor id must be 4 hex digits (VID:PID as lsusb shows)"
    echo "$pid" | grep -Eq '^[0-9a-f]{4}$' || die "--camera '$camera': product id must be 4 hex digits (VID:PID as lsusb shows)"
    case "$serial" in
    *[!A-Za-z0-9._-]*) die "--camera '$camera': serial may hold only letters, digits, '.', '_', '-'" ;;
    esac
    match="ENV{ID_VENDOR_ID}==\"$vid\", ENV{ID_MODEL_ID}==\"$pid\""
    [ -n "$serial" ] && match="$match, ENV{ID_SERIAL_SHORT}==\"$serial\""
    camera_rule=$(
        cat <<EOF
# omnidev: start omnidevd when the camera $camera appears.
# Written by scripts/install-system-files.sh --camera $camera; rewrite it the same way.
# Numbered 61 so that it runs after 60-persistent-v4l.rules, which sets ID_VENDOR_ID,
# ID_MODEL_ID, ID_SERIAL_SHORT (usb_id) and ID_V4L_CAPABILITIES (v4l_id).
# Only the capture node (a UVC camera also has a metadata node). SYSTEMD_WANTS asks
# systemd to start the unit; the daemon keeps running when the camera goes away.
SUBSYSTEM=="video4linux", ACTION=="add", $match, ENV{ID_V4L_CAPABILITIES}=="*:capture:*", TAG+="systemd", ENV{SYSTEMD_WANTS}+="omnidevd.service"
EOF
    )
fi

# -- files -----------------------------------------------------------------------
manifest | while read -r src dest mode; do
    install -d -m 0755 "$DESTDIR$(dirname "$dest")"
    case "$src" in
    udev/omnidevd*.service)
        tmp=$(mktemp)
        sed "s|^ExecStart=/usr/local/bin/omnidevd |ExecStart=$bin_dir/omnidevd |" "$SRC/$src" >"$tmp"
        install -m "$mode" "$tmp" "$DESTDIR$dest"
        rm -f "$tmp"
        ;;
    *) install -m "$mode" "$SRC/$src" "$DESTDIR$dest" ;;
    esac
    say "installed $dest"
done

if [ -n "$camera_rule" ]; then
    printf '%s\n' "$camera_rule" >"$DESTDIR$RULES_DIR/$CAMERA_RULE"
    chmod 0644 "$DESTDIR$RULES_DIR/$CAMERA_RULE"
    say "installed $RULES_DIR/$CAMERA_RULE (camera $camera)"
fi

install -d -m 0755 "$DESTDIR$CONF_DIR"
if [ -e "$DESTDIR$CONF_DIR/omnidev.toml" ]; then
    say "kept the existing $CONF_DIR/omnidev.toml (the example is $DOC_DIR/omnidev.toml.example)"
else
    install -m 0644 "$SRC/udev/omnidev.toml.example" "$DESTDIR$CONF_DIR/omnidev.toml"
    say "installed $CONF_DIR/omnidev.toml: edit it for your camera, tracker, sink and screen"
fi

# -- the devices the configuration's button input needs (omnidev/daemon/unit.py) --
dropin_dir=$UNIT_DIR/omnidevd.service.d
tmp=$(mktemp)
if "$bin_dir/omnidevd" --config "$DESTDIR$CONF_DIR/omnidev.toml" --device-allow >"$tmp" 2>&1 &&
    grep -q '^\[Service\]' "$tmp"; then
    install -d -m 0755 "$DESTDIR$dropin_dir"
    install -m 0644 "$tmp" "$DESTDIR$dropin_dir/10-devices.conf"
    allow=$(sed -n 's/^DeviceAllow=//p' "$tmp" | tr '\n' ',' | sed 's/,$//; s/,/, /g')
    say "installed $dropin_dir/10-devices.conf (DeviceAllow: ${allow:-nothing beyond the unit's})"
else
    warn "did not write $dropin_dir/10-devices.conf: '$bin_dir/omnidevd --device-allow' failed:" \
        "$(tail -n 1 "$tmp"). A [buttons] input then cannot open its device under the unit;" \
        "fix the configuration and run this again"
fi
rm -f "$tmp"

# -- the system user -------------------------------------------------------------
prefix_opt=""
user_db=0 # 1: a passwd database to act on
if [ "$live" = 1 ]; then
    user_db=1
elif [ -f "$DESTDIR/etc/passwd" ] && [ -f "$DESTDIR/etc/group" ]; then
    user_db=1
    prefix_opt="--prefix $DESTDIR"
fi
if [ "$user_db" = 1 ]; then
    group_exists() { grep -q "^$1:" "$DESTDIR/etc/group" || { [ "$live" = 1 ] && getent group "$1" >/dev/null; }; }
    user_exists() { grep -q "^$1:" "$DESTDIR/etc/passwd" || { [ "$live" = 1 ] && getent passwd "$1" >/dev/null; }; }
    for g in input video; do
        # shellcheck disable=SC2086
        group_exists "$g" || groupadd $prefix_opt --system "$g"
    done
    nologin=$(command -v nologin || echo /usr/sbin/nologin)
    if user_exists "$USER_NAME"; then
        # shellcheck disable=SC2086
        usermod $prefix_opt --append --groups input,video "$USER_NAME"
        say "user $USER_NAME exists; made sure it is in groups input, video"
    else
        # shellcheck disable=SC2086
        useradd $prefix_opt --system --user-group --no-create-home --home-dir /nonexistent \
            --shell "$nologin" --groups input,video --comment "omnidev pointer daemon" "$USER_NAME"
        say "created the system user $USER_NAME (groups input, video)"
    fi
else
    say "DESTDIR without etc/passwd: not creating the user $USER_NAME"
fi

if [ "$live" = 1 ] && [ -x "$bin_dir/omnidevd" ] && command -v runuser >/dev/null; then
    if ! runuser -u "$USER_NAME" -- "$bin_dir/omnidevd" --help >/dev/null 2>&1; then
        warn "user $USER_NAME cannot run $bin_dir/omnidevd (a home directory with mode 0700?)." \
            "Install omnidev where every user can read it, e.g. a virtualenv in /opt/omnidev" \
            "(docs/daemon.md), then run this again with --bin-dir /opt/omnidev/bin"
    fi
fi

# -- the running system ----------------------------------------------------------
if [ "$live" = 1 ] && command -v modprobe >/dev/null; then
    modprobe uinput 2>/dev/null || warn "modprobe uinput failed; the uinput sink needs it (it loads at boot from $MODULES_DIR/omnidev.conf)"
fi
reload_system
say "done. Next: edit $CONF_DIR/omnidev.toml, then: sudo systemctl enable --now omnidevd"
