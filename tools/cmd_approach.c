/* SPDX-License-Identifier: MIT */
/* cmd_approach.c -- `afmtwin approach`: the approach (and retract) curve, amplitude, phase,
 * harmonics and per-period forces against the tip-sample separation Z.
 *
 * One simulation runs the whole curve: the state carries over from step to step, as when a
 * Z piezo moves in steps on the instrument, so the curve follows the branch it is on and
 * an approach followed by a retract shows the hysteresis of a bistable region. At each Z
 * the orbit is dwelt to steady state (afm_sweep_dwell, as `afmtwin sweep`), then N more
 * whole drive periods are run and analysed: harmonics by the per-period DFT (afm_harm),
 * the lock-in, and the per-period metrics of afm_cycle plus the mean force, the largest
 * attractive force and the virial (approach_extra below), all averaged over the N periods.
 *
 * Phases are the lag of the deflection behind the drive (x_dit = Ae sin(we t)): 90 deg
 * for a free cantilever driven at resonance, below 90 in the repulsive regime, above in
 * the attractive one; harmonic k's lag is that of A_k sin(k we t - lag_k). */
#include "afmtwin_cmds.h"
#include "opts.h"

#include "config/afm_config.h"
#include "estimators/afm_cycle.h"
#include "forces/afm_force.h"
#include "estimators/afm_harm.h"
#include "estimators/afm_lockin.h"
#include "estimators/afm_orbit.h"
#include "integrators/afm_sim.h"
#include "runner/afm_twin.h"
#include "runner/afm_a0.h"
#include "runner/afm_fm.h"
#include "json_out.h"
#include "lcm_tool.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define DEFAULT_MAX_PERIODS 10000
#define DEFAULT_ANALYSE 16
#define DEFAULT_K 8
#define DEFAULT_TOL 1e-6
#define MAX_ANALYSE 4096
#define MAX_STEPS 100000
#define TWO_PI 6.283185307179586476925286766559

typedef struct {
    const char *config;
    double from_m, to_m, step_m; /* Z */
    double fe_hz, ae_m;          /* NAN: the config's tone 0 */
    bool retract, json;
    int max_periods, analyse, k_max, integrator, scheme;
    double tol;
    double rate_m_s;  /* > 0: Z ramped continuously at this speed instead of stepped */
    int fm;           /* --mode: 0 am (default), 1 fm */
    double fm_tol_hz; /* fm: settled when the mean frequency moves less than this per window */
    int fm_drive;     /* fm: AFM_FM_DRIVE_PLL or _SELF (-1: the config's fm.drive) */
} approach_opts;

static void approach_usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin approach --config FILE --from Z --to Z --step DZ [--retract]\n"
            "                        [--periods N] [--analyse N] [--harmonics K] [--fe HZ]\n"
            "                        [--ae M] [--integrator rt|reference|arkode-erk]\n"
            "                        [--scheme accurate|fast]\n"
            "                        [--tol X] [--rate M_S] [--mode am|fm] [--fm-tol HZ]\n"
            "                        [--fm-drive pll|self]\n"
            "                        [--json]\n\n"
            "Approach curve: the tip-sample separation Z (m) goes from --from to --to in steps\n"
            "of --step (towards the sample when --to < --from), and with --retract back again.\n"
            "One simulation runs the whole curve, so the state carries over from step to step\n"
            "(a bistable region shows its hysteresis between approach and retract). At each Z\n"
            "the orbit is dwelt until it repeats (as `afmtwin sweep`: at most --periods drive\n"
            "periods, tolerance --tol), then --analyse N more whole periods are run and\n"
            "analysed (and at least 12 lock-in time constants, for its filter to settle),\n"
            "each quantity the mean over the last N periods:\n"
            "  amplitude, phase  harmonic 1 of the deflection by the DFT over each period, and\n"
            "                    by the lock-in (config group lockin)\n"
            "  harmonics         amplitude and phase lag of harmonics 1..K\n"
            "  forces            peak repulsive (max) and attractive (min) tip-sample force,\n"
            "                    the mean force, indentation, contact time, the energy the\n"
            "                    tip-sample forces dissipate per period (-int F v dt) and the\n"
            "                    virial (1/T) int F x dt; tip-sample: vdW/DMT, viscoelastic,\n"
            "                    capillary, electrostatic, not the squeeze film (air between\n"
            "                    the beam and the sample), whose own dissipation per period\n"
            "                    is reported beside it (Esq_eV, squeeze_dissipated_energy_j)\n"
            "  periodicity       of the settled orbit (0: not settled within --periods)\n"
            "The regime of a step is attractive when the mean tip-sample force is below zero,\n"
            "repulsive when above. Each change of regime is reported as a jump, placed where\n"
            "the amplitude branch changes: between the two steps of the largest step change\n"
            "of the harmonic-1 phasor (A, lag) from the previous change of regime to the next,\n"
            "if it is over twice the changes of the steps beside it (sharp), else at the\n"
            "change of regime itself (a smooth crossover). On a retract the lever may stay on\n"
            "the high-amplitude branch a few steps after its mean force turned attractive.\n"
            "The records of a pass (approach, retract) are written when the pass ends.\n\n"
            "Phase convention: the lag of the deflection behind the drive (x_dit = Ae sin(we t)),\n"
            "90 deg for a free cantilever at resonance, below 90 in the repulsive regime.\n\n"
            "options:\n"
            "  --config FILE      libconfig model file (see config/README.md)\n"
            "  --from Z, --to Z   first and last separation (m), 0 <= Z <= 1e-3\n"
            "  --step DZ          separation increment > 0 (m); the sign follows --from/--to\n"
            "  --retract          after the approach, back from --to to --from\n"
            "  --periods N        most drive periods dwelt per step (default %d)\n"
            "  --analyse N        whole periods analysed per step, 1..%d (default %d)\n"
            "  --harmonics K      harmonics 1..K reported, 1..%d (default %d)\n"
            "  --fe HZ, --ae M    tone 0's frequency and amplitude; default the config's\n"
            "  --integrator NAME  rt, reference (CVODE BDF) or arkode-erk; default the "
            "config's\n" AFMT_OPT_SCHEME_HELP
            "  --tol X            steady-state tolerance as in `afmtwin sweep` (default %g)\n"
            "  --rate M_S         ramp Z continuously at M_S m/s (as the daemon's setpoint\n"
            "                     --ramp: a new Z every 64 samples) instead of stepping and\n"
            "                     dwelling: a record each --step of Z, the means over the last\n"
            "                     N periods of the ramp (settled false, periodicity 0); the\n"
            "                     first point is dwelt to steady state\n"
            "  --mode am|fm       am (default): tone 0 fixed, as above. fm: frequency\n"
            "                     modulation (runner/afm_fm.h, config group fm): a PLL on the\n"
            "                     lock-in phase moves tone 0's frequency (phase-continuous, once\n"
            "                     per fm.update_samples) to hold the lag at\n"
            "                     fm.phase_setpoint_deg (90: resonance), a PI moves its drive to\n"
            "                     hold the amplitude at fm.amplitude_setpoint_m (0: the amplitude\n"
            "                     tone 0's drive gives at the free resonance). The loops first\n"
            "                     lock at Z 1 um starting from --fe (default: mode 1's resonance)\n"
            "                     and the frequency found there is the free resonance f_free;\n"
            "                     at each Z they run in windows of the lock time until locked,\n"
            "                     the mean frequency moves less than --fm-tol and the amplitude\n"
            "                     is within 1e-4 of its set-point (at most --periods drive\n"
            "                     periods or 10 windows, the more). Per step:\n"
            "                     frequency_shift_hz = f - f_free (the mean over the last\n"
            "                     window), frequency_hz, drive_amplitude_m (the\n"
            "                     dissipation channel), amplitude_m and phase_error_deg (lock-in\n"
            "                     lag less the set-point), lag_deg, locked, lock_state\n"
            "                     (acquiring, locked, lost), settled, and the per-period forces\n"
            "                     as in am mode (means over the last --analyse periods)\n"
            "  --fm-tol HZ        fm: frequency settling tolerance per window (default 1e-3)\n"
            "  --fm-drive pll|self fm: what drives tone 0 (default: the config's fm.drive,\n"
            "                     pll): the PLL's NCO at the phase set-point, or self-excited:\n"
            "                     the deflection phase-shifted by fm.phase_setpoint_deg (a\n"
            "                     quarter-period delay line), amplitude-limited by the\n"
            "                     amplitude controller, its frequency counted\n"
            "  --json             one JSON object per step and line: z_m, direction\n"
            "                     (\"approach\" or \"retract\"), amplitude_m, phase_lag_deg,\n"
            "                     lockin {amplitude_m, phase_lag_deg}, harmonics [{k,\n"
            "                     amplitude_m, phase_lag_deg}], mean_deflection_m,\n"
            "                     peak_force_n, attractive_force_n, mean_force_n,\n"
            "                     indentation_m, contact_time_s, dissipated_energy_j,\n"
            "                     squeeze_dissipated_energy_j, virial_j, periodicity,\n"
            "                     settled, settle_periods, regime,\n"
            "                     free_amplitude_m, free_phase_lag_deg (A0: harmonic 1 at\n"
            "                     Z 1 um with the gap-dependent tip forces off and the\n"
            "                     squeeze film on, the same A0 as scan and the daemon);\n"
            "                     and one {\"jump\": {direction, from, to, z_before_m,\n"
            "                     z_after_m, amplitude_before_m, amplitude_after_m,\n"
            "                     phase_before_deg, phase_after_deg, sharp,\n"
            "                     phasor_change_m, neighbour_change_m (the step change of\n"
            "                     A e^{-i lag} there and the larger beside it),\n"
            "                     regime_z_before_m, regime_z_after_m (where the mean force\n"
            "                     changes sign)}} per change of regime, before the record\n"
            "                     at z_after_m\n"
            "  --help             this text\n\n" AFMT_OPT_SI_HELP
            "Without --json a table (nm, deg, nN, eV). Progress on stderr (terminals only).\n"
            "Exit status 0 ok, 1 simulation failure, 2 bad usage or bad input.\n",
            DEFAULT_MAX_PERIODS, MAX_ANALYSE, DEFAULT_ANALYSE, AFM_MAX_HARMONICS, DEFAULT_K,
            DEFAULT_TOL);
}

