/* SPDX-License-Identifier: MIT */
/* cmd_sweep.c -- `afmtwin sweep`: stepwise frequency sweep, each step dwelt to steady state,
 * then the orbit's periodicity, extrema, contacts and harmonics (thesis ch. 4, App. C.4).
 *
 * One simulator runs the whole sweep: the state carries over from step to step and tone 0
 * changes frequency phase-continuously, as in the thesis's time-integration sweeps (App.
 * C.4) and the stepwise experiments, so a forward sweep can climb a high-amplitude branch
 * that a start from rest would miss. */
#include "afmtwin_cmds.h"
#include "opts.h"
#include "json_out.h"

#include "config/afm_config.h"
#include "estimators/afm_cycle.h"
#include "forces/afm_force.h"
#include "estimators/afm_lockin.h"
#include "beam/afm_model.h"
#include "estimators/afm_orbit.h"
#include "runner/afm_twin.h"
#include "integrators/afm_sim.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define DEFAULT_MAX_PERIODS 10000
#define DEFAULT_TOL 1e-6
#define MAX_STEPS 1000000

static const int default_harmonics[] = {1, 6, 17};

typedef struct {
    const char *config;
    double from_hz, to_hz, step_hz; /* step NAN when not given */
    double ae_m, z_m;               /* NAN: keep the config's */
    int ks[AFM_MAX_HARMONICS], nk;  /* nk 0: config's list, else default_harmonics */
    int integrator;                 /* -1: config's */
    int scheme;                     /* -1: config's (AFM_RT_SCHEME_*) */
    int max_periods;
    double tol;
    bool json;
} sweep_opts;

