/* SPDX-License-Identifier: MIT */
/* opts.h -- the subcommands' option parser: each tool describes its options in one table
 * (name, kind, destination, range, what a bad value is told) instead of an else-if chain.
 *
 * afmt_opts_parse walks argv: --help / -h asks for the usage, a flag sets its bool, any other
 * option takes the next word, checks it against its kind and range and stores it. A value
 * that is no number where one is wanted prints "afmtwin TOOL: --opt wants a number, got
 * 'v'", one out of range (or no value of a parse function's) "afmtwin TOOL: --opt wants
 * WANTS, got 'v'", an unknown option or a missing
 * value "afmtwin TOOL: unknown or incomplete option '--x' (see --help)", a word that is
 * no option where the table has no (further) AFMT_ARG row "unknown option or extra argument
 * 'x' (see --help)"; each makes the tool
 * exit 2 and store nothing more. */
#ifndef AFMT_OPTS_H
#define AFMT_OPTS_H

#include "config/afm_config.h"
#include "integrators/afm_sim.h"

#include <stdbool.h>
#include <stdio.h>

typedef enum {
    AFMT_OPT_FLAG,   /* bool *: set to true, no value */
    AFMT_OPT_STRING, /* const char **: the value as given */
    AFMT_OPT_DOUBLE, /* double *: a finite number in the range */
    AFMT_OPT_INT,    /* int *: an integer in the range */
    AFMT_OPT_LONG,   /* long *: an integer in the range */
    AFMT_OPT_LLONG,  /* long long * */
    AFMT_OPT_UINT,   /* unsigned * (a range within 0..UINT_MAX) */
    AFMT_OPT_U64,    /* uint64_t * (a range within 0..1.8e19) */
    AFMT_OPT_FN,     /* parse(value, dest) returns 0 for a good value */
    AFMT_OPT_ARG,    /* a word that is no option (a file name; "-" too): into the
                      * const char ** once, or through parse as often as it accepts */
} afmt_opt_kind;

/* The unit of a length or frequency option: its value may carry an SI suffix (opts.c,
 * afmt_parse_si), echoed in SI on stderr when one was given (not with --quiet). */
typedef enum {
    AFMT_UNIT_NONE = 0,
    AFMT_UNIT_M,  /* m, mm, um (µm), nm, pm, fm */
    AFMT_UNIT_HZ, /* Hz, kHz, MHz, GHz */
} afmt_unit;

typedef struct {
    const char *name; /* "--count" (NULL ends the table) */
    afmt_opt_kind kind;
    void *dest;
    double lo, hi; /* the range of a number, inclusive; both 0: any finite number */
    bool lo_open;  /* the range excludes lo (a value must be > lo) */
    /* the error's "wants ...": "an integer >= 1", "seconds > 0"; NULL: "a number in lo..hi"
     * ("an integer in ...", "(lo, hi]" for lo_open) */
    const char *wants;
    /* AFMT_OPT_FN: 0 for a good value, -1 for a bad one (the parser says what the option
     * wants), AFMT_OPT_REPORTED when the function printed a more precise message itself */
    int (*parse)(const char *value, void *dest);
    /* AFMT_OPT_DOUBLE: the value may have this unit's suffix; AFMT_OPT_FN: a suffix of the
     * other unit is refused (and a suffix given is echoed) before parse is called, which
     * takes the suffix with afmt_parse_si / afmt_parse_si_list */
    afmt_unit unit;
} afmt_opt;

/* One table row each (designated, so that -Wextra sees every field set). */
#define AFMT_FLAG(name_, dest_)                                                                    \
    { .name = name_, .kind = AFMT_OPT_FLAG, .dest = dest_ }
#define AFMT_STRING(name_, dest_)                                                                  \
    { .name = name_, .kind = AFMT_OPT_STRING, .dest = dest_ }
#define AFMT_NUMBER(name_, kind_, dest_, lo_, hi_, wants_)                                         \
    { .name = name_, .kind = kind_, .dest = dest_, .lo = lo_, .hi = hi_, .wants = wants_ }
#define AFMT_DOUBLE(name_, dest_, lo_, hi_, wants_)                                                \
    AFMT_NUMBER(name_, AFMT_OPT_DOUBLE, dest_, lo_, hi_, wants_)
#define AFMT_DOUBLE_ABOVE(name_, dest_, lo_, hi_, wants_) /* > lo_ */                              \
    {                                                                                              \
        .name = name_, .kind = AFMT_OPT_DOUBLE, .dest = dest_, .lo = lo_, .hi = hi_,               \
        .lo_open = true, .wants = wants_                                                           \
    }
/* A length (m) or frequency (Hz): a number, or one with a suffix (30nm, 338.112kHz). */
#define AFMT_LENGTH(name_, dest_, lo_, hi_, wants_)                                                \
    {                                                                                              \
        .name = name_, .kind = AFMT_OPT_DOUBLE, .dest = dest_, .lo = lo_, .hi = hi_,               \
        .wants = wants_, .unit = AFMT_UNIT_M                                                       \
    }