/* 0 ok, 1 --help, -1 bad usage (said). */
static int parse_args(int argc, char **argv, approach_opts *o) {
    *o = (approach_opts){.from_m = NAN,
                         .to_m = NAN,
                         .step_m = NAN,
                         .fe_hz = NAN,
                         .ae_m = NAN,
                         .max_periods = DEFAULT_MAX_PERIODS,
                         .analyse = DEFAULT_ANALYSE,
                         .k_max = DEFAULT_K,
                         .integrator = -1,
                         .scheme = -1,
                         .tol = DEFAULT_TOL,
                         .fm_drive = -1,
                         .fm_tol_hz = 1e-3};
    static const afmt_choice mode_choices[] = {{"am", 0}, {"fm", 1}, {NULL, 0}};
    static const afmt_choice fm_drive_choices[] = {
        {"pll", AFM_FM_DRIVE_PLL}, {"self", AFM_FM_DRIVE_SELF}, {NULL, 0}};
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &o->json),
        AFMT_FLAG("--retract", &o->retract),
        AFMT_STRING("--config", &o->config),
        AFMT_LENGTH("--from", &o->from_m, 0, 0, NULL),
        AFMT_LENGTH("--to", &o->to_m, 0, 0, NULL),
        AFMT_LENGTH("--step", &o->step_m, 0, 0, NULL),
        AFMT_FREQ("--fe", &o->fe_hz, 0, 0, NULL),
        AFMT_LENGTH("--ae", &o->ae_m, 0, 0, NULL),
        AFMT_DOUBLE("--tol", &o->tol, 0, 0, NULL),
        AFMT_DOUBLE_ABOVE("--rate", &o->rate_m_s, 0, 1.0, "(0, 1] m/s"),
        AFMT_CHOICE("--mode", &o->fm, mode_choices),
        AFMT_DOUBLE_ABOVE("--fm-tol", &o->fm_tol_hz, 0, 1e6, "(0, 1e6] Hz"),
        AFMT_CHOICE("--fm-drive", &o->fm_drive, fm_drive_choices),
        AFMT_INT("--periods", &o->max_periods, 2, 100000000, NULL),
        AFMT_INT("--analyse", &o->analyse, 1, MAX_ANALYSE, NULL),
        AFMT_INT("--harmonics", &o->k_max, 1, AFM_MAX_HARMONICS, NULL),
        AFMT_CHOICE("--integrator", &o->integrator, afmt_integrator_choices),
        AFMT_CHOICE("--scheme", &o->scheme, afmt_scheme_choices),
        AFMT_OPTS_END,
    };
    int rc = afmt_opts_parse("approach", opts, argc, argv, 1);
    if (rc) return rc == AFMT_OPTS_HELP ? 1 : -1;
    if (!o->config || isnan(o->from_m) || isnan(o->to_m)) {
        fprintf(stderr, "afmtwin approach: --config, --from and --to are required\n");
        return -1;
    }
    if (o->from_m < 0 || o->from_m > 1e-3 || o->to_m < 0 || o->to_m > 1e-3) {
        fprintf(stderr, "afmtwin approach: --from and --to must be in 0..1e-3 m (got %g, %g)\n",
                o->from_m, o->to_m);
        return -1;
    }
    if (o->from_m != o->to_m && !(o->step_m > 0)) {
        fprintf(stderr, "afmtwin approach: --step must be given and > 0 m when --from and --to "
                        "differ\n");
        return -1;
    }
    if (!isnan(o->ae_m) && (o->ae_m < 0 || o->ae_m > 1e-6)) {
        fprintf(stderr, "afmtwin approach: --ae must be in 0..1e-6 m (got %g)\n", o->ae_m);
        return -1;
    }
    if (!isnan(o->fe_hz) && !(o->fe_hz > 0)) {
        fprintf(stderr, "afmtwin approach: --fe must be > 0 Hz (got %g)\n", o->fe_hz);
        return -1;
    }
    if (o->fm_drive >= 0 && !o->fm) {
        fprintf(stderr, "afmtwin approach: --fm-drive needs --mode fm\n");
        return -1;
    }
    if (o->fm && o->rate_m_s > 0) {
        fprintf(stderr, "afmtwin approach: --rate is for --mode am only\n");
        return -1;
    }
    if (!(o->tol > 0 && o->tol < 1)) {
        fprintf(stderr, "afmtwin approach: --tol must be in (0, 1) (got %g)\n", o->tol);
        return -1;
    }
    return 0;
}

