/* SPDX-License-Identifier: MIT */
/* test_wire.c -- untrusted LCM bytes (afm_lcm_wire, afm_lcm_log): every message type
 * round-trips through the wire check and lcm-gen's decoder; every truncation, trailing
 * bytes, negative and huge counts, bad string lengths and terminators are rejected before
 * the decoder runs, with a reason. The exact inputs of issue 13 are here: a samples_t with
 * n = 0x40000010 (sizeof * n wrapped into a heap overread), a status_t string length of
 * 0xffffffff (memcpy of SIZE_MAX), a dither with n_tones = -3 (malloc((size_t)-24)) and the
 * 33-byte dither with n_tones = 127 that leaked what the decoder had allocated (the
 * sanitizer build, `make sanitize`, runs this file under LSan). The log reader rejects an
 * event with datalen 0x7fffffff, bad channel lengths, cut-short events, and skips junk. */
#include "transport/afm_cmd_lcm.h"
#include "transport/afm_lcm_log.h"
#include "transport/afm_lcm_wire.h"
#include "afmtwin_samples_t.h"
#include "check.h"
#include "msg_examples.h"

#include <glob.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static unsigned char buf[1 << 16];
static char err[512];

static bool rejected(const afm_wire_type *t, size_t len, const char *needle) {
    err[0] = 0;
    union {
        char b[1024];
        double d;
        void *p;
    } m;
    int rc = afm_wire_decode(t, buf, len, &m, err, sizeof err);
    return rc == -1 && err[0] && (!needle || strstr(err, needle));
}

static void put_be32(unsigned char *p, uint32_t v) {
    for (int i = 0; i < 4; i++)
        p[i] = (unsigned char)(v >> (24 - 8 * i));
}

/* Every prefix of a valid message is rejected, the whole accepted, one more byte rejected. */
static void all_cuts(const afm_wire_type *t, int full, const char *what) {
    int bad_ok = 0;
    for (int cut = 0; cut < full; cut++)
        if (!rejected(t, (size_t)cut, NULL)) bad_ok++;
    buf[full] = 0;
    bool trailing = rejected(t, (size_t)full + 1, "trailing");
    union {
        char b[1024];
        double d;
    } msg;
    bool whole = afm_wire_decode(t, buf, (size_t)full, &msg, err, sizeof err) == 0;
    if (whole) afm_wire_free(t, &msg);
    char name[200];
    snprintf(name, sizeof name, "%s (%d bytes): whole accepted, %d cuts rejected, +1 byte rejected",
             what, full, full);
    check_true(whole && bad_ok == 0 && trailing, name);
}

static void test_types(void) {
    int n = ex_samples(buf, sizeof buf);
    all_cuts(&afm_wire_samples_t, n, "samples_t n 3");
    afmtwin_samples_t d;
    check_true(afm_wire_decode(&afm_wire_samples_t, buf, (size_t)n, &d, err, sizeof err) == 0 &&
                   d.n == 3 && d.force_n[2] == 9 && d.obd_counts[1] == -2 && d.stream == 1,
               "samples_t decoded values");
    afm_wire_free(&afm_wire_samples_t, &d);
    /* issue 13: n = 0x40000010 -- 4 * n wraps in lcm-gen's int arithmetic */
    put_be32(buf + EX_SAMPLES_N_AT, 0x40000010u);
    check_true(rejected(&afm_wire_samples_t, (size_t)n, "truncated at deflection_m"),
               "samples_t with n = 0x40000010: rejected before lcm-gen's decoder");
    put_be32(buf + EX_SAMPLES_N_AT, 0xfffffffeu);
    check_true(rejected(&afm_wire_samples_t, (size_t)n, "negative count -2"),
               "samples_t with n = -2: rejected");

    n = ex_harmonics(buf, sizeof buf);
    all_cuts(&afm_wire_harmonics_t, n, "harmonics_t n 2");

    n = ex_status(buf, sizeof buf, "x");
    all_cuts(&afm_wire_status_t, n, "status_t");
    /* issue 13: last_reject's length 0xffffffff (lcm-gen: malloc(-1), memcpy SIZE_MAX) */
    put_be32(buf + EX_STATUS_REJECT_AT, 0xffffffffu);
    check_true(rejected(&afm_wire_status_t, (size_t)n, "last_reject has a bad length -1"),
               "status_t string length 0xffffffff: rejected");
    n = ex_status(buf, sizeof buf, "x");
    buf[EX_STATUS_REJECT_AT + 4 + 1] = 'y'; /* "x" lost its NUL */
    check_true(rejected(&afm_wire_status_t, (size_t)n, "not a proper string"),
               "status_t string without its NUL: rejected");
    n = ex_status(buf, sizeof buf, "x");
    put_be32(buf + EX_STATUS_REJECT_AT, 0);
    check_true(rejected(&afm_wire_status_t, (size_t)n, "bad length 0"),
               "status_t string of length 0: rejected");

    n = ex_param(buf, sizeof buf);
    all_cuts(&afm_wire_param_t, n, "param_t n 2");
    buf[EX_PARAM_NAME0_LEN_AT + 4 + 3] = 0; /* a NUL inside the first name */
    check_true(rejected(&afm_wire_param_t, (size_t)n, "not a proper string"),
               "param_t name with a NUL inside: rejected");

    n = ex_dither(buf, sizeof buf, 4);
    all_cuts(&afm_wire_dither_t, n, "dither_t n_tones 4");
    buf[EX_DITHER_N_TONES_AT] =
        0xfd; /* issue 13: n_tones -3 -> lcm_malloc(8 * -3) = malloc((size_t)-24) */
    check_true(rejected(&afm_wire_dither_t, (size_t)n, "negative count -3"),
               "dither_t n_tones -3: rejected before any malloc");
    /* the list of types covers every msgtypes file */
    int nt = 0;
    for (const afm_wire_type *const *t = afm_wire_all; *t; t++)
        nt++;
    glob_t g;
    size_t nfiles = glob("msgtypes/*.lcm", 0, NULL, &g) == 0 ? g.gl_pathc : 0;
    if (nfiles) globfree(&g);
    char what[96];
    snprintf(what, sizeof what, "afm_wire_all lists a type per msgtypes/*.lcm file (%d, %zu)", nt,
             nfiles);
    check_true(nfiles > 0 && (size_t)nt == nfiles, what);
}