#define AFMT_LENGTH_ABOVE(name_, dest_, lo_, hi_, wants_) /* > lo_ */                              \
    {                                                                                              \
        .name = name_, .kind = AFMT_OPT_DOUBLE, .dest = dest_, .lo = lo_, .hi = hi_,               \
        .lo_open = true, .wants = wants_, .unit = AFMT_UNIT_M                                      \
    }
#define AFMT_FREQ(name_, dest_, lo_, hi_, wants_)                                                  \
    {                                                                                              \
        .name = name_, .kind = AFMT_OPT_DOUBLE, .dest = dest_, .lo = lo_, .hi = hi_,               \
        .wants = wants_, .unit = AFMT_UNIT_HZ                                                      \
    }
#define AFMT_FREQ_ABOVE(name_, dest_, lo_, hi_, wants_) /* > lo_ */                                \
    {                                                                                              \
        .name = name_, .kind = AFMT_OPT_DOUBLE, .dest = dest_, .lo = lo_, .hi = hi_,               \
        .lo_open = true, .wants = wants_, .unit = AFMT_UNIT_HZ                                     \
    }
#define AFMT_INT(name_, dest_, lo_, hi_, wants_)                                                   \
    AFMT_NUMBER(name_, AFMT_OPT_INT, dest_, lo_, hi_, wants_)
#define AFMT_LONG(name_, dest_, lo_, hi_, wants_)                                                  \
    AFMT_NUMBER(name_, AFMT_OPT_LONG, dest_, lo_, hi_, wants_)
#define AFMT_FN(name_, parse_, dest_, wants_)                                                      \
    { .name = name_, .kind = AFMT_OPT_FN, .dest = dest_, .wants = wants_, .parse = parse_ }
/* An AFMT_FN row whose value (or comma-separated values) has a unit. */
#define AFMT_FN_UNIT(name_, parse_, dest_, wants_, unit_)                                          \
    {                                                                                              \
        .name = name_, .kind = AFMT_OPT_FN, .dest = dest_, .wants = wants_, .parse = parse_,       \
        .unit = unit_                                                                              \
    }
#define AFMT_ARG(name_, dest_)                                                                     \
    { .name = name_, .kind = AFMT_OPT_ARG, .dest = dest_ }
#define AFMT_ARG_FN(name_, parse_, dest_, wants_)                                                  \
    { .name = name_, .kind = AFMT_OPT_ARG, .dest = dest_, .wants = wants_, .parse = parse_ }
#define AFMT_OPTS_END                                                                              \
    { .name = NULL }

#define AFMT_OPT_REPORTED (-2)

/* A number as strtod reads it, with an optional suffix of unit u (none for
 * AFMT_UNIT_NONE), into *v in SI: "30nm" 3e-08, "338.112kHz" 338112. Returns 0 for a plain
 * number, 1 for one with a suffix, AFMT_SI_BAD for no number or an unknown suffix,
 * AFMT_SI_WRONG_UNIT for a suffix of the other unit ("30kHz" for a length). */
#define AFMT_SI_BAD (-1)
#define AFMT_SI_WRONG_UNIT (-2)
int afmt_parse_si(const char *s, afmt_unit u, double *v);
/* 1..max comma-separated values of afmt_parse_si: the count, or -1. */
int afmt_parse_si_list(const char *s, afmt_unit u, double *v, int max);
/* "m" or "Hz" ("" for none); the other suffixes a unit takes, "mm, um, µm, nm, pm, fm". */
const char *afmt_unit_name(afmt_unit u);
const char *afmt_unit_suffixes(afmt_unit u);
/* One value of a length / frequency option parsed outside a table (e.g. when its unit is
 * known only after parsing): 0 with *v set (and the SI echo on stderr if a suffix was
 * given), or -1 after "afmtwin TOOL: OPT wants ..., got 'value'" on stderr. */
int afmt_opt_si_value(const char *tool, const char *opt, const char *value, afmt_unit u, double *v);
/* The sentence the tools' --help texts share. */
#define AFMT_OPT_SI_HELP                                                                           \
    "Lengths (m) and frequencies (Hz) may carry an SI suffix: 30nm, 1um (or 1µm), 5pm,\n"         \
    "338.112kHz, 1.5MHz (m, mm, um, nm, pm, fm; Hz, kHz, MHz, GHz).\n"

enum { AFMT_OPTS_OK = 0, AFMT_OPTS_HELP = 1, AFMT_OPTS_BAD = 2 };

/* Parse argv[first..argc-1] against the table opts for "afmtwin TOOL". Returns
 * AFMT_OPTS_OK, AFMT_OPTS_HELP (--help or -h: print the usage, exit 0) or AFMT_OPTS_BAD
 * (the message is printed: exit 2). */
