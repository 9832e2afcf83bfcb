/* SPDX-License-Identifier: MIT */
/* opts.c -- what the subcommands add to the shared option parser (opts.h, cli/afm_opts.h). */
#include "opts.h"

#include "lcm_tool.h"

#include "config/afm_config.h"

#include <errno.h>
#include <stdarg.h>
#include <unistd.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int afmt_opt_si_value(const char *tool, const char *opt, const char *value, afmt_unit u,
                      double *v) {
    char prog[96];
    snprintf(prog, sizeof prog, "afmtwin %s", tool);
    return afm_opts_si_value(prog, opt, value, u, v);
}

int afmt_opts_parse(const char *tool, const afmt_opt *opts, int argc, char **argv, int first) {
    char prog[96];
    snprintf(prog, sizeof prog, "afmtwin %s", tool);
    return afm_opts_parse(prog, opts, argc, argv, first);
}

int afmt_opt_channels(const char *value, void *want) {
    return afmt_parse_outputs(value, false, want);
}

const afmt_choice afmt_integrator_choices[] = {{"rt", AFM_INTEGRATOR_RT},
                                               {"reference", AFM_INTEGRATOR_REFERENCE},
                                               {"arkode-erk", AFM_INTEGRATOR_ARKODE_ERK},
                                               {NULL, 0}};

const afmt_choice afmt_scheme_choices[] = {
    {"accurate", AFM_RT_SCHEME_ACCURATE}, {"fast", AFM_RT_SCHEME_FAST}, {NULL, 0}};

int afmt_opt_any_number(const char *value, void *number) {
    char *end;
    errno = 0;
    double v = strtod(value, &end);
    if (errno || end == value || *end) return -1;
    *(double *)number = v;
    return 0;
}

int afmt_opt_any_length(const char *value, void *number) {
    return afmt_parse_si(value, AFMT_UNIT_M, number) < 0 ? -1 : 0;
}

int afmt_opt_any_freq(const char *value, void *number) {
    return afmt_parse_si(value, AFMT_UNIT_HZ, number) < 0 ? -1 : 0;
}

void afmt_progress_init(afmt_progress *p) {
    *p = (afmt_progress){.tty = isatty(STDERR_FILENO) != 0,
                         .out_tty = isatty(STDOUT_FILENO) != 0,
                         .t_start = afmt_mono_s()};
}

static void progress_draw(afmt_progress *p) {
    fprintf(stderr, "\r%s   ", p->line);
    fflush(stderr);
    p->shown = true;
}

void afmt_progress_update(afmt_progress *p, const char *fmt, ...) {
    if (!p->tty) return;
    double t = afmt_mono_s();
    if (t - p->t_start < 1.0 || t - p->t_last < 0.2) return;
    p->t_last = t;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(p->line, sizeof p->line, fmt, ap);
    va_end(ap);
    progress_draw(p);
}

static void progress_clear(afmt_progress *p) {
    fprintf(stderr, "\r%*s\r", (int)strlen(p->line) + 3, "");
    fflush(stderr);
}

void afmt_progress_hide(afmt_progress *p) {
    if (p->shown && p->out_tty) {
        fflush(stdout);
        progress_clear(p);
    }
}

void afmt_progress_redraw(afmt_progress *p) {
    if (p->shown && p->out_tty) {
        fflush(stdout);
        progress_draw(p);
    }
}

void afmt_progress_end(afmt_progress *p) {
    if (p->shown) progress_clear(p);
    p->shown = false;
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

bool afmt_step_events(void) {
    const char *e = getenv("AFMTWIN_STEP_EVENTS");
    return !(e && strcmp(e, "0") == 0);
}

afm_step_events *afmt_step_events_ring(afm_sim *s, int cap) {
    if (!afmt_step_events() || cap < 1 || cap > (1 << 28)) return NULL;
    afm_step_events *ring = malloc(2 * (size_t)cap * sizeof *ring);
    if (ring) afm_sim_set_events(s, ring, 2 * cap);
    return ring;
}
