/* SPDX-License-Identifier: MIT */
/* afm_opts.h -- the command line's option tables, shared by afmtwin's subcommands
 * (tools/opts.h adds what only they use) and the daemon (daemon/twind_opts.c), so that both
 * programs check a value, refuse a bad one and word the refusal alike.
 *
 * Each program describes its options in one table (name, kind, destination, range, what a
 * bad value is told) instead of an else-if chain. afm_opts_parse walks argv: --help / -h
 * asks for the usage, a flag sets its bool, any other option takes the next word, checks it
 * against its kind and range and stores it. A value that is no number where one is wanted
 * prints "PROG: --opt wants a number, got 'v'", one out of range (or no value of a parse
 * function's) "PROG: --opt wants WANTS, got 'v'", a word that names none of a choice's values
 * "PROG: --opt wants one of NAME1, NAME2, got 'v'", an unknown option or a missing value
 * "PROG: unknown or incomplete option '--x' (see --help)", a word that is no option where
 * the table has no (further) AFMT_ARG row "PROG: unknown option or extra argument 'x' (see
 * --help)"; each makes the program exit 2 and store nothing more. PROG is "afmtwin TOOL" or
 * "afmtwind". */
#ifndef AFM_CLI_OPTS_H
#define AFM_CLI_OPTS_H

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
    AFMT_OPT_CHOICE, /* int * (or an enum's): the value of the choice the word names */
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

/* One word an AFMT_OPT_CHOICE option takes and the value it stores; a list of them ends
 * with {NULL, 0}. */
typedef struct {
    const char *name;
    int value;
} afmt_choice;

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
    const afmt_choice *choices; /* AFMT_OPT_CHOICE: the words it takes, {NULL, 0} last */
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
/* A word of a list into an int (or an enum whose size is an int's): dest_ = the value
 * of the list's entry that names it. */
#define AFMT_CHOICE(name_, dest_, choices_)                                                        \
    { .name = name_, .kind = AFMT_OPT_CHOICE, .dest = dest_, .choices = choices_ }
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
/* The sentence the tools' --help texts share. */
#define AFMT_OPT_SI_HELP                                                                           \
    "Lengths (m) and frequencies (Hz) may carry an SI suffix: 30nm, 1um (or 1µm), 5pm,\n"         \
    "338.112kHz, 1.5MHz (m, mm, um, nm, pm, fm; Hz, kHz, MHz, GHz).\n"

/* One value of a length / frequency option parsed outside a table: 0 with *v set (and the
 * SI echo "PROG: OPT VALUE = V UNIT" on stderr if a suffix was given), or -1 after "PROG: OPT
 * wants ..., got 'value'" on stderr. */
int afm_opts_si_value(const char *prog, const char *opt, const char *value, afmt_unit u, double *v);

/* A whole word as strtod reads it (no trailing text, no overflow): 0 with *v set, or -1. */
int afm_opts_parse_double(const char *s, double *v);

enum { AFMT_OPTS_OK = 0, AFMT_OPTS_HELP = 1, AFMT_OPTS_BAD = 2 };

/* Parse argv[first..argc-1] against the table opts for the program named prog (its
 * messages start "PROG: "). Returns AFMT_OPTS_OK, AFMT_OPTS_HELP (--help or -h: the caller
 * prints the usage and exits 0) or AFMT_OPTS_BAD (the message is printed: exit 2). The
 * values given with an SI suffix are echoed in SI on stderr once the whole line is good
 * (not with --quiet). */
int afm_opts_parse(const char *prog, const afmt_opt *opts, int argc, char **argv, int first);

#endif