int afmt_opts_parse(const char *tool, const afmt_opt *opts, int argc, char **argv, int first);

/* --channels of listen and replay: a subset of the output channels into a bool[4] (the
 * destination), afmt_parse_outputs without "all". */
int afmt_opt_channels(const char *value, void *want);
/* The LCM tools' URL and channel-prefix options (lcm_tool.h's afmt_lcm_open takes the three
 * URLs, afmt_channels_init the prefix). */
#define AFMT_LCM_OPTS(url_, out_url_, samples_url_, prefix_)                                       \
    AFMT_STRING("--lcm-url", url_), AFMT_STRING("--lcm-out-url", out_url_),                        \
        AFMT_STRING("--lcm-samples-url", samples_url_), AFMT_STRING("--prefix", prefix_)
/* A number as strtod reads it, NaN and inf too: the commands of send and can-send, whose
 * --no-check sends what the daemon must reject. */
int afmt_opt_any_number(const char *value, void *number);
/* The same with a length's (m) or a frequency's (Hz) suffix (afmt_parse_si), for
 * AFMT_FN_UNIT rows. */
int afmt_opt_any_length(const char *value, void *number);
int afmt_opt_any_freq(const char *value, void *number);

/* Load the config file a tool's --config names into cfg; on failure print "afmtwin TOOL:
 * reason" and return -1 (the tool exits 2). */
int afmt_config_load(const char *tool, const char *path, afm_config *cfg);

/* --integrator of sweep and approach: rt, reference or arkode-erk into an int
 * (AFM_INTEGRATOR_*). */
int afmt_opt_integrator(const char *value, void *integrator);
/* What a tool does with its parse_args result (1: --help was asked, -1: bad usage, already
 * said, 0: go on): the usage on stdout for --help, the hint "(afmtwin TOOL --help describes
 * every option)" on stderr for bad usage. Returns the exit code (0 or 2), or -1 to go on:
 *     int rc = afmt_opts_done("sweep", parse_args(argc, argv, &o), sweep_usage);
 *     if (rc >= 0) return rc; */
int afmt_opts_done(const char *tool, int parse_rc, void (*usage)(FILE *));

#define AFMT_OPT_INTEGRATOR_WANTS "rt, reference or arkode-erk"

/* --scheme of the offline tools: the rt integrator's scheme, accurate or fast, into an int
 * (AFM_RT_SCHEME_*). Offline the default (auto) is accurate. */
int afmt_opt_scheme(const char *value, void *scheme);
#define AFMT_OPT_SCHEME_WANTS "accurate or fast"
#define AFMT_OPT_SCHEME_HELP                                                                       \
    "  --scheme NAME      the rt integrator's scheme: accurate (the default offline: the tip\n"    \
    "                     force cubic Hermite in time, CVODE's steady state) or fast (the\n"       \
    "                     daemon's fallback, second order; docs/numerics.md)\n"
/* The one progress line on stderr of every long offline run (scan, continue, replay, sweep,
 * approach, force-curve, map): only when stderr is a terminal, nothing in the
 * first second (a quick run stays quiet), redrawn at most every 0.2 s with "\r", cleared at
 * the end. When stdout is the same terminal, the tool hides the line around its output. */
typedef struct {
    bool tty, out_tty, shown;
    double t_start, t_last;
    char line[160];
} afmt_progress;
void afmt_progress_init(afmt_progress *p);
/* Format and draw the line if it is due (printf-style; cheap when not). */
void afmt_progress_update(afmt_progress *p, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Around a line on stdout: hide the progress line (if stdout is a terminal), draw it again. */
void afmt_progress_hide(afmt_progress *p);
void afmt_progress_redraw(afmt_progress *p);
/* Clear the line for good. */
void afmt_progress_end(afmt_progress *p);

/* The integrator's per-step record for the per-period metrics (afm_sim_set_events, then
 * afm_cycle_push_ev; issue 28): the offline tools take it unless the environment says
 * AFMTWIN_STEP_EVENTS=0 (the samples' estimator alone, to compare). Only the rt accurate scheme
 * and CVODE fill it; the fast scheme, ARKODE and thermal runs do not. The daemon, `replay`
 * and `curve` take it through the runner (afm_runner_step_events, sim.step_events). */
bool afmt_step_events(void);
/* When afmt_step_events(): a ring of 2 cap records (cap: the most samples a tool runs before
 * they reach its estimators) set on s (afm_sim_set_events); the ring, to free after s's last
 * run (NULL: off, or out of memory, and the metrics come from the samples alone). */
afm_step_events *afmt_step_events_ring(afm_sim *s, int cap);

#define AFMT_OPT_CHANNELS_WANTS "a comma-separated subset of samples,harmonics,status,tick_done"

#endif
