/* SPDX-License-Identifier: MIT */
/* send_wait.c -- the daemon's answer to a command, from its status (see send_wait.h). */
#include "send_wait.h"

#include "lcm_tool.h"

#include "afmtwin_status_t.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct send_wait {
    afmt_lcm o;
    afmt_checked_sub sub;
    bool have_base, have_new;
    int64_t base_rejected, base_refused; /* the counts before the command */
    /* the latest status */
    int64_t seq_applied, rejected, refused;
    char last_reject[512], last_refusal[512];
};

static void on_status(const void *msg, void *user) {
    const afmtwin_status_t *m = msg;
    send_wait *w = user;
    if (!w->have_base) {
        w->base_rejected = m->rejected;
        w->base_refused = m->refused;
        w->have_base = true;
    }
    w->seq_applied = m->seq_applied;
    w->rejected = m->rejected;
    w->refused = m->refused;
    snprintf(w->last_reject, sizeof w->last_reject, "%s", m->last_reject ? m->last_reject : "");
    snprintf(w->last_refusal, sizeof w->last_refusal, "%s", m->last_refusal ? m->last_refusal : "");
    w->have_new = true;
}

/* Handle status messages until one came or timeout_s passed. */
static bool next_status(send_wait *w, double t_end) {
    w->have_new = false;
    for (double left; !w->have_new && (left = t_end - afmt_mono_s()) > 0;)
        if (afmt_lcm_handle(&w->o, (int)ceil(fmin(left, 0.2) * 1e3)) < 0) break;
    return w->have_new;
}

send_wait *send_wait_open(const char *url, const char *out_url, const char *prefix,
                          double timeout_s, char *err, size_t errlen) {
    char ch[AFMT_CHAN_LEN];
    if (afmt_channel(prefix, AFMT_CHAN_STATUS, ch, err, errlen)) return NULL;
    send_wait *w = calloc(1, sizeof *w);
    if (!w) {
        snprintf(err, errlen, "out of memory");
        return NULL;
    }
    if (afmt_lcm_open(&w->o, url, out_url, NULL, 0, err, errlen)) {
        free(w);
        return NULL;
    }
    w->sub = (afmt_checked_sub){&afm_wire_status_t, on_status, w, 0};
    if (afmt_subscribe_checked(w->o.out, ch, &w->sub, 100)) {
        snprintf(err, errlen, "cannot subscribe to %s", ch);
        send_wait_destroy(&w);
        return NULL;
    }
    if (!next_status(w, afmt_mono_s() + timeout_s)) {
        snprintf(err, errlen,
                 "no status on %s within %g s (is afmtwind running on this URL, with this "
                 "prefix?); nothing sent",
                 ch, timeout_s);
        send_wait_destroy(&w);
        return NULL;
    }
    return w;
}

int send_wait_result(send_wait *w, int64_t seq, const char *channel, double timeout_s, char *err,
                     size_t errlen) {
    char tag[48];
    snprintf(tag, sizeof tag, "[seq %lld]", (long long)seq);
    double t_end = afmt_mono_s() + timeout_s;
    while (next_status(w, t_end)) {
        if (w->seq_applied == seq) return 0;
        bool rej = w->rejected > w->base_rejected, ref = w->refused > w->base_refused;
        if (rej &&
            (strstr(w->last_reject, tag) || !strncmp(w->last_reject, channel, strlen(channel)))) {
            snprintf(err, errlen, "rejected by the daemon: %s", w->last_reject);
            return 1;
        }
        if (ref && strstr(w->last_refusal, tag)) {
            snprintf(err, errlen, "refused by the daemon: %s", w->last_refusal);
            return 1;
        }
    }
    snprintf(err, errlen,
             "no status echoed seq %lld within %g s (seq_applied %lld; lost, or a later "
             "command overtook it)",
             (long long)seq, timeout_s, (long long)w->seq_applied);
    return -1;
}

void send_wait_destroy(send_wait **w) {
    if (!w || !*w) return;
    afmt_lcm_close(&(*w)->o);
    free(*w);
    *w = NULL;
}