static void sweep_usage(FILE *f) {
    fprintf(
        f,
        "usage: afmtwin sweep --config FILE --from HZ --to HZ --step HZ [--ae M] [--z M]\n"
        "                     [--harmonics K,K,...] [--integrator rt|reference|arkode-erk]\n"
        "                     [--scheme accurate|fast]\n"
        "                     [--max-periods N] [--tol X] [--json]\n\n"
        "Stepwise excitation-frequency sweep, as in the thesis's experiments: forward when\n"
        "--to > --from, backward otherwise. One simulation runs the whole sweep, so the\n"
        "cantilever state carries over from step to step and the drive frequency changes\n"
        "phase-continuously. At each step the drive is held until the orbit repeats itself\n"
        "(steady state, or --max-periods), then the last whole orbit is analysed:\n"
        "  periodicity   p = 1 harmonic, 2 after period doubling, ... up to %d; 0 = no\n"
        "                steady state within --max-periods (analysed over the best p)\n"
        "  deflection    min and max tip displacement xr (m), negative towards the sample\n"
        "  force         max total tip-sample force (N)\n"
        "  contacts      each contact moment of the p-period orbit (gap d = xr cos(alpha) + Z\n"
        "                below a0): min xr, tip velocity as the gap crosses a0 inwards (the\n"
        "                pre-contact velocity of thesis Table 4.1), max force\n"
        "  harmonics     amplitude and phase of xr and of the force at k fe: the phase phi_k\n"
        "                of A_k cos(k we t + phi_k), t from a drive-phase-0 instant (x_dit =\n"
        "                Ae sin(we t)), and the phase difference of thesis eq. E.12-E.13,\n"
        "                mod(k (180 - phi_1) + phi_k, 360) deg (Table E.2)\n\n"
        "options:\n"
        "  --config FILE       libconfig model file (see config/README.md)\n"
        "  --from HZ           first excitation frequency (tone 0), 0 < HZ < rate / 2\n"
        "  --to HZ             last excitation frequency; included when it lies on the grid\n"
        "                      from + i step (--from X --to X is a single point)\n"
        "  --step HZ           frequency increment > 0 (the sign follows --from/--to);\n"
        "                      may be omitted for a single point\n"
        "  --ae M              excitation amplitude of tone 0 (m), 0 <= M <= 1e-6;\n"
        "                      default the config's\n"
        "  --scheme NAME       the rt integrator's scheme: accurate (the default offline: the\n"
        "                      tip force cubic Hermite in time, CVODE's steady state) or fast\n"
        "                      (the daemon's fallback, second order; docs/numerics.md)\n"
        "  --z M               tip-sample separation Z (m), 0 <= M <= 1e-3; default the\n"
        "                      config's\n"
        "  --harmonics LIST    harmonic numbers k >= 1, comma-separated, at most %d, with\n"
        "                      k fe below rate / 2; default the config's sim.harmonics, or\n"
        "                      1,6,17\n"
        "  --integrator NAME   rt (real-time scheme), reference (CVODE BDF) or arkode-erk;\n"
        "                      default the config's\n"
        "  --max-periods N     most drive periods dwelt per step before giving up on a\n"
        "                      steady state, >= 2 (default %d)\n"
        "  --tol X             steady state: the orbit over p periods differs from the one\n"
        "                      before by less than X times the half peak-to-peak deflection,\n"
        "                      0 < X < 1 (default %g), judged on the samples out of contact.\n"
        "                      A slowly decaying transient can still be up to ~Q/pi times\n"
        "                      that far from the exact orbit. An integrator whose orbit is\n"
        "                      not periodic to X (rt in contact jitters by ~1e-4 at the\n"
        "                      time of writing) runs to --max-periods: loosen --tol or use\n"
        "                      reference\n"
        "  --json              one JSON object per step and line: fe_hz, periodicity,\n"
        "                      settle_periods, settled, orbit_change, analysed_periods,\n"
        "                      contacts_truncated (only when true: > %d contacts, or one\n"
        "                      ran past the samples),\n"
        "                      min_deflection_m, max_deflection_m, max_force_n, contacts\n"
        "                      [{min_deflection_m, pre_contact_velocity_m_s, max_force_n}],\n"
        "                      harmonics [{k, deflection_amplitude_m, deflection_phase_deg,\n"
        "                      phase_lag_deg (-(deflection_phase_deg + 90): the lag behind\n"
        "                      the drive, as lockin.phase_deg),\n"
        "                      force_amplitude_n, force_phase_deg, phase_diff_deg}];\n"
        "                      phases in degrees, (-180, 180], phase_diff_deg in [0, 360);\n"
        "                      lockin {amplitude_m, phase_deg}: a lock-in at fe on xr, run\n"
        "                      on every sample of the sweep (not reset between steps), read\n"
        "                      at the end of the dwell; config group lockin (time constant,\n"
        "                      order); phase_deg is the lag of xr behind the drive (90 at a\n"
        "                      free resonance, below 90 when repulsive);\n"
        "                      cycle {peak_force_n, min_deflection_m, indentation_m,\n"
        "                      contact_time_s, pre_contact_velocity_m_s (null without\n"
        "                      contact), dissipated_energy_j (-int F v dt), mean_deflection_m,\n"
        "                      squeeze_dissipated_energy_j} over the last whole drive period\n"
        "                      of the dwell; forces and energies are the tip-sample force's\n"
        "                      (vdW/DMT, viscoelastic, capillary, electrostatic), the squeeze\n"
        "                      film's dissipation apart (squeeze_dissipated_energy_j)\n"
        "  --help              this text\n\n" AFMT_OPT_SI_HELP
        "Without --json a readable table. A progress line goes to stderr (terminals only)\n"
        "when the sweep takes more than a second. Exit status 0 ok, 1 simulation failure,\n"
        "2 bad usage or bad input.\n",
        AFM_ORBIT_MAX_P, AFM_MAX_HARMONICS, DEFAULT_MAX_PERIODS, DEFAULT_TOL,
        AFM_ORBIT_MAX_CONTACTS);
}

