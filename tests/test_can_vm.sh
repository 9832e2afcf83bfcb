#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# test_can_vm.sh BUILD -- the CAN transport against a real kernel CAN stack. This host's
# kernel may have no AF_CAN, so a small VM is booted under QEMU (TCG: software emulation,
# always under `timeout`): a Debian kernel from its package (unpacked with dpkg-deb, never
# installed; cached in BUILD/can-vm), a busybox-static initramfs that loads can, can-raw,
# can-dev and vcan, creates vcan0 and runs tests/can_vm_probe.c (static) on
# tests/can_vm.conf. The probe's check lines and "N passed, N failed" come back on the
# serial console, with the exit code as "CANVM-EXIT=<rc>".
# Needs: qemu-system-x86, busybox-static, cpio (installed here when missing and root; also
# in `make deps`), and the kernel package once (apt-get download). AFMTWIN_SKIP_CAN_VM=1
# skips the test (it then reports 0 passed, 0 failed and says so).
set -uo pipefail
BUILD=${1:-build}
cd "$(dirname "$0")/.."
WORK="$BUILD/can-vm"
mkdir -p "$WORK"

fail() { echo "test_can_vm: $*"; echo "0 passed, 1 failed"; exit 1; }

if [ "${AFMTWIN_SKIP_CAN_VM:-0}" = 1 ]; then
  echo "test_can_vm: skipped (AFMTWIN_SKIP_CAN_VM=1)"; echo "0 passed, 0 failed"; exit 0
fi

# 1) host packages
need=()
command -v qemu-system-x86_64 >/dev/null || need+=(qemu-system-x86)
[ -x /bin/busybox ] && dpkg -s busybox-static >/dev/null 2>&1 || need+=(busybox-static)
command -v cpio >/dev/null || need+=(cpio)
if [ ${#need[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
  echo "test_can_vm: installing ${need[*]}"
  { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive \
      $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}"; } >/dev/null 2>&1 ||
    fail "cannot install ${need[*]} (run make deps as root)"
fi

# 2) kernel and the four CAN modules from the Debian package (cached)
if ! ls "$WORK"/k/boot/vmlinuz-* >/dev/null 2>&1; then
  KPKG=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/{print $2; exit}')
  if [ -z "$KPKG" ]; then
    SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
    $SUDO apt-get update -qq >/dev/null 2>&1
    KPKG=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/{print $2; exit}')
  fi
  [ -n "$KPKG" ] || fail "no linux-image-amd64 in the apt lists"
  (cd "$WORK" && apt-get download -qq "$KPKG" >/dev/null 2>&1) || fail "cannot download $KPKG"
  rm -rf "$WORK/k"; mkdir -p "$WORK/k"
  dpkg-deb --fsys-tarfile "$WORK/$KPKG"_*.deb | tar -x -C "$WORK/k" --wildcards \
    './boot/vmlinuz-*' './lib/modules/*/kernel/net/can/can.ko' \
    './lib/modules/*/kernel/net/can/can-raw.ko' \
    './lib/modules/*/kernel/drivers/net/can/dev/can-dev.ko' \
    './lib/modules/*/kernel/drivers/net/can/vcan.ko' || fail "cannot unpack $KPKG"
  rm -f "$WORK/$KPKG"_*.deb
fi
KERNEL=$(ls "$WORK"/k/boot/vmlinuz-* | head -1)

# 3) the probe (static)
make -s BUILD="$BUILD" can-probe >"$WORK/build.log" 2>&1 ||
  { cat "$WORK/build.log"; fail "cannot build $BUILD/tests/can_vm_probe"; }

# 4) initramfs
R="$WORK/root"; rm -rf "$R"; mkdir -p "$R"/{bin,proc,sys,dev,lib/modules}
cp /bin/busybox "$R/bin/"
for a in sh mount insmod ip poweroff dd printf echo cat; do ln -s busybox "$R/bin/$a"; done
find "$WORK/k/lib/modules" -name '*.ko' -exec cp {} "$R/lib/modules/" \;
cp "$BUILD/tests/can_vm_probe" "$R/bin/probe"
cp tests/can_vm.conf "$R/can_vm.conf"
cat > "$R/init" <<'INIT'
#!/bin/sh
export PATH=/bin
mount -t proc proc /proc; mount -t sysfs sys /sys; mount -t devtmpfs dev /dev
for m in can can-raw can-dev vcan; do insmod /lib/modules/$m.ko || echo "insmod $m failed"; done
ip link add dev vcan0 type vcan && ip link set vcan0 up
/bin/probe /can_vm.conf; rc=$?
echo "CANVM-EXIT=$rc"
poweroff -f
INIT
chmod +x "$R/init"
(cd "$R" && find . | cpio -o -H newc --quiet | gzip -1) > "$WORK/initrd.cpio.gz"

# 5) boot (TCG; -cpu max for the AVX2/FMA the engine is built with)
timeout 180 qemu-system-x86_64 -accel tcg -cpu max -m 256 -display none -serial stdio \
  -nic none -no-reboot -kernel "$KERNEL" -initrd "$WORK/initrd.cpio.gz" \
  -append 'console=ttyS0 quiet panic=-1' >"$WORK/console.log" 2>&1
qrc=$?
tr -d '\r' < "$WORK/console.log" | sed -n '/^\(ok\|FAIL\|  \|[0-9]* passed\|CANVM-EXIT\|can_vm_probe\|insmod\)/p'
rc=$(tr -d '\r' < "$WORK/console.log" | sed -n 's/^CANVM-EXIT=\([0-9]*\).*/\1/p' | tail -1)
[ -n "$rc" ] || { tail -20 "$WORK/console.log"; fail "the VM reported no result (qemu exit $qrc)"; }
tr -d '\r' < "$WORK/console.log" | grep -qE '^[0-9]+ passed, [0-9]+ failed' ||
  fail "the probe printed no result line (exit $rc)"
exit "$rc"
