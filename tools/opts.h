/* SPDX-License-Identifier: MIT */
/* opts.h -- what afmtwin's subcommands add to the shared option tables (cli/afm_opts.h: the
 * parser, its rows and messages): the tool's name in the messages ("afmtwin TOOL: ..."), the
 * values only the tools take (channels, integrator, scheme, any number for --no-check), the
 * config load, the progress line and the step-event ring every offline tool shares. */
#ifndef AFMT_OPTS_H
#define AFMT_OPTS_H

#include "cli/afm_opts.h"
#include "config/afm_config.h"
#include "integrators/afm_sim.h"

#include <stdbool.h>
#include <stdio.h>

/* One value of a length / frequency option parsed outside a table (e.g. when its unit is
 * known only after parsing): 0 with *v set (and the SI echo on stderr if a suffix was
 * given), or -1 after "afmtwin TOOL: OPT wants ..., got 'value'" on stderr. */
int afmt_opt_si_value(const char *tool, const char *opt, const char *value, afmt_unit u, double *v);

/* Parse argv[first..argc-1] against the table opts for "afmtwin TOOL" (afm_opts_parse with
 * that name). Returns AFMT_OPTS_OK, AFMT_OPTS_HELP (--help or -h: print the usage, exit 0)
 * or AFMT_OPTS_BAD (the message is printed: exit 2). */
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

/* --integrator of sweep, approach and map (AFMT_CHOICE): rt, reference or arkode-erk into an
 * int (AFM_INTEGRATOR_*). */
extern const afmt_choice afmt_integrator_choices[];
/* What a tool does with its parse_args result (1: --help was asked, -1: bad usage, already
 * said, 0: go on): the usage on stdout for --help, the hint "(afmtwin TOOL --help describes
 * every option)" on stderr for bad usage. Returns the exit code (0 or 2), or -1 to go on:
 *     int rc = afmt_opts_done("sweep", parse_args(argc, argv, &o), sweep_usage);
 *     if (rc >= 0) return rc; */
int afmt_opts_done(const char *tool, int parse_rc, void (*usage)(FILE *));

/* --scheme of the offline tools (AFMT_CHOICE): the rt integrator's scheme, accurate or fast,
 * into an int (AFM_RT_SCHEME_*). Offline the default (auto) is accurate. */
extern const afmt_choice afmt_scheme_choices[];
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
