/* SPDX-License-Identifier: MIT */
/* cmd_continue.c -- `afmtwin continue`: numerical continuation of the periodic orbits of a
 * config in one parameter (analysis/afm_cont.h): the whole branch, stable and unstable,
 * with its LPC, PD and NS bifurcations, switching at each PD onto the period-doubled
 * branch and continuing from the ends of branches (a merge at a PD, a fold just beyond the
 * range), each branch opened by a record of how it was reached; with --param2, the curves of its
 * LPC and PD points in the plane of two parameters (analysis/afm_cont_curve.h). One JSON record per
 * point or bifurcation and line (--json), or a table.
 *
 * Phases are the lag of the deflection behind the drive (x_dit = Ae sin(we t)): 90 deg for a
 * free cantilever at resonance, below 90 in the repulsive regime. */
#include "afmtwin_cmds.h"

#include "analysis/afm_cont.h"
#include "analysis/afm_cont_curve.h"
#include "config/afm_config.h"
#include "json_out.h"
#include "lcm_tool.h"
#include "opts.h"
#include "runner/afm_cmd.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* --curve-kinds: the curves of the two-parameter run it traces, as bits */
enum { CURVES_LPC = 1, CURVES_PD = 2, CURVES_ALL = CURVES_LPC | CURVES_PD };

typedef struct {
    const char *config, *param, *start, *param2;
    int curve_kinds; /* CURVES_*; -1: not given (all) */
    double from, to, from2, to2;
    const char *from_s, *to_s, *from2_s, *to2_s; /* in the unit of --param / --param2 */
    int max_points, period, settle, max_branches, curves, curve_points, join_points,
        max_branch_points;
    double h0, h_max, beyond;
    bool json, no_switch, no_end_switch;
} cont_cli;

