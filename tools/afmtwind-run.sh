#!/bin/sh
# SPDX-License-Identifier: MIT
# afmtwind-run.sh BUILD CONFIG -- what `make run` does: afmtwind in the foreground on CONFIG.
#  - LCM_DEFAULT_URL set: the daemon uses it (the user chose the transport).
#  - else, if this host routes multicast (ip route get 239.255.76.67 succeeds): LCM's
#    default udpm URL, ttl=0, so packets stay on this host.
#  - else (e.g. a container without a multicast route): a private network namespace whose
#    loopback carries multicast (needs root or unprivileged user namespaces); clients join
#    it with `nsenter -t PID -n ...` (the PID is printed), see README "Running the daemon".
# The hint names the config for `afmtwin send`, which checks every value against the
# daemon's limits and refuses without one (README "The command-line companions").
set -eu
BUILD=$1
CONF=$2
BIN=$BUILD/bin/afmtwind
CONF_ABS=$(cd "$(dirname "$CONF")" && pwd)/$(basename "$CONF")
TOOL=$(cd "$BUILD/bin" && pwd)/afmtwin
# hint [PREFIX]: the next commands, from another shell (PREFIX: into the namespace)
hint() {
  echo "afmtwind-run: from another shell: ${1:-}$TOOL listen --count 5" >&2
  echo "afmtwind-run:   ${1:-}env AFMTWIN_CONFIG=$CONF_ABS $TOOL send dither --freq 338.112kHz --amp 0.087nm --wait" >&2
}
if [ -n "${LCM_DEFAULT_URL:-}" ]; then
  echo "afmtwind-run: LCM_DEFAULT_URL=$LCM_DEFAULT_URL" >&2
  hint
  exec "$BIN" --config "$CONF"
fi
if ip route get 239.255.76.67 >/dev/null 2>&1; then
  echo "afmtwind-run: multicast route found: LCM default udpm (ttl=0, this host only)" >&2
  hint
  exec "$BIN" --config "$CONF"
fi
echo "afmtwind-run: no multicast route: running in a private network namespace" >&2
UNSHARE="unshare -n"
[ "$(id -u)" -eq 0 ] || UNSHARE="unshare -rn"
exec $UNSHARE sh -c '
  ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo || {
    echo "afmtwind-run: cannot set up loopback multicast in the namespace" >&2; exit 1; }
  echo "afmtwind-run: namespace of PID $$ (not root: nsenter -t $$ -U -n --preserve-credentials ...)" >&2
  echo "afmtwind-run: from another shell: nsenter -t $$ -n $3 listen --count 5" >&2
  echo "afmtwind-run:   nsenter -t $$ -n env AFMTWIN_CONFIG=$2 $3 send dither --freq 338.112kHz --amp 0.087nm --wait" >&2
  exec "$0" --config "$1"' "$BIN" "$CONF" "$CONF_ABS" "$TOOL"