/* --harmonics K[,K..] into o->ks, o->nk (its own messages: which part is wrong). */
static int parse_harmonics(const char *s, void *dest) {
    sweep_opts *o = dest;
    o->nk = 0;
    const char *p = s;
    while (*p) {
        char *end;
        errno = 0;
        long k = strtol(p, &end, 10);
        if (end == p || errno == ERANGE || k < 1 || k > 100000 || (*end != ',' && *end != '\0')) {
            fprintf(stderr,
                    "afmtwin sweep: --harmonics '%s': expected integers >= 1 separated by "
                    "commas\n",
                    s);
            return AFMT_OPT_REPORTED;
        }
        if (o->nk == AFM_MAX_HARMONICS) {
            fprintf(stderr, "afmtwin sweep: --harmonics '%s': at most %d harmonics\n", s,
                    AFM_MAX_HARMONICS);
            return AFMT_OPT_REPORTED;
        }
        o->ks[o->nk++] = (int)k;
        p = *end == ',' ? end + 1 : end;
        if (*end == ',' && *p == '\0') {
            fprintf(stderr, "afmtwin sweep: --harmonics '%s': trailing comma\n", s);
            return AFMT_OPT_REPORTED;
        }
    }
    if (o->nk == 0) {
        fprintf(stderr, "afmtwin sweep: --harmonics is empty\n");
        return AFMT_OPT_REPORTED;
    }
    return 0;
}

/* 0 ok, 1 --help printed, -1 bad usage (message printed). */
static int parse_args(int argc, char **argv, sweep_opts *o) {
    memset(o, 0, sizeof *o);
    o->from_hz = o->to_hz = o->step_hz = o->ae_m = o->z_m = NAN;
    o->integrator = -1;
    o->scheme = -1;
    o->max_periods = DEFAULT_MAX_PERIODS;
    o->tol = DEFAULT_TOL;
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &o->json),
        AFMT_STRING("--config", &o->config),
        AFMT_FREQ("--from", &o->from_hz, 0, 0, NULL),
        AFMT_FREQ("--to", &o->to_hz, 0, 0, NULL),
        AFMT_FREQ("--step", &o->step_hz, 0, 0, NULL),
        AFMT_LENGTH("--ae", &o->ae_m, 0, 0, NULL),
        AFMT_LENGTH("--z", &o->z_m, 0, 0, NULL),
        AFMT_FN("--harmonics", parse_harmonics, o, NULL),
        AFMT_CHOICE("--integrator", &o->integrator, afmt_integrator_choices),
        AFMT_CHOICE("--scheme", &o->scheme, afmt_scheme_choices),
        AFMT_INT("--max-periods", &o->max_periods, 2, 100000000, NULL),
        AFMT_DOUBLE("--tol", &o->tol, 0, 0, NULL),
        AFMT_OPTS_END,
    };
    int rc = afmt_opts_parse("sweep", opts, argc, argv, 1);
    if (rc) return rc == AFMT_OPTS_HELP ? 1 : -1;
    bool have_from = !isnan(o->from_hz), have_to = !isnan(o->to_hz); /* only finite values */
    if (!o->config) {
        fprintf(stderr, "afmtwin sweep: --config FILE is required\n");
        return -1;
    }
    if (!have_from || !have_to) {
        fprintf(stderr, "afmtwin sweep: --from and --to are required\n");
        return -1;
    }
    if (o->from_hz <= 0 || o->to_hz <= 0) {
        fprintf(stderr, "afmtwin sweep: frequencies must be > 0 Hz (got --from %g --to %g)\n",
                o->from_hz, o->to_hz);
        return -1;
    }
    if (o->from_hz != o->to_hz && isnan(o->step_hz)) {
        fprintf(stderr, "afmtwin sweep: --step is required when --from and --to differ\n");
        return -1;
    }
    if (!isnan(o->step_hz) && o->step_hz <= 0) {
        fprintf(stderr,
                "afmtwin sweep: --step must be > 0 Hz (got %g); the direction follows "
                "--from and --to\n",
                o->step_hz);
        return -1;
    }
    if (!isnan(o->ae_m) && (o->ae_m < 0 || o->ae_m > 1e-6)) {
        fprintf(stderr, "afmtwin sweep: --ae must be in 0..1e-6 m (got %g)\n", o->ae_m);
        return -1;
    }
    if (!isnan(o->z_m) && (o->z_m < 0 || o->z_m > 1e-3)) {
        fprintf(stderr, "afmtwin sweep: --z must be in 0..1e-3 m (got %g)\n", o->z_m);
        return -1;
    }
    if (!(o->tol > 0 && o->tol < 1)) {
        fprintf(stderr, "afmtwin sweep: --tol must be in (0, 1) (got %g)\n", o->tol);
        return -1;
    }
    return 0;
}

