/* SPDX-License-Identifier: MIT */
/* cmd_continue.c -- `afmtwin continue`: numerical continuation of the periodic orbits of a
 * config in one parameter (analysis/afm_cont.h): the whole branch, stable and unstable,
 * with its LPC, PD and NS bifurcations, switching at each PD onto the period-doubled
 * branch. One JSON record per point or bifurcation and line (--json), or a table.
 *
 * Phases are the lag of the deflection behind the drive (x_dit = Ae sin(we t)): 90 deg for a
 * free cantilever at resonance, below 90 in the repulsive regime. */
#include "afmtwin_cmds.h"

#include "analysis/afm_cont.h"
#include "config/afm_config.h"
#include "json_out.h"
#include "lcm_tool.h"
#include "opts.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const char *config, *param, *start;
    double from, to;
    int max_points, period, settle, max_branches;
    double h0, h_max;
    bool json, no_switch;
} cont_cli;

static void cont_usage(FILE *f) {
    fprintf(
        f,
        "usage: afmtwin continue --config FILE --param fe|z|ae|NAME --from X --to X\n"
        "                        [--start STATE] [--max-points N] [--period P]\n"
        "                        [--settle N] [--no-switch] [--max-branches N]\n"
        "                        [--step H] [--max-step H] [--json]\n\n"
        "Numerical continuation of the periodic orbits of the modal model with its tip\n"
        "forces (the config's drive must be one tone): starting from the orbit at --from\n"
        "(found by time integration from rest, or from --start), the branch is followed by\n"
        "pseudo-arclength continuation towards --to, through its folds, stable and unstable\n"
        "parts alike, until it leaves [--from, --to] or another stop reason. Each orbit is\n"
        "found by shooting: Newton's method on the period-p map, whose monodromy matrix comes\n"
        "from CVODES forward sensitivities (tolerance sim.ref_rtol), the contact's force kinks\n"
        "located by root finding. Stability from the Floquet multipliers (the eigenvalues of\n"
        "the monodromy matrix): LPC (a multiplier through +1, a fold), PD (through -1) and NS\n"
        "(a complex pair through the unit circle) are located and refined to the parameter.\n"
        "At each PD the period-doubled branch is continued too (unless --no-switch).\n\n"
        "Phase convention: the lag of the deflection behind the drive (x_dit = Ae sin(we t)),\n"
        "90 deg for a free cantilever at resonance, below 90 in the repulsive regime.\n\n"
        "options:\n"
        "  --config FILE      libconfig model file (see config/README.md)\n"
        "  --param NAME       fe (tone 0 frequency, Hz), z (separation, m), ae (tone 0\n"
        "                     amplitude, m), or a live parameter of `afmtwin send param`\n"
        "                     with a force or damping effect (e.g.\n"
        "                     forces.vdw_contact.hamaker_j, model.damping_ratio[0])\n"
        "  --from X, --to X   the range; the branch starts at --from (X in the unit of NAME)\n"
        "  --start STATE      the start state at drive phase 0 instead of the time\n"
        "                     integration: 2n comma-separated modal values q1..qn,q1'..qn'\n"
        "  --period P         drive periods of the start orbit, 1..%d (default 1)\n"
        "  --settle N         drive periods of time integration before the start (default\n"
        "                     5 Q1 / pi, at least 50: transients down by e^-5)\n"
        "  --max-points N     most points over all branches (default 2000)\n"
        "  --no-switch        stay on the start branch (no period-doubled branches)\n"
        "  --max-branches N   most branches, 1..32 (default 8)\n"
        "  --step H           first step (scaled arclength: 1 = the range in the parameter,\n"
        "                     or the start orbit's amplitude in the state; default 0.02)\n"
        "  --max-step H       largest step (default 0.25)\n"
        "  --json             one JSON object per line: {\"type\": \"point\", \"branch\", "
        "\"param\",\n"
        "                     \"period\", \"stable\", \"multipliers\": [[re, im], ...],\n"
        "                     \"min_deflection_m\", \"max_deflection_m\", \"max_force_n\",\n"
        "                     \"min_force_n\", \"amplitude_m\", \"phase_lag_deg\",\n"
        "                     \"mean_deflection_m\", \"indentation_m\", \"contact_time_s\",\n"
        "                     \"dissipated_energy_j\", \"virial_j\", \"contacts\": "
        "[{\"min_deflection_m\",\n"
        "                     \"pre_contact_velocity_m_s\", \"max_force_n\", \"t_in_s\",\n"
        "                     \"duration_s\"}], \"residual\", \"iterations\"}; per bifurcation\n"
        "                     {\"type\": \"LPC\"|\"PD\"|\"NS\", \"branch\", \"param\", "
        "\"multiplier\":\n"
        "                     [re, im], \"refined\" (false: not located, at the later point of a "
        "step),\n"
        "                     ...the point's fields}; per branch end {\"type\":\n"
        "                     \"end\", \"branch\", \"parent\", \"period\", \"param\", \"points\",\n"
        "                     \"reason\"}; last {\"type\": \"summary\", \"points\", \"branches\",\n"
        "                     \"bifurcations\", \"maps\", \"seconds\", \"seconds_per_point\"}\n"
        "  --help             this text\n\n"
        "Without --json a table (kHz or the parameter's unit, nm, nN). The config's sim.ref_rtol\n"
        "(default 1e-10) is the integration tolerance.\n"
        "Exit status 0 ok, 1 the start orbit was not found or the integration failed, 2 bad\n"
        "usage or bad input.\n",
        AFM_CONT_MAX_P);
}

