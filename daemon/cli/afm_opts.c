/* SPDX-License-Identifier: MIT */
/* afm_opts.c -- the table-driven option parser both programs use (afm_opts.h): the SI
 * suffixes of lengths and frequencies, the range checks and the refusal messages. */
#include "cli/afm_opts.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int afm_opts_parse_double(const char *s, double *v) {
    if (!s || !*s) return -1;
    char *end;
    errno = 0;
    double x = strtod(s, &end);
    if (*end || end == s || errno == ERANGE) return -1;
    *v = x;
    return 0;
}

static const afmt_opt *opt_find(const afmt_opt *opts, const char *name) {
    for (const afmt_opt *o = opts; o->name; o++)
        if (!strcmp(o->name, name)) return o;
    return NULL;
}

static bool in_range(const afmt_opt *o, double x) {
    if (!isfinite(x)) return false;
    if (o->lo == 0 && o->hi == 0 && !o->lo_open) return true;
    return (o->lo_open ? x > o->lo : x >= o->lo) && x <= o->hi;
}

/* The suffixes of the units, with the power of ten each scales by. */
typedef struct {
    const char *suffix;
    afmt_unit unit;
    int exp10;
} si_suffix;

static const si_suffix si_suffixes[] = {
    {"m", AFMT_UNIT_M, 0},
    {"mm", AFMT_UNIT_M, -3},
    {"um", AFMT_UNIT_M, -6},
    {"\xc2\xb5m", AFMT_UNIT_M, -6} /* U+00B5 micro sign */,
    {"\xce\xbcm", AFMT_UNIT_M, -6} /* U+03BC Greek mu */,
    {"nm", AFMT_UNIT_M, -9},
    {"pm", AFMT_UNIT_M, -12},
    {"fm", AFMT_UNIT_M, -15},
    {"Hz", AFMT_UNIT_HZ, 0},
    {"hz", AFMT_UNIT_HZ, 0},
    {"kHz", AFMT_UNIT_HZ, 3},
    {"khz", AFMT_UNIT_HZ, 3},
    {"KHz", AFMT_UNIT_HZ, 3},
    {"MHz", AFMT_UNIT_HZ, 6},
    {"GHz", AFMT_UNIT_HZ, 9},
};

const char *afmt_unit_name(afmt_unit u) {
    return u == AFMT_UNIT_M ? "m" : u == AFMT_UNIT_HZ ? "Hz" : "";
}

const char *afmt_unit_suffixes(afmt_unit u) {
    return u == AFMT_UNIT_M    ? "mm, um, \xc2\xb5m, nm, pm, fm"
           : u == AFMT_UNIT_HZ ? "kHz, MHz, GHz"
                               : "";
}

static const char *unit_kind(afmt_unit u) {
    return u == AFMT_UNIT_M ? "a length" : u == AFMT_UNIT_HZ ? "a frequency" : "a number";
}

int afmt_parse_si(const char *s, afmt_unit u, double *v) {
    if (!s || !*s) return AFMT_SI_BAD;
    char *end;
    errno = 0;
    double x = strtod(s, &end);
    if (end == s || errno == ERANGE) return AFMT_SI_BAD;
    if (!*end) {
        *v = x;
        return 0;
    }
    if (u == AFMT_UNIT_NONE) return AFMT_SI_BAD;
    const char *suf = end;
    while (*suf == ' ')
        suf++;
    const si_suffix *e = NULL;
    for (size_t i = 0; i < sizeof si_suffixes / sizeof si_suffixes[0] && !e; i++)
        if (!strcmp(suf, si_suffixes[i].suffix)) e = &si_suffixes[i];
    if (!e) return AFMT_SI_BAD;
    if (e->unit != u) return AFMT_SI_WRONG_UNIT;
    /* a decimal mantissa gets the exponent appended, so that strtod rounds once: 30nm is
     * exactly 30e-9 (30 * 1e-9 is not) */
    size_t len = (size_t)(end - s);
    char buf[96];
    if (e->exp10 != 0 && len + 8 < sizeof buf && strspn(s, "0123456789+-.") == len) {
        snprintf(buf, sizeof buf, "%.*se%d", (int)len, s, e->exp10);
        errno = 0;
        x = strtod(buf, &end);
        if (*end || errno == ERANGE) return AFMT_SI_BAD;
    } else if (e->exp10 > 0) {
        x *= pow(10, e->exp10);
    } else if (e->exp10 < 0) {
        x /= pow(10, -e->exp10);
    }
    *v = x;
    return 1;
}

#define SI_LIST_MAX 16

/* Each comma-separated word of s through afmt_parse_si: AFMT_SI_WRONG_UNIT if any word has
 * the other unit's suffix, else AFMT_SI_BAD if any is bad or there are more than max, else 1
 * if any had a suffix, 0 if none; *n the count. */
