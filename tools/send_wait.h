/* SPDX-License-Identifier: MIT */
/* send_wait.h -- `afmtwin send --wait`: the daemon's answer to one command, read from its
 * status: applied (seq_applied echoes the command's seq), or rejected / refused (the
 * daemon tags the reason of a decoded command with "[seq N]"; a message that did not decode
 * is named by its channel). */
#ifndef AFMT_SEND_WAIT_H
#define AFMT_SEND_WAIT_H

#include <stddef.h>
#include <stdint.h>

typedef struct send_wait send_wait;

/* Opens the daemon's output URL (derived from url as the daemon does, or out_url) and waits
 * up to timeout_s for a first status: the counts a rejection is judged against. Call
 * before publishing. NULL with err (LCM, no status). */
send_wait *send_wait_open(const char *url, const char *out_url, const char *prefix,
                          double timeout_s, char *err, size_t errlen);

/* After publishing seq on channel, waits up to timeout_s: 0 applied; 1 rejected or refused,
 * the daemon's reason in err; -1 no answer (err says so). */
int send_wait_result(send_wait *w, int64_t seq, const char *channel, double timeout_s, char *err,
                     size_t errlen);

void send_wait_destroy(send_wait **w);

#endif