/* 0 ok, 1 --help, -1 bad usage (said). */
static int cont_parse(int argc, char **argv, cont_cli *o) {
    *o = (cont_cli){.from = NAN, .to = NAN, .period = 1};
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &o->json),
        AFMT_FLAG("--no-switch", &o->no_switch),
        AFMT_STRING("--config", &o->config),
        AFMT_STRING("--param", &o->param),
        AFMT_STRING("--start", &o->start),
        AFMT_DOUBLE("--from", &o->from, 0, 0, NULL),
        AFMT_DOUBLE("--to", &o->to, 0, 0, NULL),
        AFMT_DOUBLE("--step", &o->h0, 0, 0, NULL),
        AFMT_DOUBLE("--max-step", &o->h_max, 0, 0, NULL),
        AFMT_INT("--max-points", &o->max_points, 1, 1000000, NULL),
        AFMT_INT("--period", &o->period, 1, AFM_CONT_MAX_P, NULL),
        AFMT_INT("--settle", &o->settle, 1, 100000000, NULL),
        AFMT_INT("--max-branches", &o->max_branches, 1, 32, NULL),
        AFMT_OPTS_END,
    };
    int rc = afmt_opts_parse("continue", opts, argc, argv, 1);
    if (rc) return rc == AFMT_OPTS_HELP ? 1 : -1;
    if (!o->config || !o->param || isnan(o->from) || isnan(o->to)) {
        fprintf(stderr, "afmtwin continue: --config, --param, --from and --to are required\n");
        return -1;
    }
    if (o->from == o->to) {
        fprintf(stderr, "afmtwin continue: --from and --to must differ\n");
        return -1;
    }
    if ((o->h0 != 0 && !(o->h0 > 0 && o->h0 <= 1)) ||
        (o->h_max != 0 && !(o->h_max > 0 && o->h_max <= 1))) {
        fprintf(stderr, "afmtwin continue: --step and --max-step must be in (0, 1]\n");
        return -1;
    }
    return 0;
}

/* --start: exactly n comma-separated finite numbers. 0 or -1 (said). */
static int cont_parse_state(const char *s, int n, double *y) {
    double v[AFM_CONT_MAX_N + 1];
    if (afmt_parse_list(s, v, AFM_CONT_MAX_N + 1) == n) {
        bool finite = true;
        for (int i = 0; i < n; i++)
            finite &= isfinite(v[i]);
        if (finite) {
            memcpy(y, v, sizeof(double) * (size_t)n);
            return 0;
        }
    }
    fprintf(stderr,
            "afmtwin continue: --start needs %d comma-separated finite numbers (q1..q%d, "
            "q1'..q%d' of the config's %d modes)\n",
            n, n / 2, n / 2, n / 2);
    return -1;
}

typedef struct {
    bool json;
    const char *name; /* --param */
    const char *unit;
    double scale; /* of the table's parameter column */
} cont_sink;

