#!/bin/sh
# bench-ir.sh BUILD -- `make bench`'s instruction row for the two real-time schemes (issue 29):
# callgrind instructions per sample of the integrator stage (--toggle-collect=afm_runner_run:
# the daemon's path with its step record, the chain not counted) in bench-states' steady
# tapping state, accurate and fast side by side, on the four configs the issue names, and the
# ratio. The count covers the state's settling and window (bench-states --json: samples_run),
# so it is the same on any machine and under any load (the VM has no hardware counters; the
# ns rows of bench and bench-scheme are the timed side). Two configs at a time; ~5 minutes.
# Without valgrind the row is skipped, said.
B="${1:-build}"
A="$B/bin/afmtwin"
if ! command -v valgrind > /dev/null 2>&1; then
  echo "# bench-ir: no valgrind here: instructions per sample not counted"
  exit 0
fi
T=$(mktemp -d) || exit 1
trap 'rm -rf "$T"' EXIT
CONFIGS="nchv default thesis-fig-4-13 thesis-1dof"
one() { # config scheme
  valgrind --tool=callgrind --collect-atstart=no --toggle-collect=afm_runner_run \
    --callgrind-out-file="$T/cg.$1.$2" "$A" bench-states --config "config/$1.conf" \
    --only "tapping, Z" --runs 1 --scheme "$2" --no-fifo --json > "$T/out.$1.$2" 2> "$T/err.$1.$2"
  echo $? > "$T/rc.$1.$2"
}
per() { # config scheme -> its instructions per sample
  ir=$(sed -n 's/^summary: *\([0-9]*\).*/\1/p' "$T/cg.$1.$2")
  n=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["states"][0]["samples_run"])' "$T/out.$1.$2")
  awk -v i="$ir" -v n="$n" 'BEGIN { printf "%.1f", i / n }'
}
for c in $CONFIGS; do
  one "$c" accurate &
  one "$c" fast &
  wait
done
printf '# %-18s %12s %12s %8s   (callgrind Ir per sample, integrator stage, tapping Z 40 nm)\n' \
  config accurate fast ratio
for c in $CONFIGS; do
  for s in accurate fast; do
    if [ "$(cat "$T/rc.$c.$s")" != 0 ]; then
      echo "# bench-ir: $c $s failed: $(tail -3 "$T/err.$c.$s")"
      exit 1
    fi
  done
  a=$(per "$c" accurate)
  f=$(per "$c" fast)
  printf '  %-18s %12s %12s %8s\n' "$c" "$a" "$f" "$(awk -v a="$a" -v f="$f" 'BEGIN { printf "%.2f", a / f }')"
done