/* Per period: mean force, min force and the virial of the tip-sample force (the sample's
 * total less the squeeze film's, afm_force_parts_at: as afm_cycle splits it),
 * trapezoid over the samples with the step across a period boundary (theta = 2 pi m)
 * split at it (linear interpolant). */
typedef struct {
    bool have, active;
    afm_sample prev;
    double th_prev, t_len, f_int, fx_int, f_min;
} approach_extra;

typedef struct {
    double mean_force_n, attractive_force_n, virial_j;
} extra_period;

/* Integrals of f and f x over a part [s0, s1] (fractions) of the step from a to b. */
static void extra_add(approach_extra *e, const afm_sample *a, const afm_sample *b, double s0,
                      double s1) {
    double h = (b->t_s - a->t_s) * (s1 - s0);
    double fa = a->f_n + s0 * (b->f_n - a->f_n), fb = a->f_n + s1 * (b->f_n - a->f_n);
    double xa = a->x_m + s0 * (b->x_m - a->x_m), xb = a->x_m + s1 * (b->x_m - a->x_m);
    e->t_len += h;
    e->f_int += 0.5 * h * (fa + fb);
    e->fx_int += 0.5 * h * (fa * xa + fb * xb);
    if (fb < e->f_min) e->f_min = fb;
}

/* 1 when the sample completed a period (*out), else 0. */
static int extra_push(approach_extra *e, const afm_sample *s, double th, extra_period *out) {
    int done = 0;
    if (e->have) {
        double m = floor(th / TWO_PI);
        if (m > floor(e->th_prev / TWO_PI)) { /* the boundary 2 pi m lies in this step */
            double sb = (m * TWO_PI - e->th_prev) / (th - e->th_prev);
            if (e->active) {
                extra_add(e, &e->prev, s, 0.0, sb);
                *out = (extra_period){e->f_int / e->t_len, e->f_min, e->fx_int / e->t_len};
                done = 1;
            }
            e->active = true;
            e->t_len = e->f_int = e->fx_int = 0.0;
            e->f_min = HUGE_VAL;
            extra_add(e, &e->prev, s, sb, 1.0);
        } else if (e->active) {
            extra_add(e, &e->prev, s, 0.0, 1.0);
        }
    }
    e->prev = *s;
    e->th_prev = th;
    e->have = true;
    return done;
}

/* Every sample of the curve goes through the estimators; completed periods into rings. */
typedef struct {
    afm_lockin lockin;
    afm_cycle cycle;
    afm_harm harm;
    approach_extra extra;
    double lockin_tau_s;
    bool lockin_fed; /* fm: the FM loop feeds the lock-in (afm_fm_run), not on_samples */
    long n_cyc, n_harm, n_extra; /* completed periods so far */
    afm_cycle_metrics cyc[MAX_ANALYSE];
    afm_harm_result harm_r[MAX_ANALYSE];
    extra_period ext[MAX_ANALYSE];
} approach_est;

static void on_samples(void *ctx, const afm_sim *s, const afm_sample *smp, int n) {
    approach_est *e = ctx;
    const afm_drive *d = afm_sim_drive(s);
    for (int i = 0; i < n; i++) {
        double th = afm_drive_phase(d, 0, smp[i].t_s);
        if (!e->lockin_fed) afm_lockin_push(&e->lockin, smp[i].x_m, th);
        if (afm_cycle_push_ev(&e->cycle, &smp[i], th, afm_sim_events_at(s, smp[i].t_s)) == 1)
            e->cyc[e->n_cyc++ % MAX_ANALYSE] = e->cycle.out;
        if (afm_harm_push(&e->harm, smp[i].x_m, smp[i].f_n, th) == 1)
            e->harm_r[e->n_harm++ % MAX_ANALYSE] = e->harm.out;
        extra_period ep;
        afm_sample ts = smp[i];
        afm_force_parts fp;
        afm_force_parts_at(afm_sim_forces(s), afm_sim_separation(s), ts.x_m, ts.v_m_s, &fp);
        ts.f_n -= fp.squeeze_n;
        if (extra_push(&e->extra, &ts, th, &ep)) e->ext[e->n_extra++ % MAX_ANALYSE] = ep;
    }
}

/* What one step reports (means over the analysed periods). */
typedef struct {
    double z_m;
    bool retract;
    double amp_m[AFM_MAX_HARMONICS], lag_deg[AFM_MAX_HARMONICS];
    double lockin_amp_m, lockin_lag_deg;
    afm_cycle_metrics cyc; /* means */
    extra_period ext;      /* means */
    int periodicity, settle_periods;
    bool settled, attractive;
    double free_amp_m, free_lag_deg; /* A0 and its lag (runner/afm_a0.h) */
} approach_point;