static const char *kind_name(afm_cont_kind k) {
    static const char *const names[] = {"point", "LPC", "PD", "NS", "end"};
    return names[k];
}

static void json_metrics(cJSON *o, const afm_cont_metrics *m) {
    cJSON_AddNumberToObject(o, "min_deflection_m", m->min_deflection_m);
    cJSON_AddNumberToObject(o, "max_deflection_m", m->max_deflection_m);
    cJSON_AddNumberToObject(o, "max_force_n", m->max_force_n);
    cJSON_AddNumberToObject(o, "min_force_n", m->min_force_n);
    cJSON_AddNumberToObject(o, "amplitude_m", m->amplitude_m);
    cJSON_AddNumberToObject(o, "phase_lag_deg", m->phase_lag_deg);
    cJSON_AddNumberToObject(o, "mean_deflection_m", m->mean_deflection_m);
    cJSON_AddNumberToObject(o, "indentation_m", m->indentation_m);
    cJSON_AddNumberToObject(o, "contact_time_s", m->contact_time_s);
    cJSON_AddNumberToObject(o, "dissipated_energy_j", m->dissipated_energy_j);
    cJSON_AddNumberToObject(o, "virial_j", m->virial_j);
    cJSON *cs = cJSON_AddArrayToObject(o, "contacts");
    for (int i = 0; i < m->n_contacts; i++) {
        const afm_cont_contact *c = &m->contacts[i];
        cJSON *e = cJSON_CreateObject();
        cJSON_AddNumberToObject(e, "min_deflection_m", c->min_deflection_m);
        cJSON_AddNumberToObject(e, "pre_contact_velocity_m_s", c->pre_contact_velocity_m_s);
        cJSON_AddNumberToObject(e, "max_force_n", c->max_force_n);
        cJSON_AddNumberToObject(e, "t_in_s", c->t_in_s);
        cJSON_AddNumberToObject(e, "duration_s", c->duration_s);
        cJSON_AddItemToArray(cs, e);
    }
}

static int cont_emit(void *ctx, const afm_cont_record *r) {
    const cont_sink *s = ctx;
    if (!s->json) {
        if (r->kind == AFM_CONT_END)
            printf("# branch %d (period %d, from branch %d) ends after %d points: %s\n", r->branch,
                   r->p, r->parent, r->points, r->stop_reason);
        else
            printf("%-5s %3d %2d %14.8g %-8s %12.6f %12.6f %10.5f %12.6f %8.3f\n",
                   kind_name(r->kind), r->branch, r->p, r->param * s->scale,
                   r->stable ? "stable" : "unstable", r->metrics.min_deflection_m * 1e9,
                   r->metrics.max_deflection_m * 1e9, r->metrics.max_force_n * 1e9,
                   r->metrics.amplitude_m * 1e9, r->metrics.phase_lag_deg);
        fflush(stdout);
        return 0;
    }
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "type", kind_name(r->kind));
    cJSON_AddStringToObject(o, "param_name", s->name);
    cJSON_AddNumberToObject(o, "branch", r->branch);
    cJSON_AddNumberToObject(o, "parent", r->parent);
    cJSON_AddNumberToObject(o, "param", r->param);
    cJSON_AddNumberToObject(o, "period", r->p);
    if (r->kind == AFM_CONT_END) {
        cJSON_AddNumberToObject(o, "points", r->points);
        cJSON_AddStringToObject(o, "reason", r->stop_reason);
        afmt_json_emit(o);
        fflush(stdout);
        return 0;
    }
    cJSON_AddBoolToObject(o, "stable", r->stable);
    if (r->kind != AFM_CONT_POINT) {
        cJSON *mu = cJSON_AddArrayToObject(o, "multiplier");
        cJSON_AddItemToArray(mu, cJSON_CreateNumber(r->multiplier[0]));
        cJSON_AddItemToArray(mu, cJSON_CreateNumber(r->multiplier[1]));
        cJSON_AddBoolToObject(o, "refined", r->refined);
    }
    cJSON *ms = cJSON_AddArrayToObject(o, "multipliers");
    for (int i = 0; i < r->n_mult; i++) {
        cJSON *e = cJSON_CreateArray();
        cJSON_AddItemToArray(e, cJSON_CreateNumber(r->mult_re[i]));
        cJSON_AddItemToArray(e, cJSON_CreateNumber(r->mult_im[i]));
        cJSON_AddItemToArray(ms, e);
    }
    json_metrics(o, &r->metrics);
    cJSON *st = cJSON_AddArrayToObject(o, "state");
    for (int i = 0; i < r->n_mult; i++)
        cJSON_AddItemToArray(st, cJSON_CreateNumber(r->y[i]));
    cJSON_AddNumberToObject(o, "residual", r->residual);
    cJSON_AddNumberToObject(o, "iterations", r->iterations);
    afmt_json_emit(o);
    fflush(stdout);
    return 0;
}