/* Frequency of step i (exact multiples of the step, no accumulated rounding). */
static double step_freq(const sweep_opts *o, int i) {
    if (i == 0) return o->from_hz;
    return o->to_hz >= o->from_hz ? o->from_hz + (double)i * o->step_hz
                                  : o->from_hz - (double)i * o->step_hz;
}

/* Streaming estimators fed with every sample of the sweep (afm_sweep.on_samples). */
typedef struct {
    afm_lockin lockin;
    afm_cycle cycle;
} estimators;

static void on_samples(void *ctx, const afm_sim *s, const afm_sample *smp, int n) {
    estimators *e = ctx;
    const afm_drive *d = afm_sim_drive(s);
    for (int i = 0; i < n; i++) {
        double th = afm_drive_phase(d, 0, smp[i].t_s);
        /* both refuse only non-finite values, which the simulator never returns */
        afm_lockin_push(&e->lockin, smp[i].x_m, th);
        afm_cycle_push_ev(&e->cycle, &smp[i], th, afm_sim_events_at(s, smp[i].t_s));
    }
}

static void add_estimators_json(cJSON *o, const estimators *e) {
    cJSON *l = cJSON_AddObjectToObject(o, "lockin");
    cJSON_AddNumberToObject(l, "amplitude_m", afm_lockin_amplitude(&e->lockin));
    cJSON_AddNumberToObject(l, "phase_deg", afm_lockin_phase_deg(&e->lockin));
    if (e->cycle.periods < 1) {
        cJSON_AddNullToObject(o, "cycle");
        return;
    }
    const afm_cycle_metrics *m = &e->cycle.out;
    cJSON *c = cJSON_AddObjectToObject(o, "cycle");
    cJSON_AddNumberToObject(c, "peak_force_n", m->peak_force_n);
    cJSON_AddNumberToObject(c, "min_deflection_m", m->min_deflection_m);
    cJSON_AddNumberToObject(c, "indentation_m", m->indentation_m);
    cJSON_AddNumberToObject(c, "contact_time_s", m->contact_time_s);
    if (m->n_contacts > 0)
        cJSON_AddNumberToObject(c, "pre_contact_velocity_m_s", m->pre_contact_velocity_m_s);
    else
        cJSON_AddNullToObject(c, "pre_contact_velocity_m_s");
    cJSON_AddNumberToObject(c, "dissipated_energy_j", m->dissipated_energy_j);
    cJSON_AddNumberToObject(c, "mean_deflection_m", m->mean_deflection_m);
    cJSON_AddNumberToObject(c, "squeeze_dissipated_energy_j", m->squeeze_dissipated_energy_j);
}

/* What made the records: the integrator and its scheme (set once the twin exists). */
static const char *json_integrator = "-", *json_scheme = "-";