/* issue 13: a 33-byte dither with n_tones = 127 made lcm-gen's decoder allocate the arrays
 * and return early; afm_cmd_decode returned before the cleanup (a ~1 KB leak per message,
 * 300 MB in a 15 s flood). Now the check rejects it before the decoder allocates; under
 * LSan (make sanitize) a leak fails this binary. */
static void test_leak_input(void) {
    ex_dither(buf, sizeof buf, 1);
    buf[EX_DITHER_N_TONES_AT] = 127;
    afm_cmd_limits lim = {.sample_rate_hz = 14.06e6};
    afm_cmd c;
    int bad = 0;
    for (int i = 0; i < 1000; i++)
        if (afm_cmd_decode(AFM_CMD_DITHER, buf, 33, &lim, &c, err, sizeof err) != -1) bad++;
    char name[600];
    snprintf(name, sizeof name, "1000 x the 33-byte dither with n_tones 127: rejected (\"%s\")",
             err);
    check_true(bad == 0 && strstr(err, "truncated at frequency_hz"), name);
}

/* Random mutations of valid messages: whatever the check accepts, lcm-gen's decoder takes
 * exactly (the layouts agree), and nothing crashes. */
static void test_mutations(void) {
    srand(13);
    int accepted = 0, disagree = 0;
    for (int trial = 0; trial < 20000; trial++) {
        const afm_wire_type *t = trial % 2 ? &afm_wire_status_t : &afm_wire_dither_t;
        int n = trial % 2 ? ex_status(buf, sizeof buf, "abc") : ex_dither(buf, sizeof buf, 2);
        int flips = 1 + rand() % 3;
        for (int i = 0; i < flips; i++)
            buf[8 + rand() % (n - 8)] = (unsigned char)rand();
        int len = n + (rand() % 5 == 0 ? rand() % 9 - 4 : 0);
        if (afm_wire_check(t, buf, (size_t)len, err, sizeof err) == 0) {
            accepted++;
            union {
                char b[1024];
                double d;
            } m;
            memset(&m, 0, sizeof m);
            int used = t->decode(buf, len, &m);
            if (used != len) disagree++;
            t->cleanup(&m);
        }
    }
    char name[200];
    snprintf(name, sizeof name,
             "20000 mutated dither/status messages: %d accepted, all decoded exactly by lcm-gen",
             accepted);
    check_true(disagree == 0 && accepted > 100, name);
}

/* ---- the log reader --------------------------------------------------------------------- */