int afm_cmd_continue(int argc, char **argv) {
    cont_cli o;
    int rc = afmt_opts_done("continue", cont_parse(argc, argv, &o), cont_usage);
    if (rc >= 0) return rc;
    char err[512];
    afm_config cfg;
    if (afm_config_load(o.config, &cfg, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin continue: %s\n", err);
        return 2;
    }
    afm_cont_ctx probe;
    if (afm_cont_ctx_init(&probe, &cfg, o.param, fabs(o.to - o.from), 1e-9, err, sizeof err) != 0) {
        afm_cont_ctx_free(&probe);
        fprintf(stderr, "afmtwin continue: %s\n", err);
        return 2;
    }
    afm_cont_inst inst;
    int bad = afm_cont_inst_at(&probe.base, &probe.par, &o.from, 1, &inst, err, sizeof err) ||
              afm_cont_inst_at(&probe.base, &probe.par, &o.to, 1, &inst, err, sizeof err);
    int N = probe.N;
    bool is_fe = probe.par.kind == AFM_CONT_FE;
    char unit[16];
    snprintf(unit, sizeof unit, "%s", is_fe ? "kHz" : probe.par.unit);
    afm_cont_ctx_free(&probe);
    if (bad) {
        fprintf(stderr, "afmtwin continue: %s\n", err);
        return 2;
    }
    double y0[AFM_CONT_MAX_N];
    if (o.start && cont_parse_state(o.start, N, y0) != 0) return 2;
    afm_cont_opts co = {.param = o.param,
                        .from = o.from,
                        .to = o.to,
                        .p = o.period,
                        .max_points = o.max_points,
                        .max_branches = o.max_branches,
                        .no_switch = o.no_switch,
                        .start_y = o.start ? y0 : NULL,
                        .settle_periods = o.settle,
                        .h0 = o.h0,
                        .h_max = o.h_max};
    cont_sink sink = {.json = o.json, .name = o.param, .unit = unit, .scale = is_fe ? 1e-3 : 1.0};
    if (!o.json)
        printf("# %-3s %3s %2s %14s %-8s %12s %12s %10s %12s %8s\n", "kind", "br", "p", unit, "",
               "min x (nm)", "max x (nm)", "max F (nN)", "ampl (nm)", "lag (deg)");
    afm_cont_summary sum;
    if (afm_cont_run(&cfg, &co, cont_emit, &sink, &sum, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin continue: %s\n", err);
        return 1;
    }
    double per = sum.points > 0 ? sum.seconds / sum.points : 0.0;
    if (o.json) {
        cJSON *s = cJSON_CreateObject();
        cJSON_AddStringToObject(s, "type", "summary");
        cJSON_AddNumberToObject(s, "points", sum.points);
        cJSON_AddNumberToObject(s, "branches", sum.branches);
        cJSON_AddNumberToObject(s, "bifurcations", sum.bifurcations);
        cJSON_AddNumberToObject(s, "maps", (double)sum.maps);
        cJSON_AddNumberToObject(s, "flow_steps", (double)sum.flow_steps);
        cJSON_AddNumberToObject(s, "seconds", sum.seconds);
        cJSON_AddNumberToObject(s, "seconds_per_point", per);
        afmt_json_emit(s);
    } else {
        printf("# %d points on %d branches, %d bifurcations, %ld Newton maps, %.2f s (%.3f s "
               "per point)\n",
               sum.points, sum.branches, sum.bifurcations, sum.maps, sum.seconds, per);
    }
    return 0;
}