/* Means over the last n periods of each ring. */
static void approach_means(const approach_est *e, int n, int nk, approach_point *pt) {
    double re[AFM_MAX_HARMONICS] = {0}, im[AFM_MAX_HARMONICS] = {0}, len = 0.0;
    memset(&pt->cyc, 0, sizeof pt->cyc);
    memset(&pt->ext, 0, sizeof pt->ext);
    for (int j = 0; j < n; j++) {
        const afm_harm_result *h = &e->harm_r[(e->n_harm - 1 - j) % MAX_ANALYSE];
        for (int k = 0; k < nk; k++) { /* lane k: x re at raw + 16 (k / 4) + k % 4, im + 4 */
            const double *g = h->raw + 16 * (k / 4) + k % 4;
            re[k] += g[0];
            im[k] += g[4];
        }
        len += h->samples;
        const afm_cycle_metrics *c = &e->cyc[(e->n_cyc - 1 - j) % MAX_ANALYSE];
        pt->cyc.peak_force_n += c->peak_force_n / n;
        pt->cyc.min_deflection_m += c->min_deflection_m / n;
        pt->cyc.indentation_m += c->indentation_m / n;
        pt->cyc.contact_time_s += c->contact_time_s / n;
        pt->cyc.dissipated_energy_j += c->dissipated_energy_j / n;
        pt->cyc.squeeze_dissipated_energy_j += c->squeeze_dissipated_energy_j / n;
        pt->cyc.mean_deflection_m += c->mean_deflection_m / n;
        const extra_period *x = &e->ext[(e->n_extra - 1 - j) % MAX_ANALYSE];
        pt->ext.mean_force_n += x->mean_force_n / n;
        pt->ext.attractive_force_n += x->attractive_force_n / n;
        pt->ext.virial_j += x->virial_j / n;
    }
    for (int k = 0; k < nk; k++) { /* A e^{i phi} = (2 / T) int x e^{-ik theta} dt */
        pt->amp_m[k] = 2.0 * hypot(re[k], im[k]) / len;
        pt->lag_deg[k] = afm_orbit_lag_deg(atan2(im[k], re[k]) * (360.0 / TWO_PI));
    }
    afm_lockin_polar(&e->lockin, &pt->lockin_amp_m, &pt->lockin_lag_deg);
    pt->attractive = pt->ext.mean_force_n < 0.0;
}

static const char *regime(bool attractive) {
    return attractive ? "attractive" : "repulsive";
}

/* What made the records: the integrator and its scheme (set once the twin exists). */
static const char *json_integrator = "-", *json_scheme = "-";

static int print_json(const approach_point *p, int nk) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "z_m", p->z_m);
    cJSON_AddStringToObject(o, "integrator", json_integrator);
    cJSON_AddStringToObject(o, "scheme", json_scheme);
    cJSON_AddStringToObject(o, "direction", p->retract ? "retract" : "approach");
    cJSON_AddNumberToObject(o, "amplitude_m", p->amp_m[0]);
    cJSON_AddNumberToObject(o, "phase_lag_deg", p->lag_deg[0]);
    cJSON *l = cJSON_AddObjectToObject(o, "lockin");
    cJSON_AddNumberToObject(l, "amplitude_m", p->lockin_amp_m);
    cJSON_AddNumberToObject(l, "phase_lag_deg", p->lockin_lag_deg);
    cJSON *hs = cJSON_AddArrayToObject(o, "harmonics");
    for (int k = 0; k < nk; k++) {
        cJSON *h = cJSON_CreateObject();
        cJSON_AddNumberToObject(h, "k", k + 1);
        cJSON_AddNumberToObject(h, "amplitude_m", p->amp_m[k]);
        cJSON_AddNumberToObject(h, "phase_lag_deg", p->lag_deg[k]);
        cJSON_AddItemToArray(hs, h);
    }
    cJSON_AddNumberToObject(o, "mean_deflection_m", p->cyc.mean_deflection_m);
    cJSON_AddNumberToObject(o, "min_deflection_m", p->cyc.min_deflection_m);
    cJSON_AddNumberToObject(o, "peak_force_n", p->cyc.peak_force_n);
    cJSON_AddNumberToObject(o, "attractive_force_n", p->ext.attractive_force_n);
    cJSON_AddNumberToObject(o, "mean_force_n", p->ext.mean_force_n);
    cJSON_AddNumberToObject(o, "indentation_m", p->cyc.indentation_m);
    cJSON_AddNumberToObject(o, "contact_time_s", p->cyc.contact_time_s);
    cJSON_AddNumberToObject(o, "dissipated_energy_j", p->cyc.dissipated_energy_j);
    cJSON_AddNumberToObject(o, "squeeze_dissipated_energy_j", p->cyc.squeeze_dissipated_energy_j);
    cJSON_AddNumberToObject(o, "virial_j", p->ext.virial_j);
    cJSON_AddNumberToObject(o, "periodicity", p->periodicity);
    cJSON_AddBoolToObject(o, "settled", p->settled);
    cJSON_AddNumberToObject(o, "settle_periods", p->settle_periods);
    cJSON_AddStringToObject(o, "regime", regime(p->attractive));
    cJSON_AddNumberToObject(o, "free_amplitude_m", p->free_amp_m);
    cJSON_AddNumberToObject(o, "free_phase_lag_deg", p->free_lag_deg);
    return afmt_json_emit(o);
}

/* A jump: the amplitude branch changes between points after - 1 and after of the curve,
 * at the change of regime (the sign of the mean tip-sample force) between points
 * regime - 1 and regime, which may lie a few steps away (on a retract the lever stays on
 * the high-amplitude branch after its mean force has turned attractive). */
typedef struct {
    int after, regime;
    double change_m, neighbour_m; /* |step change of the harmonic-1 phasor| here, beside */
    bool sharp;                   /* change_m > JUMP_CONTRAST x neighbour_m */
} approach_jump;

/* A branch switch is a step-to-step change of the harmonic-1 phasor this many times the
 * larger of the changes of the steps beside it (1.5-4 on the smooth parts of README's
 * probe-q300 curve near its folds, 3.8 at its retract jump with 0.1 nm steps, more with
 * finer steps: the jump is fixed, the smooth changes shrink with the step). */
#define JUMP_CONTRAST 2.0

/* |A_a e^{-i lag_a} - A_b e^{-i lag_b}|, harmonic 1 (m). */
static double phasor_change(const approach_point *a, const approach_point *b) {
    double d = (a->lag_deg[0] - b->lag_deg[0]) * (TWO_PI / 360.0);
    double s = a->amp_m[0] * a->amp_m[0] + b->amp_m[0] * b->amp_m[0] -
               2.0 * a->amp_m[0] * b->amp_m[0] * cos(d);
    return s > 0.0 ? sqrt(s) : 0.0;
}

/* The jumps of the pass p[s..e) (pair j: points j - 1 and j, j >= 1; the retract's first
 * pair joins it to the approach's last point). For each change of regime at pair c, the
 * search runs over the pairs after the previous change and before the next one (the
 * pass's ends else): the pair of the largest phasor change is the jump if it stands out
 * (JUMP_CONTRAST over its neighbours) and no earlier change took it; otherwise the jump
 * is put at c itself (a smooth crossover, sharp false). Returns the number found. */
