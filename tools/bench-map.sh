#!/bin/sh
# bench-map.sh -- `make bench`'s map row (issue 31): settled points per second of `afmtwin
# map`, per rank, with 1 and 2 MPI ranks, and the speed-up, on thesis-fig-4-2.conf and
# nchv.conf. MPI on loopback and shared memory only, in a private network namespace when
# unshare works. Usage: sh tools/bench-map.sh BUILD
B=${1:-build}
A="$B/bin/afmtwin"
T=$(mktemp -d /tmp/afmtwin-bench-map.XXXXXX)
trap 'rm -rf "$T"' EXIT
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl=self,vader \
  OMPI_MCA_oob_tcp_if_include=lo OMPI_MCA_rmaps_base_oversubscribe=1
if unshare -n true 2> /dev/null; then
  NS="unshare -n sh -c 'ip link set lo up; exec \"\$0\" \"\$@\"'"
else
  NS=""
fi
now() { date +%s.%N; }
row() { # NAME CONFIG AE_FROM AE_TO X-AXIS...: a map of 4 lines in Ae (both directions), 1 and 2 ranks
  name=$1; conf=$2; a0=$3; a1=$4; shift 4
  npts=$(($4 * 4 * 2))
  for n in 1 2; do
    t0=$(now)
    eval "$NS" mpirun -np $n "$A" map --config "$conf" --x "$@" --y ae $a0 $a1 4 \
      --max-periods 3000 --out "$T/m$n.map" > "$T/log" 2>&1 || { cat "$T/log"; exit 1; }
    t1=$(now)
    eval "r$n=\$(echo \"$npts / ($t1 - $t0) / $n\" | bc -l)"
  done
  cmp -s "$T/m1.map" "$T/m2.map" && same=yes || same=NO
  printf 'map %-18s %3d points: 1 rank %7.2f points/s; 2 ranks %7.2f points/s per rank, speed-up %.2f (same file: %s)\n' \
    "$name" $npts "$r1" "$r2" "$(echo "2 * $r2 / $r1" | bc -l)" $same
}
row thesis-fig-4-2 config/thesis-fig-4-2.conf 6e-10 7e-10 fe 80000 86000 16
row nchv config/nchv.conf 3e-10 4e-10 fe 334000 342000 8
