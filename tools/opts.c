/* SPDX-License-Identifier: MIT */
/* opts.c -- the subcommands' table-driven option parser (opts.h). */
#include "opts.h"

#include "lcm_tool.h"

#include "config/afm_config.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
        if (afmt_parse_double(v, &x) || !in_range(o, x)) return -1;
        *(double *)o->dest = x;
        return 0;
    case AFMT_OPT_INT:
    case AFMT_OPT_LONG:
    case AFMT_OPT_LLONG:
    case AFMT_OPT_UINT:
    case AFMT_OPT_U64:
        if (afmt_parse_double(v, &x) || !in_range(o, x) || x != floor(x)) return -1;
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
    case AFMT_OPT_FLAG:
    case AFMT_OPT_ARG:
        break;
    }
    return -1;
}

int afmt_opts_parse(const char *tool, const afmt_opt *opts, int argc, char **argv, int first) {
    for (int i = first; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) return AFMT_OPTS_HELP;
        if (a[0] != '-' || !a[1]) { /* an argument: the first AFMT_ARG row that takes it */
            const afmt_opt *o = opts;
            while (o->name && !(o->kind == AFMT_OPT_ARG && (o->parse || !*(const char **)o->dest)))
                o++;
            if (!o->name) {
                fprintf(stderr, "afmtwin %s: unknown option or extra argument '%s' (see --help)\n",
                        tool, a);
                return AFMT_OPTS_BAD;
            }
            int rc = 0;
            if (!o->parse)
                *(const char **)o->dest = a;
            else
                rc = o->parse(a, o->dest);
            if (rc && rc != AFMT_OPT_REPORTED)
                fprintf(stderr, "afmtwin %s: %s '%s': %s\n", tool, o->name, a,
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
            fprintf(stderr, "afmtwin %s: unknown or incomplete option '%s' (see --help)\n", tool,
                    a);
            return AFMT_OPTS_BAD;
        }
        const char *v = argv[++i];
        double x;
        bool number =
            o->kind == AFMT_OPT_DOUBLE || o->kind == AFMT_OPT_INT || o->kind == AFMT_OPT_LONG;
        if (number && (afmt_parse_double(v, &x) || !isfinite(x))) {
            fprintf(stderr, "afmtwin %s: %s wants a number, got '%s'\n", tool, a, v);
            return AFMT_OPTS_BAD;
        }
        int rc = opt_store(o, v);
        if (rc == AFMT_OPT_REPORTED) return AFMT_OPTS_BAD;
        if (rc) {
            if (o->wants)
                fprintf(stderr, "afmtwin %s: %s wants %s, got '%s'\n", tool, a, o->wants, v);
            else
                fprintf(stderr,
                        o->lo_open ? "afmtwin %s: %s wants %s in (%g, %g], got '%s'\n"
                                   : "afmtwin %s: %s wants %s in %g..%g, got '%s'\n",
                        tool, a, o->kind == AFMT_OPT_DOUBLE ? "a number" : "an integer", o->lo,
                        o->hi, v);
            return AFMT_OPTS_BAD;
        }
    }
    return AFMT_OPTS_OK;
}

int afmt_opt_channels(const char *value, void *want) {
    return afmt_parse_outputs(value, false, want);
}

int afmt_opt_integrator(const char *value, void *integrator) {
    int *it = integrator;
    if (!strcmp(value, "rt"))
        *it = AFM_INTEGRATOR_RT;
    else if (!strcmp(value, "reference"))
        *it = AFM_INTEGRATOR_REFERENCE;
    else if (!strcmp(value, "arkode-erk"))
        *it = AFM_INTEGRATOR_ARKODE_ERK;
    else
        return -1;
    return 0;
}

int afmt_opt_scheme(const char *value, void *scheme) {
    int *it = scheme;
    if (!strcmp(value, "accurate"))
        *it = AFM_RT_SCHEME_ACCURATE;
    else if (!strcmp(value, "fast"))
        *it = AFM_RT_SCHEME_FAST;
    else
        return -1;
    return 0;
}

int afmt_opt_any_number(const char *value, void *number) {
    char *end;
    errno = 0;
    double v = strtod(value, &end);
    if (errno || end == value || *end) return -1;
    *(double *)number = v;
    return 0;
}

int afmt_config_load(const char *tool, const char *path, afm_config *cfg) {
    char err[AFM_ERR_LEN];
    if (afm_config_load(path, cfg, err, sizeof err) == 0) return 0;
    fprintf(stderr, "afmtwin %s: %s\n", tool, err);
    return -1;
}

int afmt_opts_done(const char *tool, int parse_rc, void (*usage)(FILE *)) {
    if (parse_rc == 1) {
        usage(stdout);
        return 0;
    }
    if (parse_rc < 0) {
        fprintf(stderr, "(afmtwin %s --help describes every option)\n", tool);
        return 2;
    }
    return -1;
}