static int find_jumps(const approach_point *p, int s, int e, approach_jump *out, int max) {
    const int first = s > 1 ? s : 1;
    int c[64], nc = 0, n = 0;
    for (int j = first; j < e && nc < 64; j++)
        if (p[j].attractive != p[j - 1].attractive) c[nc++] = j;
    for (int k = 0; k < nc && n < max; k++) {
        int lo = k > 0 ? c[k - 1] + 1 : first, hi = k + 1 < nc ? c[k + 1] - 1 : e - 1;
        if (lo > c[k]) lo = c[k];
        if (hi < c[k]) hi = c[k];
        int best = c[k];
        for (int j = lo; j <= hi; j++)
            if (phasor_change(&p[j - 1], &p[j]) > phasor_change(&p[best - 1], &p[best])) best = j;
        for (int m = 0; m < n; m++)
            if (out[m].after == best) best = c[k];
        double nb = 0.0;
        if (best - 1 >= first) nb = fmax(nb, phasor_change(&p[best - 2], &p[best - 1]));
        if (best + 1 < e) nb = fmax(nb, phasor_change(&p[best], &p[best + 1]));
        double ch = phasor_change(&p[best - 1], &p[best]);
        bool sharp = ch > JUMP_CONTRAST * nb;
        if (!sharp && best != c[k]) { /* nothing stands out: at the change of regime */
            best = c[k];
            ch = phasor_change(&p[best - 1], &p[best]);
            nb = 0.0;
            if (best - 1 >= first) nb = fmax(nb, phasor_change(&p[best - 2], &p[best - 1]));
            if (best + 1 < e) nb = fmax(nb, phasor_change(&p[best], &p[best + 1]));
            sharp = ch > JUMP_CONTRAST * nb;
        }
        out[n++] = (approach_jump){best, c[k], ch, nb, sharp};
    }
    return n;
}

static void print_jump(const approach_point *p, const approach_jump *jp, bool json) {
    const approach_point *a = &p[jp->after - 1], *b = &p[jp->after];
    const approach_point *ra = &p[jp->regime - 1], *rb = &p[jp->regime];
    if (!json) {
        printf("# jump (%s): %s -> %s between Z %.4f and %.4f nm: A %.4f -> %.4f nm, lag "
               "%.3f -> %.3f deg; %s; the mean tip-sample force changes sign from Z %.4f to "
               "%.4f nm\n",
               b->retract ? "retract" : "approach", regime(ra->attractive), regime(rb->attractive),
               a->z_m * 1e9, b->z_m * 1e9, a->amp_m[0] * 1e9, b->amp_m[0] * 1e9, a->lag_deg[0],
               b->lag_deg[0],
               jp->sharp ? "the amplitude branch changes" : "no sharp branch change (a crossover)",
               ra->z_m * 1e9, rb->z_m * 1e9);
        return;
    }
    printf("{\"jump\":{\"direction\":\"%s\",\"from\":\"%s\",\"to\":\"%s\",\"z_before_m\":%.17g,"
           "\"z_after_m\":%.17g,\"amplitude_before_m\":%.17g,\"amplitude_after_m\":%.17g,"
           "\"phase_before_deg\":%.17g,\"phase_after_deg\":%.17g,\"sharp\":%s,"
           "\"phasor_change_m\":%.17g,\"neighbour_change_m\":%.17g,"
           "\"regime_z_before_m\":%.17g,\"regime_z_after_m\":%.17g}}\n",
           b->retract ? "retract" : "approach", regime(ra->attractive), regime(rb->attractive),
           a->z_m, b->z_m, a->amp_m[0], b->amp_m[0], a->lag_deg[0], b->lag_deg[0],
           jp->sharp ? "true" : "false", jp->change_m, jp->neighbour_m, ra->z_m, rb->z_m);
}

static void print_text(const approach_point *p);
static int print_json(const approach_point *p, int k_max);

/* Writes the records p[s..e) with their jumps before the records they jump to. 0 ok, -1
 * out of memory. */
static int print_pass(const approach_point *p, int s, int e, const approach_opts *o) {
    static approach_jump jumps[64];
    int nj = find_jumps(p, s, e, jumps, 64);
    for (int i = s; i < e; i++) {
        for (int m = 0; m < nj; m++)
            if (jumps[m].after == i) print_jump(p, &jumps[m], o->json);
        if (o->json ? print_json(&p[i], o->k_max) != 0 : (print_text(&p[i]), 0)) return -1;
    }
    fflush(stdout);
    return 0;
}

static void print_text(const approach_point *p) {
    printf("%-8s %10.4f %10.5f %9.4f %10.5f %9.4f %10.4f %10.4f %9.4f %11.4e %9.4f %9.3f %3d%s\n",
           p->retract ? "retract" : "approach", p->z_m * 1e9, p->amp_m[0] * 1e9, p->lag_deg[0],
           p->lockin_amp_m * 1e9, p->lockin_lag_deg, p->cyc.peak_force_n * 1e9,
           p->ext.attractive_force_n * 1e9, p->cyc.indentation_m * 1e9, p->cyc.contact_time_s,
           p->cyc.dissipated_energy_j / 1.602176634e-19,
           p->cyc.squeeze_dissipated_energy_j / 1.602176634e-19, p->periodicity,
           p->settled ? "" : " *");
}

/* Z of step i of n from a to b (exact multiples of the step). */
static double step_z(double a, double b, double dz, int i, int n) {
    if (i == n - 1) return b;
    return b < a ? a - (double)i * dz : a + (double)i * dz;
}

/* Run the estimators over n_min samples or more, until each has completed `need` more
 * periods and 12 lock-in time constants have passed; with rate > 0, Z moves from z0
 * towards z1 at that speed (a new Z every 64 samples) and the run also lasts until it
 * reaches z1. 0 ok, -1 (err). */
static int approach_run(afm_sim *sim, approach_est *e, int need, double z0, double z1, double rate,
                        char *err, size_t errlen) {
    const long c0 = e->n_cyc, h0 = e->n_harm, x0 = e->n_extra;
    const double t0 = afm_sim_time(sim), t_end = t0 + 12.0 * e->lockin_tau_s;
    const double t_ramp = rate > 0 ? fabs(z1 - z0) / rate : 0.0;
    static afm_sample buf[64];
    double z = z0;
    while (e->n_cyc - c0 < need || e->n_harm - h0 < need || e->n_extra - x0 < need ||
           afm_sim_time(sim) < t_end || (rate > 0 && z != z1)) {
        if (rate > 0 && z != z1) {
            double u = (afm_sim_time(sim) - t0) / t_ramp;
            z = u >= 1.0 ? z1 : z0 + u * (z1 - z0);
            if (afm_sim_set_separation(sim, z) != AFM_SIM_OK) {
                snprintf(err, errlen, "cannot set Z = %g m", z);
                return -1;
            }
            afm_cycle_set_forces(&e->cycle, afm_sim_forces(sim), z);
        }
        if (afm_sim_run(sim, 64, buf) != AFM_SIM_OK) {
            snprintf(err, errlen, "simulation failed at Z = %g m", z);
            return -1;
        }
        on_samples(e, sim, buf, 64);
    }
    return 0;
}