static void cont_usage(FILE *f) {
    fprintf(
        f,
        "usage: afmtwin continue --config FILE --param fe|z|ae|NAME --from X --to X\n"
        "                        [--start STATE] [--max-points N] [--period P]\n"
        "                        [--settle N] [--no-switch] [--max-branches N]\n"
        "                        [--max-branch-points N] [--no-end-switch]\n"
        "                        [--join-points N] [--beyond F]\n"
        "                        [--step H] [--max-step H] [--json]\n"
        "                        [--param2 NAME --from2 X --to2 X [--curves N]\n"
        "                         [--curve-points N] [--curve-kinds lpc|pd|all]]\n\n"
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
        "At each PD the period-doubled branch is continued too (unless --no-switch), and\n"
        "so are the branches that leave from the ends of a branch (unless --no-end-switch):\n"
        "where a period-2p branch meets the period-p orbit again (at another PD) and no\n"
        "branch computed so far passes there, the period-p orbit is continued from there\n"
        "both ways; a switch at a PD where a branch ended (the far end of its band) is made\n"
        "first, and a branch that runs onto one computed before (--join-points points in a\n"
        "row whose orbits equal that branch's at the same parameter, 1e-6 of the orbit\n"
        "size) ends there, \"joins branch k\"; a branch that leaves the range and folds\n"
        "back within --beyond of it is continued from the range's end inwards (its LPC\n"
        "reported outside the range). Each branch opens with a record of how it was reached.\n"
        "With --param2, each LPC and PD found is then continued in the plane of the two\n"
        "parameters (a minimally augmented system: the orbit and a test function that is zero\n"
        "where M - I or M + I is singular): the curves that bound the bistable windows (LPC)\n"
        "and the period-doubled regions (PD), both ways from the point until they leave the\n"
        "rectangle of the two ranges or close.\n\n"
        "Phase convention: the lag of the deflection behind the drive (x_dit = Ae sin(we t)),\n"
        "90 deg for a free cantilever at resonance, below 90 in the repulsive regime.\n\n"
        "options:\n"
        "  --config FILE      libconfig model file (see config/README.md)\n"
        "  --param NAME       fe (tone 0 frequency, Hz), z (separation, m), ae (tone 0\n"
        "                     amplitude, m), or a live parameter of `afmtwin send param`\n"
        "                     (listed by `afmtwin send --help`) with a force or damping\n"
        "                     effect (e.g. forces.vdw_contact.hamaker_j,\n"
        "                     model.damping_ratio[0])\n"
        "  --from X, --to X   the range; the branch starts at --from (X in the unit of NAME;\n"
        "                     a length or frequency may have a suffix: 11nm, 338kHz)\n"
        "  --start STATE      the start state at drive phase 0 instead of the time\n"
        "                     integration: 2n comma-separated modal values q1..qn,q1'..qn'\n"
        "  --period P         drive periods of the start orbit, 1..%d (default 1)\n"
        "  --settle N         drive periods of time integration before the start (default\n"
        "                     5 Q1 / pi, at least 50: transients down by e^-5)\n"
        "  --max-points N     most points over all branches (default 2000)\n"
        "  --no-switch        stay on the start branch (no period-doubled branches)\n"
        "  --max-branches N   most branches, 1..32 (default 8); starts queued beyond it are\n"
        "                     counted in the summary (not_started)\n"
        "  --max-branch-points N  most points of one branch (default 0: no limit but\n"
        "                     --max-points)\n"
        "  --no-end-switch    nothing from the ends of branches: no continuation from a\n"
        "                     merge, no switch at a PD where a branch ended, no joins, no\n"
        "                     look beyond the range\n"
        "  --join-points N    points in a row on a branch computed before that end a branch\n"
        "                     (default 3)\n"
        "  --beyond F         how far beyond the range's end to follow a branch looking for\n"
        "                     a fold that brings it back, a fraction of the range (default\n"
        "                     0.05; 0: not at all)\n"
        "  --step H           first step (scaled arclength: 1 = the range in the parameter,\n"
        "                     or the start orbit's amplitude in the state; default 0.02)\n"
        "  --max-step H       largest step (default 0.25)\n"
        "  --param2 NAME      a second parameter (names as --param): continue every LPC and\n"
        "                     PD point found in (--param, --param2); its config value must lie\n"
        "                     in [--from2, --to2]\n"
        "  --from2 X, --to2 X the second parameter's range\n"
        "  --curves N         most curves, 1..32 (default 8: the first N LPC / PD points)\n"
        "  --curve-points N   most points per side of a curve (default 400)\n"
        "  --curve-kinds K    which points get a curve: lpc, pd or all (default all); e.g.\n"
        "                     lpc for the edges of the bistable windows alone, those of\n"
        "                     the period-doubled branches' folds included\n"
        "  --json             one JSON object per line: {\"type\": \"point\", \"branch\", "
        "\"param\",\n"
        "                     \"period\", \"stable\", \"multipliers\": [[re, im], ...],\n"
        "                     \"min_deflection_m\", \"max_deflection_m\", \"max_force_n\",\n"
        "                     \"min_force_n\", \"amplitude_m\", \"phase_lag_deg\",\n"
        "                     \"mean_deflection_m\", \"indentation_m\", \"contact_time_s\",\n"
        "                     \"dissipated_energy_j\", \"virial_j\" (of the tip-sample\n"
        "                     force), \"squeeze_dissipated_energy_j\" (the squeeze film's),\n"
        "                     \"contacts\": [{\"min_deflection_m\",\n"
        "                     \"pre_contact_velocity_m_s\", \"max_force_n\", \"t_in_s\",\n"
        "                     \"duration_s\"}], \"residual\", \"iterations\"}; per bifurcation\n"
        "                     {\"type\": \"LPC\"|\"PD\"|\"NS\", \"branch\", \"param\", "
        "\"multiplier\":\n"
        "                     [re, im], \"refined\" (false: not located, at the later point of a "
        "step),\n"
        "                     ...the point's fields}; per branch end {\"type\":\n"
        "                     \"end\", \"branch\", \"parent\", \"period\", \"param\", \"points\",\n"
        "                     \"reason\", \"via\", \"label\", and if it ran onto another\n"
        "                     \"joined\", \"join_dist\", \"join_diff\"}; per branch start,\n"
        "                     before its first point, {\"type\": \"branch\", \"branch\",\n"
        "                     \"parent\", \"period\", \"param\", \"stable\", \"via\":\n"
        "                     \"start\"|\"PD\"|\"end\"|\"fold\", \"via_param\" (the PD, the\n"
        "                     merge or the fold it comes from), \"label\"}; with --param2 per "
        "curve point {\"type\":\n"
        "                     \"curve_point\", \"curve\", \"kind\": \"LPC\"|\"PD\", \"side\",\n"
        "                     \"param\", \"param2\", \"period\", \"stable\" (the other\n"
        "                     multipliers inside the circle), \"multiplier\", \"g\",\n"
        "                     ...the point's fields}, per side's end {\"type\": \"curve_end\",\n"
        "                     \"curve\", \"kind\", \"side\", \"param\", \"param2\", \"points\",\n"
        "                     \"reason\"}; last {\"type\": \"summary\", \"points\", \"branches\",\n"
        "                     \"bifurcations\", \"joins\", \"not_started\", \"maps\", "
        "\"seconds\",\n"
        "                     \"seconds_per_point\",\n"
        "                     and with --param2 \"curves\", \"curve_points\", \"curve_seconds\"}\n"
        "  --help             this text\n\n"
        "Without --json a table (kHz or the parameter's unit, nm, nN). The config's sim.ref_rtol\n"
        "(default 1e-10) is the integration tolerance.\n"
        "Progress on stderr (terminals only).\n"
        "Exit status 0 ok, 1 the start orbit was not found or the integration failed, 2 bad\n"
        "usage or bad input.\n",
        AFM_CONT_MAX_P);
}

