#!/usr/bin/env python3
# harm_identical.py DAEMON.jsonl REPLAY.jsonl -- are a daemon's harmonics records (afmtwin listen
# --json) the replay's, bit for bit? Each daemon record is looked up by its period start t_s
# in the replay's and compared in every field but utime, seq_applied and msg_seq (when a
# record was handed out, not what it says). Prints "N daemon harmonics records, F found in the
# replay (t_s), D differ[; the first]"; exit 0 when more than 100 records, at least 99 % of them
# found and none differs, else 1. Used by test_applied_log.sh and test_fm_daemon.sh.
import json
import sys

SKIP = ("utime", "seq_applied", "msg_seq")


def load(path):
    d = {}
    for line in open(path):
        if line.strip():
            r = json.loads(line)
            d[r["t_s"]] = {k: v for k, v in r.items() if k not in SKIP}
    return d


dm, rp = load(sys.argv[1]), load(sys.argv[2])
found = [t for t in dm if t in rp]
diff = [t for t in found if dm[t] != rp[t]]
first = ""
if diff:
    t = min(diff)
    k = next(k for k in dm[t] if dm[t][k] != rp[t].get(k))
    first = "; first at t_s %r: %s daemon %.60s, replay %.60s" % (t, k, repr(dm[t][k]),
                                                                  repr(rp[t].get(k)))
print("%d daemon harmonics records, %d found in the replay (t_s), %d differ%s" %
      (len(dm), len(found), len(diff), first))
sys.exit(0 if len(dm) > 100 and len(found) >= 0.99 * len(dm) and not diff else 1)