/* One Z: dwell, then the analysed periods. 0 ok, -1 (err). */
static int approach_step(afm_sweep *sw, afm_sim *sim, approach_est *e, const approach_opts *o,
                         double z, approach_point *pt, char *err, size_t errlen) {
    if (afm_sim_set_separation(sim, z) != AFM_SIM_OK) {
        snprintf(err, errlen, "cannot set Z = %g m", z);
        return -1;
    }
    afm_cycle_set_forces(&e->cycle, afm_sim_forces(sim), z);
    static afm_orbit ob;
    int settled = afm_sweep_dwell(sw, sim, &ob, err, errlen);
    if (settled < 0) return -1;
    pt->z_m = z;
    pt->settled = settled == 1;
    pt->periodicity = settled == 1 ? sw->st.p : 0;
    pt->settle_periods = sw->st.periods;
    /* the analysed periods: all after the dwell (one more for the partial one at its end),
     * and at least 12 lock-in time constants, so that its filter has settled (4th order:
     * the step's transient below 1e-5 of it) */
    if (approach_run(sim, e, o->analyse + 1, z, z, 0.0, err, errlen)) return -1;
    approach_means(e, o->analyse, o->k_max, pt);
    return 0;
}

/* One leg of a ramp, from z0 to z: the last N periods of it. */
static int approach_ramp(afm_sim *sim, approach_est *e, const approach_opts *o, double z0, double z,
                         approach_point *pt, char *err, size_t errlen) {
    if (approach_run(sim, e, o->analyse + 1, z0, z, o->rate_m_s, err, errlen)) return -1;
    pt->z_m = z;
    approach_means(e, o->analyse, o->k_max, pt);
    return 0;
}

/* ------------------------------------------------------------------ --mode fm */

/* What one FM step reports: the loops' window means and the per-period forces. */
typedef struct {
    approach_point pt; /* z, direction, per-period forces and harmonics (as am) */
    afm_fm_means fm;
    double f_free_hz, a_set_m;
    bool self; /* the self-excited drive */
} approach_fm_point;

static int print_fm_json(const approach_fm_point *p) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "z_m", p->pt.z_m);
    cJSON_AddStringToObject(o, "mode", "fm");
    cJSON_AddStringToObject(o, "fm_drive", p->self ? "self" : "pll");
    cJSON_AddStringToObject(o, "integrator", json_integrator);
    cJSON_AddStringToObject(o, "scheme", json_scheme);
    cJSON_AddStringToObject(o, "direction", p->pt.retract ? "retract" : "approach");
    cJSON_AddNumberToObject(o, "frequency_shift_hz", p->fm.freq_hz - p->f_free_hz);
    cJSON_AddNumberToObject(o, "frequency_hz", p->fm.freq_hz);
    cJSON_AddNumberToObject(o, "free_frequency_hz", p->f_free_hz);
    cJSON_AddNumberToObject(o, "drive_amplitude_m", p->fm.drive_m);
    cJSON_AddNumberToObject(o, "amplitude_m", p->fm.amplitude_m);
    cJSON_AddNumberToObject(o, "amplitude_setpoint_m", p->a_set_m);
    cJSON_AddNumberToObject(o, "phase_error_deg", p->fm.phase_error_deg);
    cJSON_AddNumberToObject(o, "lag_deg", p->fm.lag_deg);
    cJSON_AddBoolToObject(o, "locked", p->fm.lock == AFM_FM_LOCKED);
    cJSON_AddStringToObject(o, "lock_state", afm_fm_lock_name(p->fm.lock));
    cJSON_AddBoolToObject(o, "settled", p->fm.settled);
    cJSON_AddNumberToObject(o, "windows", p->fm.windows);
    cJSON_AddNumberToObject(o, "harmonic1_amplitude_m", p->pt.amp_m[0]);
    cJSON_AddNumberToObject(o, "mean_deflection_m", p->pt.cyc.mean_deflection_m);
    cJSON_AddNumberToObject(o, "peak_force_n", p->pt.cyc.peak_force_n);
    cJSON_AddNumberToObject(o, "attractive_force_n", p->pt.ext.attractive_force_n);
    cJSON_AddNumberToObject(o, "mean_force_n", p->pt.ext.mean_force_n);
    cJSON_AddNumberToObject(o, "dissipated_energy_j", p->pt.cyc.dissipated_energy_j);
    cJSON_AddStringToObject(o, "regime", regime(p->pt.attractive));
    return afmt_json_emit(o);
}

static void print_fm_text(const approach_fm_point *p) {
    printf("%-8s %10.4f %12.5f %14.6f %11.5g %10.5f %10.4f %-9s %10.4f %9.4f%s\n",
           p->pt.retract ? "retract" : "approach", p->pt.z_m * 1e9, p->fm.freq_hz - p->f_free_hz,
           p->fm.freq_hz, p->fm.drive_m * 1e12, p->fm.amplitude_m * 1e9, p->fm.phase_error_deg,
           afm_fm_lock_name(p->fm.lock), p->pt.cyc.peak_force_n * 1e9,
           p->pt.cyc.dissipated_energy_j / 1.602176634e-19, p->fm.settled ? "" : " *");
}

