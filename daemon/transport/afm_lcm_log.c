/* SPDX-License-Identifier: MIT */
/* afm_lcm_log.c -- the checked LCM log reader (contract in afm_lcm_log.h). */
#include "transport/afm_lcm_log.h"

#include <errno.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define SYNC 0xEDA1DA01u
#define DEFAULT_MAX_DATA (16u << 20)
#define HEADER_BYTES 24 /* after the sync word: eventnum, timestamp, channellen, datalen */

struct afm_lcm_log {
    FILE *f;
    long long pos, size; /* bytes read so far; file size (-1: unknown) */
    uint32_t max_data;
    long long skipped;
    int done;
    char channel[AFM_LCM_LOG_MAX_CHANNEL + 1];
    uint8_t *buf;
    size_t cap;
};

static void set_err(char *err, size_t errlen, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void set_err(char *err, size_t errlen, const char *fmt, ...) {
    if (!err || !errlen) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

afm_lcm_log *afm_lcm_log_from_file(FILE *f, uint32_t max_data, char *err, size_t errlen) {
    if (!f) {
        snprintf(err, errlen, "no file");
        return NULL;
    }
    afm_lcm_log *l = calloc(1, sizeof *l);
    if (!l) {
        fclose(f);
        snprintf(err, errlen, "out of memory");
        return NULL;
    }
    l->f = f;
    l->max_data = max_data ? max_data : DEFAULT_MAX_DATA;
    l->size = -1;
    long here = ftell(f);
    if (here >= 0 && fseek(f, 0, SEEK_END) == 0) {
        long end = ftell(f);
        if (end >= here) l->size = end - here;
        fseek(f, here, SEEK_SET);
    }
    return l;
}

afm_lcm_log *afm_lcm_log_open(const char *path, uint32_t max_data, char *err, size_t errlen) {
    struct stat st;
    if (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) {
        snprintf(err, errlen, "%s: is a directory, not an LCM log", path);
        return NULL;
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errlen, "%s: %s", path, strerror(errno));
        return NULL;
    }
    return afm_lcm_log_from_file(f, max_data, err, errlen);
}

void afm_lcm_log_close(afm_lcm_log **lp) {
    if (!lp || !*lp) return;
    fclose((*lp)->f);
    free((*lp)->buf);
    free(*lp);
    *lp = NULL;
}

int afm_lcm_log_channel_is(const char *channel, const char *suffix) {
    size_t cl = strlen(channel), sl = strlen(suffix);
    return cl >= sl && !strcmp(channel + cl - sl, suffix);
}

long long afm_lcm_log_skipped(const afm_lcm_log *l) {
    return l ? l->skipped : 0;
}

static int read_exact(afm_lcm_log *l, void *dst, size_t n) {
    size_t got = fread(dst, 1, n, l->f);
    l->pos += (long long)got;
    return got == n ? 0 : -1;
}

static uint64_t be(const uint8_t *b, int n) {
    uint64_t v = 0;
    for (int i = 0; i < n; i++)
        v = v << 8 | b[i];
    return v;
}

int afm_lcm_log_next(afm_lcm_log *l, afm_lcm_log_event *ev, char *err, size_t errlen) {
    if (!l || l->done) return 0;
    /* the sync word, skipping (and counting) anything before it */
    uint32_t w = 0;
    int have = 0;
    for (;;) {
        int c = fgetc(l->f);
        if (c == EOF) {
            l->done = 1;
            l->skipped += have; /* junk at the very end */
            return 0;
        }
        l->pos++;
        w = w << 8 | (uint32_t)c;
        if (++have >= 4 && w == SYNC) break;
    }
    l->skipped += have - 4;
    long long off = l->pos - 4;
    uint8_t h[HEADER_BYTES];
    if (read_exact(l, h, sizeof h)) {
        l->done = 1;
        set_err(err, errlen, "truncated event header (%lld of %lld bytes) at byte %lld",
                (long long)(l->pos - off - 4), (long long)HEADER_BYTES, off);
        return -1;
    }
    int64_t chlen = (int32_t)be(h + 16, 4), dlen = (int32_t)be(h + 20, 4);
    long long left = l->size >= 0 ? l->size - l->pos : -1;
    if (chlen < 1 || chlen > AFM_LCM_LOG_MAX_CHANNEL) {
        l->done = 1;
        set_err(err, errlen, "bad channel length %lld (1..%lld) in the event at byte %lld",
                (long long)chlen, (long long)AFM_LCM_LOG_MAX_CHANNEL, off);
        return -1;
    }
    if (dlen < 0 || dlen > (int64_t)l->max_data) {
        l->done = 1;
        set_err(err, errlen, "bad data length %lld (0..%lld) in the event at byte %lld",
                (long long)dlen, (long long)l->max_data, off);
        return -1;
    }
    if (left >= 0 && chlen + dlen > left) {
        l->done = 1;
        set_err(err, errlen, "truncated event: %lld bytes announced, %lld left, at byte %lld",
                (long long)(chlen + dlen), left, off);
        return -1;
    }
    if ((size_t)dlen > l->cap || !l->buf) { /* checked above: at most max_data */
        size_t cap = dlen > 0 ? (size_t)dlen : 1;
        uint8_t *nb = realloc(l->buf, cap);
        if (!nb) {
            l->done = 1;
            set_err(err, errlen, "out of memory for %lld data bytes (event at byte %lld)",
                    (long long)dlen, off);
            return -1;
        }
        l->buf = nb;
        l->cap = cap;
    }
    if (read_exact(l, l->channel, (size_t)chlen) || read_exact(l, l->buf, (size_t)dlen)) {
        l->done = 1;
        set_err(err, errlen, "truncated event (%lld channel + %lld data bytes) at byte %lld",
                (long long)chlen, (long long)dlen, off);
        return -1;
    }
    l->channel[chlen] = 0;
    if (memchr(l->channel, 0, (size_t)chlen)) {
        l->done = 1;
        set_err(err, errlen, "channel name of %lld bytes holds a NUL (event at byte %lld)",
                (long long)chlen, off);
        return -1;
    }
    ev->eventnum = (int64_t)be(h, 8);
    ev->timestamp = (int64_t)be(h + 8, 8);
    ev->channel = l->channel;
    ev->data = l->buf;
    ev->datalen = (uint32_t)dlen;
    ev->offset = off;
    return 1;
}