static cJSON *orbit_json(const afm_orbit *ob, const afm_orbit_settler *st, bool settled) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "fe_hz", ob->fe_hz);
    cJSON_AddStringToObject(o, "integrator", json_integrator);
    cJSON_AddStringToObject(o, "scheme", json_scheme);
    cJSON_AddNumberToObject(o, "periodicity", settled ? st->p : 0);
    cJSON_AddNumberToObject(o, "settle_periods", st->periods);
    cJSON_AddBoolToObject(o, "settled", settled);
    afmt_json_num(o, "orbit_change", st->change_rel);
    cJSON_AddNumberToObject(o, "analysed_periods", ob->p);
    cJSON_AddNumberToObject(o, "min_deflection_m", ob->min_deflection_m);
    cJSON_AddNumberToObject(o, "max_deflection_m", ob->max_deflection_m);
    cJSON_AddNumberToObject(o, "max_force_n", ob->max_force_n);
    if (ob->contacts_truncated) cJSON_AddBoolToObject(o, "contacts_truncated", true);
    cJSON *cs = cJSON_AddArrayToObject(o, "contacts");
    for (int i = 0; i < ob->n_contacts; i++) {
        cJSON *c = cJSON_CreateObject();
        cJSON_AddNumberToObject(c, "min_deflection_m", ob->contacts[i].min_deflection_m);
        cJSON_AddNumberToObject(c, "pre_contact_velocity_m_s",
                                ob->contacts[i].pre_contact_velocity_m_s);
        cJSON_AddNumberToObject(c, "max_force_n", ob->contacts[i].max_force_n);
        cJSON_AddItemToArray(cs, c);
    }
    cJSON *hs = cJSON_AddArrayToObject(o, "harmonics");
    for (int i = 0; i < ob->n_harmonics; i++) {
        const afm_orbit_harmonic *h = &ob->harmonics[i];
        cJSON *c = cJSON_CreateObject();
        cJSON_AddNumberToObject(c, "k", h->k);
        cJSON_AddNumberToObject(c, "deflection_amplitude_m", h->x_amp_m);
        cJSON_AddNumberToObject(c, "deflection_phase_deg", h->x_phase_deg);
        cJSON_AddNumberToObject(c, "phase_lag_deg", afm_orbit_lag_deg(h->x_phase_deg));
        cJSON_AddNumberToObject(c, "force_amplitude_n", h->f_amp_n);
        cJSON_AddNumberToObject(c, "force_phase_deg", h->f_phase_deg);
        cJSON_AddNumberToObject(c, "phase_diff_deg", h->phase_diff_deg);
        cJSON_AddItemToArray(hs, c);
    }
    return o;
}

static int print_json_line(const afm_orbit *ob, const afm_orbit_settler *st, bool settled,
                           const estimators *e) {
    cJSON *o = orbit_json(ob, st, settled);
    if (o) add_estimators_json(o, e);
    int rc = afmt_json_emit(o);
    fflush(stdout);
    return rc;
}

static void print_text_estimators(const estimators *e) {
    printf("    lock-in: %.5e m  lag %8.3f deg", afm_lockin_amplitude(&e->lockin),
           afm_lockin_phase_deg(&e->lockin));
    if (e->cycle.periods > 0) {
        const afm_cycle_metrics *m = &e->cycle.out;
        printf("   last period: indentation %.4f nm, contact %.4e s, dissipated %.4e J "
               "(squeeze film %.4e J), mean xr %.5f nm",
               m->indentation_m * 1e9, m->contact_time_s, m->dissipated_energy_j,
               m->squeeze_dissipated_energy_j, m->mean_deflection_m * 1e9);
    }
    printf("\n");
    fflush(stdout);
}

static void print_text_step(const afm_orbit *ob, const afm_orbit_settler *st, bool settled) {
    char p[16];
    if (settled)
        snprintf(p, sizeof p, "%d", st->p);
    else
        snprintf(p, sizeof p, "- (%d)", ob->p);
    printf("%-12.3f %-7s %8d %10.2e %12.5f %12.5f %12.5e %3d\n", ob->fe_hz, p, st->periods,
           st->change_rel, ob->min_deflection_m * 1e9, ob->max_deflection_m * 1e9, ob->max_force_n,
           ob->n_contacts);
    for (int i = 0; i < ob->n_contacts; i++)
        printf("    contact %d: min(xr) %.5f nm, pre-contact velocity %.5e m/s, max(Fts) "
               "%.5e N\n",
               i + 1, ob->contacts[i].min_deflection_m * 1e9,
               ob->contacts[i].pre_contact_velocity_m_s, ob->contacts[i].max_force_n);
    if (ob->contacts_truncated) printf("    (contact list truncated)\n");
    for (int i = 0; i < ob->n_harmonics; i++) {
        const afm_orbit_harmonic *h = &ob->harmonics[i];
        printf("    k %2d: |xr| %.5e m  phase %8.3f deg  |F| %.5e N  phase %8.3f deg  "
               "dphi %7.3f deg  lag %8.3f deg\n",
               h->k, h->x_amp_m, h->x_phase_deg, h->f_amp_n, h->f_phase_deg, h->phase_diff_deg,
               afm_orbit_lag_deg(h->x_phase_deg));
    }
    fflush(stdout);
}