/* The FM curve: lock at Z = 1 um (f_free, the amplitude set-point), then every Z. */
static int approach_fm(afm_sim *sim, const afm_modal *m, afm_config *cfg, approach_est *est,
                       const approach_opts *o, const afm_cfg_lockin *lk, int n_steps) {
    char err[AFM_ERR_LEN];
    static afm_sample buf[4096];
    afm_fm_plant p;
    afm_fm_plant_of(m, &p);
    const double f_start = isnan(o->fe_hz) ? p.f0_hz : o->fe_hz;
    if (o->fm_drive >= 0) cfg->fm.drive = (afm_fm_drive)o->fm_drive;
    static afm_fm f;
    if (afm_fm_init(&f, &cfg->fm, lk, &p, cfg->sim.sample_rate_hz, f_start, f_start,
                    fmin(cfg->drive.tones[0].amplitude_m, cfg->fm.drive_max_m), err, sizeof err) ||
        afm_sim_set_tone(sim, 0, f.drive_m, f.freq_hz) != AFM_SIM_OK) {
        fprintf(stderr, "afmtwin approach: %s\n", err);
        return 2;
    }
    est->lockin_fed = true;
    const double t_upd = cfg->fm.update_samples / cfg->sim.sample_rate_hz;
    const long win = (long)ceil(f.lock_time_s / t_upd);
    int max_win = (int)ceil(o->max_periods / (f_start * win * t_upd));
    if (max_win < 10) max_win = 10;
    /* the free resonance and, unless configured, the amplitude set-point */
    afm_fm_means mn;
    if (afm_sim_set_separation(sim, AFM_A0_Z_M) != AFM_SIM_OK ||
        afm_fm_settle(&f, sim, &est->lockin, buf, 4096, win, max_win, o->fm_tol_hz, 1e-4,
                      on_samples, est, &mn, err, sizeof err)) {
        fprintf(stderr, "afmtwin approach: fm at Z 1 um: %s\n", err[0] ? err : "refused");
        return 1;
    }
    if (!(cfg->fm.amplitude_setpoint_m > 0)) {
        afm_fm_hold_amplitude(&f, mn.amplitude_m);
        if (afm_fm_settle(&f, sim, &est->lockin, buf, 4096, win, max_win, o->fm_tol_hz, 1e-4,
                          on_samples, est, &mn, err, sizeof err)) {
            fprintf(stderr, "afmtwin approach: fm at Z 1 um: %s\n", err);
            return 1;
        }
    }
    if (mn.lock != AFM_FM_LOCKED)
        fprintf(stderr, "afmtwin approach: warning: the PLL did not lock at Z 1 um (%s)\n",
                afm_fm_lock_name(mn.lock));
    const double f_free = mn.freq_hz;
    afm_fm_recenter(&f);
    if (!o->json) {
        printf("# afmtwin approach %s --mode fm: drive %s; integrator %s (scheme %s); PLL "
               "bandwidth %g Hz "
               "(kp %.4g Hz/deg, ki %.4g Hz/(deg s)), amplitude bandwidth %g Hz (kp %.4g, ki "
               "%.4g 1/s), lock-in tau %g s order %d, update every %d samples\n",
               o->config, cfg->fm.drive == AFM_FM_DRIVE_SELF ? "self-excited (delay line)" : "pll",
               afm_sim_integrator_name(sim), afm_sim_scheme_name(sim), cfg->fm.pll_bandwidth_hz,
               f.kp, f.ki, cfg->fm.amplitude_bandwidth_hz, f.akp, f.aki, lk->time_constant_s,
               lk->order, cfg->fm.update_samples);
        printf("# free resonance f_free %.6f Hz (locked at Z 1 um, lag %.3f deg held; model mode "
               "1: %.6f Hz, Q %.5g); amplitude set-point %.6g nm, free drive %.6g pm\n",
               f_free, cfg->fm.phase_setpoint_deg, p.f0_hz, p.q, f.a_set_m * 1e9,
               mn.drive_m * 1e12);
        printf("# df = f - f_free; phase error = lock-in lag - set-point; drive = tone 0's "
               "amplitude; * = not settled\n");
        printf("%-8s %10s %12s %14s %11s %10s %10s %-9s %10s %9s\n", "# dir", "Z_nm", "df_Hz",
               "f_Hz", "drive_pm", "A_nm", "perr_deg", "lock", "Fpeak_nN", "Ediss_eV");
    }
    afmt_progress pg; /* opts.h: stderr, terminals only, after the first second */
    afmt_progress_init(&pg);
    const int passes = o->retract ? 2 : 1;
    for (int pass = 0; pass < passes; pass++) {
        for (int i = pass; i < n_steps; i++) {
            approach_fm_point q;
            memset(&q, 0, sizeof q);
            q.pt.retract = pass == 1;
            q.f_free_hz = f_free;
            q.self = cfg->fm.drive == AFM_FM_DRIVE_SELF;
            q.a_set_m = f.a_set_m;
            double z = step_z(o->from_m, o->to_m, o->step_m, pass ? n_steps - 1 - i : i, n_steps);
            afmt_progress_update(&pg, "approach --mode fm: %s step %d/%d, Z %.4f nm",
                                 pass ? "retract" : "approach", i + 1, n_steps, z * 1e9);
            if (afm_sim_set_separation(sim, z) != AFM_SIM_OK) {
                afmt_progress_end(&pg);
                fprintf(stderr, "afmtwin approach: cannot set Z = %g m\n", z);
                return 1;
            }
            afm_cycle_set_forces(&est->cycle, afm_sim_forces(sim), z);
            if (afm_fm_settle(&f, sim, &est->lockin, buf, 4096, win, max_win, o->fm_tol_hz, 1e-4,
                              on_samples, est, &q.fm, err, sizeof err)) {
                afmt_progress_end(&pg);
                fprintf(stderr, "afmtwin approach: %s\n", err);
                return 1;
            }
            q.pt.z_m = z;
            approach_means(est, o->analyse, o->k_max, &q.pt);
            afmt_progress_hide(&pg); /* stdout on the same terminal: the record, then the line */
            if (o->json ? print_fm_json(&q) != 0 : (print_fm_text(&q), 0)) {
                afmt_progress_end(&pg);
                fprintf(stderr, "afmtwin approach: out of memory writing JSON\n");
                return 1;
            }
            fflush(stdout);
            afmt_progress_redraw(&pg);
        }
    }
    afmt_progress_end(&pg);
    return 0;
}