#define CONT_MAX_CURVES 32 /* --curves */

/* The unit of a --param name, for the SI suffixes of its range: fe Hz, z and ae m, a live
 * parameter's if it is m or Hz, else none (plain numbers). */
static afmt_unit param_unit(const char *name) {
    if (!name) return AFMT_UNIT_NONE;
    if (!strcmp(name, "fe")) return AFMT_UNIT_HZ;
    if (!strcmp(name, "z") || !strcmp(name, "ae")) return AFMT_UNIT_M;
    size_t len = strcspn(name, "[");
    int n;
    const afm_param_def *d = afm_param_table(&n);
    for (int i = 0; i < n; i++)
        if (strlen(d[i].name) == len && !strncmp(d[i].name, name, len) && d[i].unit)
            return !strcmp(d[i].unit, "m")    ? AFMT_UNIT_M
                   : !strcmp(d[i].unit, "Hz") ? AFMT_UNIT_HZ
                                              : AFMT_UNIT_NONE;
    return AFMT_UNIT_NONE;
}

/* 0 ok, 1 --help, -1 bad usage (said). */
static int cont_parse(int argc, char **argv, cont_cli *o) {
    *o = (cont_cli){.from = NAN,
                    .to = NAN,
                    .from2 = NAN,
                    .to2 = NAN,
                    .period = 1,
                    .curves = 8,
                    .beyond = NAN,
                    .curve_kinds = -1};
    static const afmt_choice curve_kinds_choices[] = {
        {"lpc", CURVES_LPC}, {"pd", CURVES_PD}, {"all", CURVES_ALL}, {NULL, 0}};
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &o->json),
        AFMT_FLAG("--no-switch", &o->no_switch),
        AFMT_FLAG("--no-end-switch", &o->no_end_switch),
        AFMT_INT("--join-points", &o->join_points, 1, 1000, NULL),
        AFMT_INT("--max-branch-points", &o->max_branch_points, 1, 1000000, NULL),
        AFMT_DOUBLE("--beyond", &o->beyond, 0, 1, NULL),
        AFMT_STRING("--config", &o->config),
        AFMT_STRING("--param", &o->param),
        AFMT_STRING("--start", &o->start),
        AFMT_STRING("--param2", &o->param2),
        AFMT_STRING("--from2", &o->from2_s),
        AFMT_STRING("--to2", &o->to2_s),
        AFMT_INT("--curves", &o->curves, 1, CONT_MAX_CURVES, NULL),
        AFMT_INT("--curve-points", &o->curve_points, 1, 100000, NULL),
        AFMT_CHOICE("--curve-kinds", &o->curve_kinds, curve_kinds_choices),
        AFMT_STRING("--from", &o->from_s),
        AFMT_STRING("--to", &o->to_s),
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
    /* the ranges in the parameters' units, known once the names are */
    const struct {
        const char *opt, *s, *param;
        double *v;
    } ranges[] = {{"--from", o->from_s, o->param, &o->from},
                  {"--to", o->to_s, o->param, &o->to},
                  {"--from2", o->from2_s, o->param2, &o->from2},
                  {"--to2", o->to2_s, o->param2, &o->to2}};
    for (size_t i = 0; i < sizeof ranges / sizeof ranges[0]; i++)
        if (ranges[i].s && afmt_opt_si_value("continue", ranges[i].opt, ranges[i].s,
                                             param_unit(ranges[i].param), ranges[i].v))
            return -1;
    if (!o->config || !o->param || isnan(o->from) || isnan(o->to)) {
        fprintf(stderr, "afmtwin continue: --config, --param, --from and --to are required\n");
        return -1;
    }
    if (o->from == o->to) {
        fprintf(stderr, "afmtwin continue: --from and --to must differ\n");
        return -1;
    }
    bool r2 = !isnan(o->from2) || !isnan(o->to2);
    if ((o->param2 || r2) && (!o->param2 || isnan(o->from2) || isnan(o->to2))) {
        fprintf(stderr, "afmtwin continue: --param2 needs --from2 and --to2 (and they need it)\n");
        return -1;
    }
    if (o->curve_kinds >= 0 && !o->param2) {
        fprintf(stderr, "afmtwin continue: --curve-kinds is for --param2\n");
        return -1;
    }
    if (o->param2 && (!strcmp(o->param2, o->param) || o->from2 == o->to2)) {
        fprintf(stderr, "afmtwin continue: --param2 must differ from --param, and --from2 from "
                        "--to2\n");
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

/* An LPC or PD point of the one-parameter run, kept to start its curve from. */
typedef struct {
    afm_cont_kind kind;
    int p;
    double param, y[AFM_CONT_MAX_N];
} cont_event;

typedef struct {
    bool json;
    const char *name, *name2; /* --param, --param2 */
    const char *unit;
    double scale; /* of the table's parameter column */
    cont_event ev[CONT_MAX_CURVES];
    int n_ev, max_ev;
    bool want_lpc, want_pd; /* --curve-kinds */
    int points;             /* records so far, for the progress */
    afmt_progress pg;       /* on stderr, terminals only */
} cont_sink;

static const char *kind_name(afm_cont_kind k) {
    static const char *const names[] = {"point", "LPC", "PD", "NS", "end", "branch"};
    return names[k];
}

static const char *via_name(afm_cont_via v) {
    static const char *const names[] = {"start", "PD", "end", "fold"};
    return names[v];
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
    cJSON_AddNumberToObject(o, "squeeze_dissipated_energy_j", m->squeeze_dissipated_energy_j);
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

/* A two-element array, e.g. a multiplier (re, im). */
static void json_pair(cJSON *o, const char *key, const double *v) {
    cJSON *a = cJSON_AddArrayToObject(o, key);
    cJSON_AddItemToArray(a, cJSON_CreateNumber(v[0]));
    cJSON_AddItemToArray(a, cJSON_CreateNumber(v[1]));
}

/* The orbit's fields of a point record: metrics, multipliers, state, residual, iterations. */
static void json_orbit(cJSON *o, const afm_cont_metrics *met, int n, const double *re,
                       const double *im, const double *y, double residual, int iterations) {
    json_metrics(o, met);
    cJSON *ms = cJSON_AddArrayToObject(o, "multipliers");
    for (int i = 0; i < n; i++) {
        cJSON *e = cJSON_CreateArray();
        cJSON_AddItemToArray(e, cJSON_CreateNumber(re[i]));
        cJSON_AddItemToArray(e, cJSON_CreateNumber(im[i]));
        cJSON_AddItemToArray(ms, e);
    }
    cJSON *st = cJSON_AddArrayToObject(o, "state");
    for (int i = 0; i < n; i++)
        cJSON_AddItemToArray(st, cJSON_CreateNumber(y[i]));
    cJSON_AddNumberToObject(o, "residual", residual);
    cJSON_AddNumberToObject(o, "iterations", iterations);
}

static int cont_emit_record(void *ctx, const afm_cont_record *r) {
    cont_sink *s = ctx;
    const bool wanted =
        (r->kind == AFM_CONT_LPC && s->want_lpc) || (r->kind == AFM_CONT_PD && s->want_pd);
    if (wanted && r->refined && s->n_ev < s->max_ev) {
        cont_event *e = &s->ev[s->n_ev++];
        e->kind = r->kind;
        e->p = r->p;
        e->param = r->param;
        memcpy(e->y, r->y, sizeof(double) * (size_t)r->n_mult);
    }
    if (!s->json) {
        if (r->kind == AFM_CONT_END) {
            char from[32] = ""; /* the start branch has no parent (-1): said nothing of */
            if (r->parent >= 0) snprintf(from, sizeof from, ", from branch %d", r->parent);
            printf("# branch %d (period %d%s) ends after %d points: %s\n", r->branch, r->p, from,
                   r->points, r->stop_reason);
        } else if (r->kind == AFM_CONT_BRANCH)
            printf("# branch %d (period %d): %s\n", r->branch, r->p, r->how);
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
    if (r->kind == AFM_CONT_END || r->kind == AFM_CONT_BRANCH) {
        cJSON_AddStringToObject(o, "via", via_name(r->via));
        cJSON_AddNumberToObject(o, "via_param", r->via_param);
        cJSON_AddStringToObject(o, "label", r->how);
    }
    if (r->kind == AFM_CONT_END) {
        cJSON_AddNumberToObject(o, "points", r->points);
        cJSON_AddStringToObject(o, "reason", r->stop_reason);
        if (r->joined >= 0) {
            cJSON_AddNumberToObject(o, "joined", r->joined);
            cJSON_AddNumberToObject(o, "join_dist", r->join_dist);
            cJSON_AddNumberToObject(o, "join_diff", r->join_diff);
        }
        afmt_json_emit(o);
        fflush(stdout);
        return 0;
    }
    cJSON_AddBoolToObject(o, "stable", r->stable);
    if (r->kind == AFM_CONT_BRANCH) {
        afmt_json_emit(o);
        fflush(stdout);
        return 0;
    }
    if (r->kind != AFM_CONT_POINT) {
        json_pair(o, "multiplier", r->multiplier);
        cJSON_AddBoolToObject(o, "refined", r->refined);
    }
    json_orbit(o, &r->metrics, r->n_mult, r->mult_re, r->mult_im, r->y, r->residual, r->iterations);
    afmt_json_emit(o);
    fflush(stdout);
    return 0;
}

static int curve_emit_record(void *ctx, const afm_cont_curve_record *r) {
    const cont_sink *s = ctx;
    const char *kind = kind_name(r->kind);
    if (!s->json) {
        if (r->end)
            printf("# curve %d (%s, period %d) side %d ends after %d points: %s\n", r->curve, kind,
                   r->p, r->side, r->points, r->stop_reason);
        else
            printf("%-5s %3d %4d %14.8g %14.8g %-8s %12.6f %12.6f %10.5f %12.6f\n", kind, r->curve,
                   r->side, r->param * s->scale, r->param2, r->stable ? "stable" : "unstable",
                   r->metrics.min_deflection_m * 1e9, r->metrics.max_deflection_m * 1e9,
                   r->metrics.max_force_n * 1e9, r->metrics.amplitude_m * 1e9);
        fflush(stdout);
        return 0;
    }
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "type", r->end ? "curve_end" : "curve_point");
    cJSON_AddNumberToObject(o, "curve", r->curve);
    cJSON_AddStringToObject(o, "kind", kind);
    cJSON_AddNumberToObject(o, "side", r->side);
    cJSON_AddStringToObject(o, "param_name", s->name);
    cJSON_AddNumberToObject(o, "param", r->param);
    cJSON_AddStringToObject(o, "param2_name", s->name2);
    cJSON_AddNumberToObject(o, "param2", r->param2);
    cJSON_AddNumberToObject(o, "period", r->p);
    if (r->end) {
        cJSON_AddNumberToObject(o, "points", r->points);
        cJSON_AddStringToObject(o, "reason", r->stop_reason);
    } else {
        cJSON_AddBoolToObject(o, "stable", r->stable);
        json_pair(o, "multiplier", r->multiplier);
        cJSON_AddNumberToObject(o, "g", r->g);
        json_orbit(o, &r->metrics, r->n_mult, r->mult_re, r->mult_im, r->y, r->residual,
                   r->iterations);
    }
    afmt_json_emit(o);
    fflush(stdout);
    return 0;
}

/* The records through the progress line: hidden around the output, updated after. */
static int cont_emit(void *ctx, const afm_cont_record *r) {
    cont_sink *s = ctx;
    s->points++;
    afmt_progress_hide(&s->pg);
    int rc = cont_emit_record(ctx, r);
    afmt_progress_update(&s->pg, "continue: branch %d (period %d), %d records, %s %.8g %s",
                         r->branch, r->p, s->points, s->name, r->param * s->scale, s->unit);
    afmt_progress_redraw(&s->pg);
    return rc;
}

static int curve_emit(void *ctx, const afm_cont_curve_record *r) {
    cont_sink *s = ctx;
    s->points++;
    afmt_progress_hide(&s->pg);
    int rc = curve_emit_record(ctx, r);
    afmt_progress_update(&s->pg, "continue: curve %d side %d, %d records, %s %.6g, %s %.6g",
                         r->curve, r->side, s->points, s->name, r->param, s->name2, r->param2);
    afmt_progress_redraw(&s->pg);
    return rc;
}

/* --param2: the curve of every kept event. Returns the points; *secs the time. */
static int run_curves(const afm_config *cfg, const cont_cli *o, cont_sink *sink, long *maps,
                      double *secs) {
    int points = 0;
    *maps = 0;
    *secs = 0.0;
    if (sink->n_ev == 0)
        fprintf(stderr, "afmtwin continue: no %s point in the range: no curve in %s\n",
                sink->want_lpc && sink->want_pd ? "LPC or PD"
                : sink->want_lpc                ? "LPC"
                                                : "PD",
                o->param2);
    else if (!o->json)
        printf("# %-3s %3s %4s %14s %14s %-8s %12s %12s %10s %12s\n", "kind", "cv", "side",
               sink->unit, o->param2, "", "min x (nm)", "max x (nm)", "max F (nN)", "ampl (nm)");
    for (int k = 0; k < sink->n_ev; k++) {
        const cont_event *e = &sink->ev[k];
        afm_cont_curve_opts co = {.param = o->param,
                                  .param2 = o->param2,
                                  .from = o->from,
                                  .to = o->to,
                                  .from2 = o->from2,
                                  .to2 = o->to2,
                                  .kind = e->kind,
                                  .p = e->p,
                                  .y = e->y,
                                  .lambda = e->param,
                                  .curve = k,
                                  .max_points = o->curve_points};
        afm_cont_summary sum;
        char err[360];
        if (afm_cont_curve_run(cfg, &co, curve_emit, sink, &sum, err, sizeof err) != 0) {
            afm_cont_curve_record r = {.end = true,
                                       .kind = e->kind,
                                       .curve = k,
                                       .p = e->p,
                                       .param = e->param,
                                       .param2 = NAN};
            snprintf(r.stop_reason, sizeof r.stop_reason, "not started: %s", err);
            curve_emit(sink, &r);
        }
        points += sum.points;
        *maps += sum.maps;
        *secs += sum.seconds;
    }
    return points;
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
    if (!bad && o.param2) { /* the second parameter: a name, a range holding its value */
        afm_cont_param p2;
        bad = afm_cont_param_parse(&probe.base, o.param2, &p2, err, sizeof err) ||
              afm_cont_inst_at(&probe.base, &p2, &o.from2, 1, &inst, err, sizeof err) ||
              afm_cont_inst_at(&probe.base, &p2, &o.to2, 1, &inst, err, sizeof err);
        double v2 = bad ? 0.0 : afm_cont_param_value(&probe.base, &p2);
        if (!bad && !(v2 >= fmin(o.from2, o.to2) && v2 <= fmax(o.from2, o.to2))) {
            snprintf(err, sizeof err,
                     "the config's %s = %g is outside [--from2, --to2]: the curves start at "
                     "the one-parameter run's points, which are at the config's %s",
                     o.param2, v2, o.param2);
            bad = 1;
        }
    }
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
                        .no_end_switch = o.no_end_switch,
                        .join_points = o.join_points,
                        .max_branch_points = o.max_branch_points,
                        .beyond = isnan(o.beyond) ? 0.0
                                  : o.beyond > 0  ? o.beyond
                                                  : -1.0,
                        .start_y = o.start ? y0 : NULL,
                        .settle_periods = o.settle,
                        .h0 = o.h0,
                        .h_max = o.h_max};
    static cont_sink sink;
    sink = (cont_sink){.json = o.json,
                       .name = o.param,
                       .name2 = o.param2,
                       .unit = unit,
                       .scale = is_fe ? 1e-3 : 1.0,
                       .max_ev = o.param2 ? o.curves : 0,
                       .want_lpc = o.curve_kinds < 0 || (o.curve_kinds & CURVES_LPC),
                       .want_pd = o.curve_kinds < 0 || (o.curve_kinds & CURVES_PD)};
    if (!o.json) {
        /* the parameter's column by its name and unit ("z (m)", "fe (kHz)"), not the unit
         * alone; and what the lag is, as every other tool's header says */
        char pcol[96];
        snprintf(pcol, sizeof pcol, "%s (%s)", o.param, unit);
        printf("# lag: of the deflection behind the drive (90 deg free at resonance); br: "
               "branch, p: period\n");
        printf("# %-3s %3s %2s %14s %-8s %12s %12s %10s %12s %8s\n", "kind", "br", "p", pcol, "",
               "min x (nm)", "max x (nm)", "max F (nN)", "ampl (nm)", "lag (deg)");
    }
    afm_cont_summary sum;
    afmt_progress_init(&sink.pg);
    if (afm_cont_run(&cfg, &co, cont_emit, &sink, &sum, err, sizeof err) != 0) {
        afmt_progress_end(&sink.pg);
        fprintf(stderr, "afmtwin continue: %s\n", err);
        return 1;
    }
    double per = sum.points > 0 ? sum.seconds / sum.points : 0.0, csecs = 0.0;
    long cmaps = 0;
    int cpoints = o.param2 ? run_curves(&cfg, &o, &sink, &cmaps, &csecs) : 0;
    afmt_progress_end(&sink.pg);
    if (o.json) {
        cJSON *s = cJSON_CreateObject();
        cJSON_AddStringToObject(s, "type", "summary");
        cJSON_AddNumberToObject(s, "points", sum.points);
        cJSON_AddNumberToObject(s, "branches", sum.branches);
        cJSON_AddNumberToObject(s, "bifurcations", sum.bifurcations);
        cJSON_AddNumberToObject(s, "joins", sum.joins);
        cJSON_AddNumberToObject(s, "not_started", sum.not_started);
        cJSON_AddNumberToObject(s, "maps", (double)sum.maps);
        cJSON_AddNumberToObject(s, "flow_steps", (double)sum.flow_steps);
        cJSON_AddNumberToObject(s, "seconds", sum.seconds);
        cJSON_AddNumberToObject(s, "seconds_per_point", per);
        if (o.param2) {
            cJSON_AddNumberToObject(s, "curves", sink.n_ev);
            cJSON_AddNumberToObject(s, "curve_points", cpoints);
            cJSON_AddNumberToObject(s, "curve_maps", (double)cmaps);
            cJSON_AddNumberToObject(s, "curve_seconds", csecs);
        }
        afmt_json_emit(s);
    } else {
        printf("# %d points on %d branches (%d joined one computed before, %d queued not "
               "started: --max-branches), %d bifurcations, %ld Newton maps, %.2f s (%.3f s per "
               "point)\n",
               sum.points, sum.branches, sum.joins, sum.not_started, sum.bifurcations, sum.maps,
               sum.seconds, per);
        if (o.param2)
            printf("# %d curves, %d points, %ld Newton maps, %.2f s\n", sink.n_ev, cpoints, cmaps,
                   csecs);
    }
    return 0;
}