static size_t put_event(unsigned char *p, int64_t num, int64_t ts, const char *ch, uint32_t chlen,
                        uint32_t dlen, const void *data) {
    size_t o = 0;
    put_be32(p, 0xEDA1DA01u);
    o += 4;
    for (int i = 0; i < 8; i++)
        p[o + (size_t)i] = (unsigned char)((uint64_t)num >> (56 - 8 * i));
    o += 8;
    for (int i = 0; i < 8; i++)
        p[o + (size_t)i] = (unsigned char)((uint64_t)ts >> (56 - 8 * i));
    o += 8;
    put_be32(p + o, chlen);
    o += 4;
    put_be32(p + o, dlen);
    o += 4;
    if (ch) memcpy(p + o, ch, strlen(ch));
    o += ch ? strlen(ch) : 0;
    if (data) memcpy(p + o, data, dlen);
    o += data ? dlen : 0;
    return o;
}

/* Read a log held in memory; count of events, -1 on a reported error (reason in err). */
static int read_mem(const unsigned char *b, size_t len, long long *skipped) {
    FILE *f = fmemopen((void *)b, len, "rb");
    afm_lcm_log *l = afm_lcm_log_from_file(f, 0, err, sizeof err);
    if (!l) return -2;
    afm_lcm_log_event ev;
    int r, n = 0;
    while ((r = afm_lcm_log_next(l, &ev, err, sizeof err)) > 0)
        n++;
    if (skipped) *skipped = afm_lcm_log_skipped(l);
    afm_lcm_log_close(&l);
    return r < 0 ? -1 : n;
}

static void test_log(void) {
    static unsigned char lg[4096];
    size_t o = put_event(lg, 0, 100, "AFMTWIN_STATUS", 14, 5, "hello");
    o += put_event(lg + o, 1, 200, "X", 1, 0, NULL);
    check_true(read_mem(lg, o, NULL) == 2, "log: two good events read");
    /* issue 13: datalen 0x7fffffff (liblcm: calloc fails, fread into NULL) */
    size_t p = put_event(lg, 0, 100, "AFMTWIN_STATUS", 14, 0x7fffffffu, NULL);
    check_true(read_mem(lg, p, NULL) == -1 && strstr(err, "bad data length 2147483647"),
               "log: datalen 0x7fffffff rejected before allocating");
    p = put_event(lg, 0, 100, "AFMTWIN_STATUS", 14, 1000, NULL);
    memset(lg + p, 0, 10);
    check_true(read_mem(lg, p + 10, NULL) == -1 && strstr(err, "truncated event"),
               "log: datalen past the end of the file rejected (truncated)");
    p = put_event(lg, 0, 100, NULL, 0, 0, NULL);
    check_true(read_mem(lg, p, NULL) == -1 && strstr(err, "bad channel length 0"),
               "log: channel length 0 rejected");
    p = put_event(lg, 0, 100, NULL, 0x7fffffffu, 0, NULL);
    check_true(read_mem(lg, p, NULL) == -1 && strstr(err, "bad channel length"),
               "log: channel length 0x7fffffff rejected");
    p = put_event(lg, 0, 100, "AB", 2, 0, NULL);
    lg[p - 1] = 0;
    check_true(read_mem(lg, p, NULL) == -1 && strstr(err, "NUL"),
               "log: a NUL inside the channel name rejected");
    p = put_event(lg, 0, 100, "AB", 2, 0, NULL);
    check_true(read_mem(lg, 12, NULL) == -1 && strstr(err, "truncated event header"),
               "log: header cut short rejected");
    memcpy(lg, "junk!", 5);
    p = 5 + put_event(lg + 5, 0, 100, "AB", 2, 1, "z");
    long long sk = 0;
    check_true(read_mem(lg, p, &sk) == 1 && sk == 5,
               "log: 5 junk bytes before an event skipped, counted");
    check_true(read_mem(lg, 0, NULL) == 0, "log: an empty file has no events");
    /* the channel's kind, whatever the daemon's --prefix (curve, plot fm, plot trace) */
    check_true(afm_lcm_log_channel_is("AFMTWIN_HARMONICS", "HARMONICS") &&
                   afm_lcm_log_channel_is("HARMONICS", "HARMONICS") &&
                   afm_lcm_log_channel_is("LAB2_SAMPLES", "SAMPLES"),
               "log: channel_is: the kind at the end of the name, with or without a prefix");
    check_true(!afm_lcm_log_channel_is("ARMONICS", "HARMONICS") &&
                   !afm_lcm_log_channel_is("AFMTWIN_HARMONICS_X", "HARMONICS") &&
                   !afm_lcm_log_channel_is("", "SAMPLES"),
               "log: channel_is: not a shorter name, nor one with the kind inside");
}

int main(void) {
    test_types();
    test_leak_input();
    test_mutations();
    test_log();
    return check_done();
}