static int si_scan(const char *s, afmt_unit u, double *v, int max, int *n) {
    char buf[512];
    *n = 0;
    if (!s || strlen(s) >= sizeof buf) return AFMT_SI_BAD;
    strcpy(buf, s);
    int worst = 0;
    char *save = NULL;
    for (char *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
        double x;
        int rc = afmt_parse_si(t, u, &x);
        if (rc == AFMT_SI_WRONG_UNIT) return rc;
        if (rc < 0 || *n >= max)
            worst = AFMT_SI_BAD;
        else {
            v[(*n)++] = x;
            if (worst == 0) worst = rc;
        }
    }
    return *n == 0 ? AFMT_SI_BAD : worst;
}

int afmt_parse_si_list(const char *s, afmt_unit u, double *v, int max) {
    int n;
    return si_scan(s, u, v, max, &n) < 0 ? -1 : n;
}

/* The echoes of the values given with a suffix, printed once the whole command line is
 * good (none before a usage error or --help). */
typedef struct {
    char text[2048];
    size_t len;
} si_echoes;

static void echo_add(si_echoes *e, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void echo_add(si_echoes *e, const char *fmt, ...) {
    if (e->len >= sizeof e->text - 1) return;
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(e->text + e->len, sizeof e->text - e->len, fmt, ap);
    va_end(ap);
    if (n > 0) e->len += (size_t)n;
    if (e->len >= sizeof e->text - 1) { /* cut: end with a newline */
        e->len = sizeof e->text - 2;
        e->text[e->len++] = '\n';
        e->text[e->len] = 0;
    }
}

/* "PROG: OPT VALUE = V1[,V2..] UNIT" */
static void si_echo(si_echoes *e, const char *prog, const char *opt, const char *value, afmt_unit u,
                    const double *v, int n) {
    echo_add(e, "%s: %s %s = ", prog, opt, value);
    for (int i = 0; i < n; i++)
        echo_add(e, "%s%.10g", i ? "," : "", v[i]);
    echo_add(e, " %s\n", afmt_unit_name(u));
}

static void si_bad(const char *prog, const char *opt, const char *value, afmt_unit u, int rc) {
    if (rc == AFMT_SI_WRONG_UNIT)
        fprintf(stderr,
                "%s: %s wants %s in %s (or with a suffix: %s), got '%s': not a unit of "
                "%s\n",
                prog, opt, unit_kind(u), afmt_unit_name(u), afmt_unit_suffixes(u), value,
                unit_kind(u) + 2);
    else if (u == AFMT_UNIT_NONE)
        fprintf(stderr, "%s: %s wants a number, got '%s'\n", prog, opt, value);
    else
        fprintf(stderr, "%s: %s wants a number (%s, or with a suffix: %s), got '%s'\n", prog, opt,
                afmt_unit_name(u), afmt_unit_suffixes(u), value);
}

int afm_opts_si_value(const char *prog, const char *opt, const char *value, afmt_unit u,
                      double *v) {
    double x;
    int rc = afmt_parse_si(value, u, &x);
    if (rc < 0 || !isfinite(x)) {
        si_bad(prog, opt, value, u, rc < 0 ? rc : AFMT_SI_BAD);
        return -1;
    }
    if (rc == 1) {
        si_echoes e = {.len = 0};
        si_echo(&e, prog, opt, value, u, &x, 1);
        fputs(e.text, stderr);
    }
    *v = x;
    return 0;
}

/* Store v into o's destination; -1 if it is no value of o's kind and range,
 * AFMT_OPT_REPORTED if o's parse function said so itself. */
static int opt_store(const afmt_opt *o, const char *v) {
    double x;
    switch (o->kind) {
    case AFMT_OPT_STRING:
        *(const char **)o->dest = v;
        return 0;
    case AFMT_OPT_FN: {
        int rc = o->parse(v, o->dest);
        return rc == 0 || rc == AFMT_OPT_REPORTED ? rc : -1;
    }
    case AFMT_OPT_DOUBLE:
        if (afmt_parse_si(v, o->unit, &x) < 0 || !in_range(o, x)) return -1;
        *(double *)o->dest = x;
        return 0;
    case AFMT_OPT_INT:
    case AFMT_OPT_LONG:
    case AFMT_OPT_LLONG:
    case AFMT_OPT_UINT:
    case AFMT_OPT_U64:
        if (afm_opts_parse_double(v, &x) || !in_range(o, x) || x != floor(x)) return -1;
        if (o->kind == AFMT_OPT_INT)
            *(int *)o->dest = (int)x;
        else if (o->kind == AFMT_OPT_LONG)
            *(long *)o->dest = (long)x;
        else if (o->kind == AFMT_OPT_LLONG)
            *(long long *)o->dest = (long long)x;
        else if (o->kind == AFMT_OPT_UINT)
            *(unsigned *)o->dest = (unsigned)x;
        else
            *(uint64_t *)o->dest = (uint64_t)x;
        return 0;
    case AFMT_OPT_CHOICE:
        for (const afmt_choice *c = o->choices; c->name; c++)
            if (!strcmp(c->name, v)) {
                *(int *)o->dest = c->value;
                return 0;
            }
        return -1;
    case AFMT_OPT_FLAG:
    case AFMT_OPT_ARG:
        break;
    }
    return -1;
}

/* "PROG: OPT wants one of NAME1, NAME2, got 'v'" */
static void choice_bad(const char *prog, const char *opt, const afmt_choice *choices,
                       const char *v) {
    fprintf(stderr, "%s: %s wants one of ", prog, opt);
    for (const afmt_choice *c = choices; c->name; c++)
        fprintf(stderr, "%s%s", c == choices ? "" : ", ", c->name);
    fprintf(stderr, ", got '%s'\n", v);
}

int afm_opts_parse(const char *prog, const afmt_opt *opts, int argc, char **argv, int first) {
    si_echoes echoes = {.len = 0};
    for (int i = first; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) return AFMT_OPTS_HELP;
        if (a[0] != '-' || !a[1]) { /* an argument: the first AFMT_ARG row that takes it */
            const afmt_opt *o = opts;
            while (o->name && !(o->kind == AFMT_OPT_ARG && (o->parse || !*(const char **)o->dest)))
                o++;
            if (!o->name) {
                fprintf(stderr, "%s: unknown option or extra argument '%s' (see --help)\n", prog,
                        a);
                return AFMT_OPTS_BAD;
            }
            int rc = 0;
            if (!o->parse)
                *(const char **)o->dest = a;
            else
                rc = o->parse(a, o->dest);
            if (rc && rc != AFMT_OPT_REPORTED)
                fprintf(stderr, "%s: %s '%s': %s\n", prog, o->name, a,
                        o->wants ? o->wants : "not taken");
            if (rc) return AFMT_OPTS_BAD;
            continue;
        }
        const afmt_opt *o = opt_find(opts, a);
        if (o && o->kind == AFMT_OPT_FLAG) {
            *(bool *)o->dest = true;
            continue;
        }
        if (!o || o->kind == AFMT_OPT_ARG || i + 1 >= argc) {
            fprintf(stderr, "%s: unknown or incomplete option '%s' (see --help)\n", prog, a);
            return AFMT_OPTS_BAD;
        }
        const char *v = argv[++i];
        double x;
        bool number =
            o->kind == AFMT_OPT_DOUBLE || o->kind == AFMT_OPT_INT || o->kind == AFMT_OPT_LONG;
        /* a unit: the values in SI (to echo), a suffix of the other unit refused first */
        double si[SI_LIST_MAX];
        int n_si = 0, si_rc = 0;
        if (o->unit != AFMT_UNIT_NONE) {
            si_rc = si_scan(v, o->unit, si, o->kind == AFMT_OPT_FN ? SI_LIST_MAX : 1, &n_si);
            bool bad_number = o->kind == AFMT_OPT_DOUBLE && (si_rc < 0 || !isfinite(si[0]));
            if (si_rc == AFMT_SI_WRONG_UNIT || bad_number) {
                si_bad(prog, a, v, o->unit, si_rc == AFMT_SI_WRONG_UNIT ? si_rc : AFMT_SI_BAD);
                return AFMT_OPTS_BAD;
            }
        } else if (number && (afm_opts_parse_double(v, &x) || !isfinite(x))) {
            fprintf(stderr, "%s: %s wants a number, got '%s'\n", prog, a, v);
            return AFMT_OPTS_BAD;
        }
        int rc = opt_store(o, v);
        if (rc == AFMT_OPT_REPORTED) return AFMT_OPTS_BAD;
        if (rc && o->kind == AFMT_OPT_CHOICE) {
            choice_bad(prog, a, o->choices, v);
            return AFMT_OPTS_BAD;
        }
        if (rc) {
            if (o->wants)
                fprintf(stderr, "%s: %s wants %s, got '%s'", prog, a, o->wants, v);
            else
                fprintf(stderr,
                        o->lo_open ? "%s: %s wants %s in (%g, %g]%s%s, got '%s'"
                                   : "%s: %s wants %s in %g..%g%s%s, got '%s'",
                        prog, a, o->kind == AFMT_OPT_DOUBLE ? "a number" : "an integer", o->lo,
                        o->hi, o->unit ? " " : "", afmt_unit_name(o->unit), v);
            if (si_rc == 1 && n_si == 1)
                fprintf(stderr, " (= %.10g %s)", si[0], afmt_unit_name(o->unit));
            fputc('\n', stderr);
            return AFMT_OPTS_BAD;
        }
        if (si_rc == 1) si_echo(&echoes, prog, a, v, o->unit, si, n_si);
    }
    bool quiet = false; /* --quiet (send, replay: nothing on success) silences the echoes */
    for (int i = first; i < argc; i++)
        quiet = quiet || !strcmp(argv[i], "--quiet");
    if (!quiet) fputs(echoes.text, stderr);
    return AFMT_OPTS_OK;
}