int afm_cmd_approach(int argc, char **argv) {
    approach_opts o;
    int rc = afmt_opts_done("approach", parse_args(argc, argv, &o), approach_usage);
    if (rc >= 0) return rc;
    static afm_config cfg;
    char err[AFM_ERR_LEN];
    if (afmt_config_load("approach", o.config, &cfg)) return 2;
    if (!isnan(o.fe_hz)) cfg.drive.tones[0].frequency_hz = o.fe_hz;
    if (!isnan(o.ae_m)) cfg.drive.tones[0].amplitude_m = o.ae_m;
    if (o.integrator >= 0) cfg.sim.integrator = (afm_integrator_kind)o.integrator;
    if (o.scheme >= 0) cfg.sim.rt_scheme = (afm_rt_scheme_kind)o.scheme;
    cfg.drive.separation_m = o.from_m;
    const double fe = cfg.drive.tones[0].frequency_hz, fs = cfg.sim.sample_rate_hz;
    if (o.k_max * fe >= 0.5 * fs) {
        fprintf(stderr,
                "afmtwin approach: harmonic %d of %g Hz is not below half the sample "
                "rate\n",
                o.k_max, fe);
        return 2;
    }
    if (afm_config_validate(&cfg, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin approach: %s\n", err);
        return 2;
    }
    int n_steps = 1;
    if (o.from_m != o.to_m) {
        double n = ceil(fabs(o.to_m - o.from_m) / o.step_m * (1.0 - 1e-12)) + 1.0;
        if (n > MAX_STEPS) {
            fprintf(stderr, "afmtwin approach: %.0f steps; at most %d\n", n, MAX_STEPS);
            return 2;
        }
        n_steps = (int)n;
    }
    static afm_modal model;
    afm_sim *sim = afm_twin_create(&cfg, &model, NULL, err, sizeof err);
    if (!sim) {
        fprintf(stderr, "afmtwin approach: %s\n", err);
        return 1;
    }
    static afm_sweep sw;
    static approach_est est;
    /* The per-period metrics take what the integrator knows of each step (afm_cycle_push_ev:
     * the rt accurate scheme's crossings, min of x and tip-sample work from its pieces, CVODE's
     * from its dense output; the fast scheme records nothing): on unless AFMTWIN_STEP_EVENTS=0
     * (afmt_step_events; docs/numerics.md, issue 28). */
    afm_step_events *ev_ring = NULL;
    int ks[AFM_MAX_HARMONICS];
    for (int k = 0; k < o.k_max; k++)
        ks[k] = k + 1;
    afm_cfg_lockin lk = cfg.lockin;
    if (lk.time_constant_s == 0) lk.time_constant_s = 10.0 / fe;
    if (lk.order == 0) lk.order = 4;
    double xc = afm_force_contact_x(afm_sim_forces(sim), o.from_m);
    if (afm_sweep_init(&sw, fs, fe, o.tol, o.max_periods, ks, 1, err, sizeof err) != 0 ||
        afm_lockin_init(&est.lockin, &lk, afm_sim_dt(sim), err, sizeof err) != 0 ||
        afm_cycle_init(&est.cycle, xc, afm_sim_forces(sim)->cos_alpha, err, sizeof err) != 0 ||
        afm_cycle_set_forces(&est.cycle, afm_sim_forces(sim), o.from_m) != 0 ||
        afm_harm_init(&est.harm, ks, o.k_max, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin approach: %s\n", err);
        afm_sim_destroy(&sim);
        return 1;
    }
    ev_ring = afmt_step_events_ring(sim, sw.cap > (1 << 13) ? sw.cap : 1 << 13);
    est.lockin_tau_s = lk.time_constant_s;
    sw.on_samples = on_samples;
    sw.on_samples_ctx = &est;
    json_integrator = afm_sim_integrator_name(sim);
    json_scheme = afm_sim_scheme_name(sim);
    if (o.fm) {
        int st = approach_fm(sim, &model, &cfg, &est, &o, &lk, n_steps);
        afm_sweep_destroy(&sw);
        afm_sim_destroy(&sim);
        free(ev_ring);
        return st;
    }
    if (!o.json) {
        printf("# afmtwin approach %s: integrator %s (scheme %s), fe %.6g Hz, Ae %.4g m, %d "
               "periods analysed per step; phase: lag of the deflection behind the drive (90 deg "
               "free at resonance)\n",
               o.config, afm_sim_integrator_name(sim), afm_sim_scheme_name(sim), fe,
               cfg.drive.tones[0].amplitude_m, o.analyse);
        printf("%-8s %10s %10s %9s %10s %9s %10s %10s %9s %11s %9s %9s %3s\n", "# dir", "Z_nm",
               "A1_nm", "lag_deg", "lockin_nm", "li_lag", "Fpeak_nN", "Fattr_nN", "indent_nm",
               "contact_s", "Ediss_eV", "Esq_eV", "p");
        printf(
            "# p: the periodicity of the orbit the step settled on (1: repeats every drive "
            "period, 2: every second, ...); 'p 0 *': the orbit did not repeat within --tol "
            "in --periods periods (%d here; in hard viscoelastic contact the rt schemes may never "
            "settle to it): the row is the mean of the last --analyse periods run\n",
            o.max_periods);
    }
    /* the free amplitude A0 (afm_a0.h: harmonic 1 at Z 1 um, gap forces off, squeeze on) */
    afm_a0 a0;
    if (afm_a0_compute(&cfg, &a0, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin approach: %s\n", err);
        afm_sweep_destroy(&sw);
        afm_sim_destroy(&sim);
        free(ev_ring);
        return 1;
    }
    const double free_amp = a0.amplitude_m, free_lag = a0.lag_deg;
    if (!o.json)
        printf("# free amplitude A0 (harmonic 1 at Z %.0f nm, gap-dependent tip forces off, "
               "squeeze film on): %.6g nm, lag %.4f deg\n",
               a0.z_m * 1e9, free_amp * 1e9, free_lag);
    afmt_progress pg; /* opts.h: stderr, terminals only, after the first second */
    afmt_progress_init(&pg);
    int status = 0;
    /* the records of a pass are written when it ends: its jumps need the whole pass */
    const int passes = o.retract ? 2 : 1;
    approach_point *pts = calloc((size_t)n_steps * (size_t)passes, sizeof *pts);
    if (!pts) {
        fprintf(stderr, "afmtwin approach: out of memory\n");
        afm_sweep_destroy(&sw);
        afm_sim_destroy(&sim);
        free(ev_ring);
        return 1;
    }
    int np = 0;
    for (int pass = 0; pass < passes && status == 0; pass++) {
        const int start = np;
        for (int i = pass; i < n_steps && status == 0; i++) { /* the retract skips --to */
            approach_point *pt = &pts[np];
            pt->retract = pass == 1;
            pt->free_amp_m = free_amp;
            pt->free_lag_deg = free_lag;
            /* the retract visits the approach's points in reverse */
            double z = step_z(o.from_m, o.to_m, o.step_m, pass ? n_steps - 1 - i : i, n_steps);
            afmt_progress_update(&pg, "approach: %s step %d/%d, Z %.4f nm",
                                 pass ? "retract" : "approach", i + 1, n_steps, z * 1e9);
            const bool ramp = o.rate_m_s > 0 && np > 0;
            if (ramp ? approach_ramp(sim, &est, &o, pts[np - 1].z_m, z, pt, err, sizeof err) != 0
                     : approach_step(&sw, sim, &est, &o, z, pt, err, sizeof err) != 0) {
                afmt_progress_end(&pg);
                fprintf(stderr, "afmtwin approach: %s\n", err);
                status = 1;
                break;
            }
            np++;
        }
        afmt_progress_hide(&pg); /* stdout on the same terminal: the records, then the line */
        if (print_pass(pts, start, np, &o) != 0) { /* on a failure too: what was computed */
            afmt_progress_end(&pg);
            fprintf(stderr, "afmtwin approach: out of memory writing JSON\n");
            status = 1;
        }
        fflush(stdout);
        afmt_progress_redraw(&pg);
    }
    free(pts);
    afmt_progress_end(&pg);
    afm_sweep_destroy(&sw);
    afm_sim_destroy(&sim);
    free(ev_ring);
    return status;
}