/* The progress line (opts.h afmt_progress: stderr, terminals only) and where the sweep is. */
typedef struct {
    afmt_progress p;
    int step, n_steps;
} sweep_progress;

static void on_period(void *ctx, const afm_orbit_settler *st, double fe_hz) {
    sweep_progress *pg = ctx;
    afmt_progress_update(&pg->p, "sweep: step %d/%d  fe %.3f Hz  period %d  change %.1e",
                         pg->step + 1, pg->n_steps, fe_hz, st->periods, st->change_rel);
}

int afm_cmd_sweep(int argc, char **argv) {
    sweep_opts o;
    int rc = afmt_opts_done("sweep", parse_args(argc, argv, &o), sweep_usage);
    if (rc >= 0) return rc;

    static afm_config cfg;
    char err[AFM_ERR_LEN];
    if (afmt_config_load("sweep", o.config, &cfg)) return 2;
    double fs = cfg.sim.sample_rate_hz, f_hi = fmax(o.from_hz, o.to_hz);
    double f_lo = fmin(o.from_hz, o.to_hz);
    if (f_hi >= 0.5 * fs) {
        fprintf(stderr, "afmtwin sweep: frequencies must be below half the sample rate, %g Hz\n",
                0.5 * fs);
        return 2;
    }
    int n_steps = 1;
    if (o.from_hz != o.to_hz) {
        double n = floor(fabs(o.to_hz - o.from_hz) / o.step_hz * (1.0 + 1e-12)) + 1.0;
        if (n > MAX_STEPS) {
            fprintf(stderr, "afmtwin sweep: %.0f steps; at most %d\n", n, MAX_STEPS);
            return 2;
        }
        n_steps = (int)n;
    }
    if (o.nk == 0) {
        if (cfg.sim.n_harmonics > 0) {
            o.nk = cfg.sim.n_harmonics;
            memcpy(o.ks, cfg.sim.harmonics, (size_t)o.nk * sizeof o.ks[0]);
        } else {
            o.nk = (int)(sizeof default_harmonics / sizeof default_harmonics[0]);
            memcpy(o.ks, default_harmonics, sizeof default_harmonics);
        }
    }
    for (int j = 0; j < o.nk; j++)
        if ((double)o.ks[j] * f_hi >= 0.5 * fs) {
            fprintf(stderr,
                    "afmtwin sweep: harmonic %d at %g Hz is not below half the sample rate, "
                    "%g Hz\n",
                    o.ks[j], o.ks[j] * f_hi, 0.5 * fs);
            return 2;
        }
    if (!isnan(o.ae_m)) cfg.drive.tones[0].amplitude_m = o.ae_m;
    if (!isnan(o.z_m)) cfg.drive.separation_m = o.z_m;
    if (o.integrator >= 0) cfg.sim.integrator = (afm_integrator_kind)o.integrator;
    if (o.scheme >= 0) cfg.sim.rt_scheme = (afm_rt_scheme_kind)o.scheme;
    cfg.drive.tones[0].frequency_hz = o.from_hz;
    if (afm_config_validate(&cfg, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin sweep: %s\n", err);
        return 2;
    }

    afm_sim *sim = afm_twin_create(&cfg, NULL, NULL, err, sizeof err);
    if (!sim) {
        fprintf(stderr, "afmtwin sweep: %s\n", err);
        return 1;
    }
    json_integrator = afm_sim_integrator_name(sim);
    json_scheme = afm_sim_scheme_name(sim);
    afm_sweep sw;
    if (afm_sweep_init(&sw, fs, f_lo, o.tol, o.max_periods, o.ks, o.nk, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin sweep: %s\n", err);
        afm_sim_destroy(&sim);
        return 1;
    }
    /* the per-period metrics from the integrator's record (afmt_step_events) */
    afm_step_events *ev_ring = afmt_step_events_ring(sim, sw.cap);

    double ae = cfg.drive.tones[0].amplitude_m;
    double xc = afm_force_contact_x(afm_sim_forces(sim), afm_sim_separation(sim));
    /* lock-in: the config's; a time constant of 0 (older configs) means 10 periods of the
     * lowest sweep frequency, order 4 if unset */
    static estimators est;
    afm_cfg_lockin lk = cfg.lockin;
    if (lk.time_constant_s == 0) lk.time_constant_s = 10.0 / f_lo;
    if (lk.order == 0) lk.order = 4;
    if (afm_lockin_init(&est.lockin, &lk, afm_sim_dt(sim), err, sizeof err) != 0 ||
        afm_cycle_init(&est.cycle, xc, afm_sim_forces(sim)->cos_alpha, err, sizeof err) != 0 ||
        afm_cycle_set_forces(&est.cycle, afm_sim_forces(sim), afm_sim_separation(sim)) != 0) {
        fprintf(stderr, "afmtwin sweep: %s\n", err);
        afm_sweep_destroy(&sw);
        afm_sim_destroy(&sim);
        free(ev_ring);
        return 2;
    }
    if (!o.json) {
        printf("# afmtwin sweep %s: integrator %s (scheme %s), Ae %.4g m, Z %.4g m, contact at "
               "xr < %.5g nm, tol %.1e, max %d periods\n",
               o.config, afm_sim_integrator_name(sim), afm_sim_scheme_name(sim), ae,
               afm_sim_separation(sim), xc * 1e9, o.tol, o.max_periods);
        printf("# phases: phi_k of A_k cos(k theta + phi_k) (thesis App. E.4); lag = -(phi + 90): "
               "the lag of the deflection behind the drive, 90 deg free at resonance (the "
               "lock-in's)\n");
        printf("%-12s %-7s %8s %10s %12s %12s %12s %3s\n", "# fe_hz", "p", "periods", "change",
               "min_xr_nm", "max_xr_nm", "max_F_N", "nc");
    }

    sweep_progress pg = {.n_steps = n_steps};
    afmt_progress_init(&pg.p);
    sw.on_period = on_period;
    sw.on_period_ctx = &pg;
    sw.on_samples = on_samples;
    sw.on_samples_ctx = &est;
    int status = 0;
    static afm_orbit ob;
    for (int i = 0; i < n_steps && status == 0; i++) {
        double fe = step_freq(&o, i);
        pg.step = i;
        int settled = afm_sweep_step(&sw, sim, fe, ae, &ob, err, sizeof err);
        if (settled < 0) {
            afmt_progress_end(&pg.p);
            fprintf(stderr, "afmtwin sweep: %s\n", err);
            status = 1;
            break;
        }
        afmt_progress_hide(&pg.p); /* stdout on the same terminal: the record, then the line */
        if (o.json) {
            if (print_json_line(&ob, &sw.st, settled == 1, &est) != 0) {
                fprintf(stderr, "afmtwin sweep: out of memory writing JSON\n");
                status = 1;
            }
        } else {
            print_text_step(&ob, &sw.st, settled == 1);
            print_text_estimators(&est);
        }
        afmt_progress_redraw(&pg.p);
    }
    afmt_progress_end(&pg.p);
    afm_sweep_destroy(&sw);
    afm_sim_destroy(&sim);
    free(ev_ring);
    return status;
}
