#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# test_unit.sh BUILD -- systemd/afmtwind.service passes `systemd-analyze verify` (with
# ExecStart pointed at BUILD's afmtwind and the repository's default.conf, as `make install`
# rewrites it for PREFIX and SYSCONFDIR, and its Documentation= man pages found among BUILD's
# generated ones), and keeps the promised settings: Type=notify, a watchdog, an
# unprivileged dynamic user with only CAP_SYS_NICE and CAP_IPC_LOCK, NoNewPrivileges and
# ProtectSystem=strict.
set -u
BUILD=${1:-build}
cd "$(dirname "$0")/.."
pass=0; fail=0
ok() { echo "ok   $1"; pass=$((pass+1)); }
bad() { echo "FAIL $1"; fail=$((fail+1)); }
unit=systemd/afmtwind.service
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
case "$BUILD" in /*) bin=$BUILD/bin/afmtwind ;; *) bin=$PWD/$BUILD/bin/afmtwind ;; esac
sed "s|/usr/local/bin/afmtwind|$bin|; s|/usr/local/etc/afmtwin/afmtwind.conf|$PWD/config/default.conf|" \
  "$unit" > "$tmp/afmtwind.service"
# verify runs `man` for every man: page in Documentation=
mkdir -p "$tmp/man/man1" "$tmp/man/man8"
cp "$BUILD/man/afmtwin.1" "$tmp/man/man1/" 2>/dev/null; cp "$BUILD/man/afmtwind.8" "$tmp/man/man8/" 2>/dev/null
export MANPATH="$tmp/man"
if ! command -v systemd-analyze >/dev/null; then
  bad "systemd-analyze not installed (Debian package systemd; make deps installs it)"
elif out=$(systemd-analyze verify "$tmp/afmtwind.service" 2>&1) && [ -z "$out" ]; then
  ok "systemd-analyze verify: clean"
else
  bad "systemd-analyze verify: $out"
fi
for want in 'Type=notify' 'WatchdogSec=' 'DynamicUser=yes' 'NoNewPrivileges=yes' \
            'ProtectSystem=strict' 'ProtectHome=yes' 'PrivateTmp=yes' \
            'CapabilityBoundingSet=CAP_SYS_NICE CAP_IPC_LOCK' \
            'AmbientCapabilities=CAP_SYS_NICE CAP_IPC_LOCK' 'LimitRTPRIO=' 'LimitMEMLOCK='; do
  if grep -q "^$want" "$unit"; then ok "unit has $want"; else bad "unit lacks $want"; fi
done
# Every address family the daemon opens a socket of is one the unit allows (issue 13: the
# unit left out AF_CAN, so the CAN transport could never open its socket under systemd).
# LCM's own sockets (liblcm, udpm) are AF_INET; sd_notify's AF_UNIX.
allowed=$(sed -n 's/^RestrictAddressFamilies=//p' "$unit")
used=$( { grep -rhoE 'socket\((PF|AF)_[A-Z0-9]+' daemon/ | sed 's/socket(//; s/^PF_/AF_/'; echo AF_INET; echo AF_UNIX; } | sort -u)
for fam in $used; do
  case " $allowed " in
    *" $fam "*) ok "RestrictAddressFamilies allows $fam (opened by the daemon)" ;;
    *) bad "RestrictAddressFamilies lacks $fam, which the daemon opens (allowed: $allowed)" ;;
  esac
done
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
