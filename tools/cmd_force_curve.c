/* SPDX-License-Identifier: MIT */
/* cmd_force_curve.c -- `afmtwin force-curve`: the quasi-static force-distance curve (issue 30).
 *
 * The drive is off (every tone's amplitude 0); the base Z is ramped at a constant speed from
 * --from down to --to and back, one new Z every sample, and the deflection (the tip
 * displacement x, negative towards the sample) is recorded against Z. The force is what a
 * user reads off such a curve, F = k x with k the model's static tip stiffness. Found on
 * the way:
 *   snap-in   the jump to contact on the approach: the first sample in contact (gap
 *             d = x cos(alpha) + Z below a0) that the deflection reached by a jump (it moved
 *             over the last lever period more than JUMP_RATIO times as far as Z did); the
 *             event is where the jump started: walking back from contact, the first sample
 *             where the curve is no steeper than |dx/dZ| = SNAP_SLOPE and the tip no faster
 *             than JUMP_V_FRAC of the jump's peak speed. On the quasi-static curve x(Z) of
 *             a fold (x - x* ~ sqrt(Z - Z*)) the slope 100 lies 1/300 of the gap before the
 *             fold: |x| 0.7 % short of |x*|, Z off by 2e-5 of it. The ramp adds a delay: the
 *             departure from a fold takes T ~ (2 d* / (3 w1^4 speed))^(1/5) and runs over
 *             L ~ 2 d* / (3 w1^2 T^2) in x before the slope passes 100 (the vdW fold of
 *             lumped-vdw-fold.conf: T 3 us, L 0.01 nm at 1e-7 m/s)
 *   pull-off  the most negative force of the retract (the adhesion) after the tip has been
 *             in contact on it, and whether the tip then jumped off (same ratio)
 *   slope     of deflection against Z over the approach records in contact in the upper half
 *             of their force range (least squares): 1 on an infinitely hard sample,
 *             k_c / (k + k_c) on one of contact stiffness k_c
 * The curve starts from the static equilibrium at --from (the modal state of the tip force
 * there, when the far branch has one), dwelt 16 lever periods. */
#include "afmtwin_cmds.h"
#include "opts.h"

#include "config/afm_config.h"
#include "forces/afm_force.h"
#include "beam/afm_model.h"
#include "integrators/afm_sim.h"
#include "runner/afm_twin.h"
#include "json_out.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define DEFAULT_SPEED_M_S 1e-6
#define DEFAULT_POINTS 200
#define MAX_POINTS 1000000
#define MAX_SAMPLES 500000000.0 /* both legs: about half a minute of the rt integrator */
#define JUMP_RATIO 10.0         /* |dx| cos(alpha) over one lever period vs |dZ| */
#define JUMP_V_FRAC 0.05        /* the jump starts where the speed is below this of its peak */
#define SNAP_SLOPE 100.0        /* ...or where the curve's |dx/dZ| is below this */
#define DWELL_PERIODS 16
#define TWO_PI 6.283185307179586476925286766559

typedef struct {
    const char *config;
    double from_m, to_m, speed_m_s;
    int points;
    bool json;
} fc_opts;

static void fc_usage(FILE *f) {
    fprintf(
        f,
        "usage: afmtwin force-curve --config FILE --from Z --to Z [--speed M_S]\n"
        "                           [--points N] [--json]\n\n"
        "Quasi-static force-distance curve, the first curve of every AFM session: the drive\n"
        "off (every tone's amplitude 0), the base Z ramped at --speed from --from towards the\n"
        "sample down to --to and back (a new Z every sample of the config's sample rate, the\n"
        "config's integrator), the deflection (tip displacement, negative towards the\n"
        "sample) recorded against Z and read as a force F = k x, with k the model's static\n"
        "tip stiffness. The curve starts from the static equilibrium at --from. Found on\n"
        "the way and summed up at the end:\n"
        "  snap-in       the jump to contact of the approach (none when the lever is stiffer\n"
        "                than the largest attractive force gradient: the tip then reaches\n"
        "                contact smoothly), at the Z, deflection and force where it started\n"
        "  pull-off      the most negative force of the retract, after contact: the\n"
        "                adhesion force, its Z and deflection, and whether the tip jumped\n"
        "                off there\n"
        "  slope         the deflection up per Z down in contact (-dx/dZ), fitted to the\n"
        "                approach records in the upper half of their contact forces: the\n"
        "                deflection sensitivity check, 1 on a hard sample (1 / cos(alpha)\n"
        "                on an inclined lever), k_c / (k + k_c) on one of contact\n"
        "                stiffness k_c (reported too)\n"
        "  k             the spring constant the forces are computed with\n"
        "Contact is the gap x cos(alpha) + Z below a0. The config's thermal noise is left\n"
        "off: the curve is the deterministic one.\n\n"
        "Quasi-static: Z should move little in one lever period (the header gives the\n"
        "ramp per period; 1e-6 m/s moves 3.3 pm per period of a 300 kHz lever); a high-Q\n"
        "lever rings after a jump for about Q / (pi f1) s, over speed times that in Z.\n\n"
        "options:\n"
        "  --config FILE      libconfig model file (see config/README.md)\n"
        "  --from Z, --to Z   the start (far) and the turning (near) Z (m), 0 <= --to <\n"
        "                     --from <= 1e-3\n"
        "  --speed M_S        Z ramp speed in m/s, (0, 1] (default %g)\n"
        "  --points N         records each way, evenly spaced in Z from --from to --to and\n"
        "                     back, 2..%d (default %d)\n"
        "  --json             one JSON object per record and line: z_m, direction\n"
        "                     (\"approach\" or \"retract\"), deflection_m, force_n, gap_m,\n"
        "                     contact; one per event: {\"event\": \"snap_in\" or \"pull_off\",\n"
        "                     z_m, deflection_m, force_n, jump}; and last {\"summary\": {config,\n"
        "                     integrator, speed_m_s, points, samples, model_time_s,\n"
        "                     ramp_per_period_m, spring_constant_n_m, contact_z_m,\n"
        "                     snap_in_z_m, snap_in_deflection_m, snap_in_force_n,\n"
        "                     pull_off_z_m, pull_off_deflection_m, adhesion_force_n,\n"
        "                     pull_off_jump, contact_slope, contact_slope_points,\n"
        "                     contact_stiffness_n_m}} (null where there is none)\n"
        "  --help             this text\n\n" AFMT_OPT_SI_HELP
        "Without --json a table (nm, nN) with the events and the summary as # lines.\n"
        "Progress on stderr (terminals only).\n"
        "Exit status 0 ok, 1 simulation failure, 2 bad usage or bad input.\n",
        DEFAULT_SPEED_M_S, MAX_POINTS, DEFAULT_POINTS);
}

/* 0 ok, 1 --help, -1 bad usage (said). */
static int parse_args(int argc, char **argv, fc_opts *o) {
    *o = (fc_opts){
        .from_m = NAN, .to_m = NAN, .speed_m_s = DEFAULT_SPEED_M_S, .points = DEFAULT_POINTS};
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &o->json),
        AFMT_STRING("--config", &o->config),
        AFMT_LENGTH("--from", &o->from_m, 0, 1e-3, "a Z in 0..1e-3 m"),
        AFMT_LENGTH("--to", &o->to_m, 0, 1e-3, "a Z in 0..1e-3 m"),
        AFMT_DOUBLE_ABOVE("--speed", &o->speed_m_s, 0, 1.0, "a speed in (0, 1] m/s"),
        AFMT_INT("--points", &o->points, 2, MAX_POINTS, NULL),
        AFMT_OPTS_END,
    };
    int rc = afmt_opts_parse("force-curve", opts, argc, argv, 1);
    if (rc) return rc == AFMT_OPTS_HELP ? 1 : -1;
    if (!o->config) {
        fprintf(stderr, "afmtwin force-curve: --config is required\n");
        return -1;
    }
    if (isnan(o->from_m) || isnan(o->to_m)) {
        fprintf(stderr, "afmtwin force-curve: --from and --to are required\n");
        return -1;
    }
    if (!(o->from_m > o->to_m)) {
        fprintf(stderr,
                "afmtwin force-curve: --from (%g m) must be above --to (%g m): the approach "
                "goes from --from down to --to\n",
                o->from_m, o->to_m);
        return -1;
    }
    return 0;
}

/* One sample of the recent past, for the events. */
typedef struct {
    double z_m, x_m, v_m_s;
} fc_hist;

typedef struct {
    bool have;
    double z_m, x_m, f_n;
    bool jump;
} fc_event;

typedef struct {
    /* constants */
    double k, cos_alpha, a0, speed;
    long period; /* samples per lever period (mode 1) */
    /* the last cap samples; n counts every sample pushed */
    fc_hist *ring;
    long cap, n;
    /* approach */
    bool touched; /* the first contact of the approach is behind */
    double contact_z_m;
    fc_event snap;
    /* retract */
    bool retract_touched; /* in contact at some sample of the retract */
    fc_event pull;        /* the retract's force minimum after contact */
    bool left;            /* the tip out of contact at or after that minimum */
    long pull_n;          /* its sample index */
} fc_track;

static const fc_hist *hist_at(const fc_track *t, long i) {
    return &t->ring[i % t->cap];
}

static bool in_contact(const fc_track *t, double z_m, double x_m) {
    return x_m * t->cos_alpha + z_m < t->a0;
}

/* The first contact of the approach, at sample index i = t->n - 1: a snap-in when the
 * deflection got there by a jump; the event is the start of the jump. */
static void snap_check(fc_track *t) {
    const long i = t->n - 1, p = t->period;
    const fc_hist *now = hist_at(t, i);
    t->touched = true;
    t->contact_z_m = now->z_m;
    if (i < p) return;
    const fc_hist *was = hist_at(t, i - p);
    double dx = (now->x_m - was->x_m) * t->cos_alpha, dz = fabs(now->z_m - was->z_m);
    if (!(dx < 0 && -dx > JUMP_RATIO * dz)) return;
    double v_peak = 0.0;
    for (long j = i; j > i - p; j--)
        v_peak = fmax(v_peak, fabs(hist_at(t, j)->v_m_s));
    /* back to where the curve is no steeper than SNAP_SLOPE and the tip no faster than
     * JUMP_V_FRAC of the jump's peak (the latter for a ramp too fast to be quasi-static) */
    const double v_start = fmin(SNAP_SLOPE * t->speed / t->cos_alpha, JUMP_V_FRAC * v_peak);
    long j = i, oldest = i - t->cap + 1 > 0 ? i - t->cap + 1 : 0;
    while (j > oldest && fabs(hist_at(t, j)->v_m_s) > v_start)
        j--;
    const fc_hist *s = hist_at(t, j);
    t->snap =
        (fc_event){.have = true, .z_m = s->z_m, .x_m = s->x_m, .f_n = t->k * s->x_m, .jump = true};
}

/* Whether the tip jumped off after the pull-off sample: its deflection one lever period
 * later (or at the end of the run) against the Z travelled. */
static bool pull_jumped(const fc_track *t) {
    long i = t->pull_n + t->period;
    if (i > t->n - 1) i = t->n - 1;
    if (t->n - 1 - t->pull_n >= t->cap || i <= t->pull_n) return false;
    const fc_hist *a = hist_at(t, t->pull_n), *b = hist_at(t, i);
    double dx = (b->x_m - a->x_m) * t->cos_alpha, dz = fabs(b->z_m - a->z_m);
    return dx > 0 && dx > JUMP_RATIO * dz;
}

/* One sample into the tracker. */
static void track_push(fc_track *t, bool retract, double z_m, const afm_sample *s) {
    t->ring[t->n % t->cap] = (fc_hist){z_m, s->x_m, s->v_m_s};
    t->n++;
    bool c = in_contact(t, z_m, s->x_m);
    if (!retract) {
        if (c && !t->touched) snap_check(t);
        return;
    }
    if (c) t->retract_touched = true;
    if (!t->retract_touched) return;
    double f = t->k * s->x_m;
    if (!t->pull.have || f < t->pull.f_n) {
        t->pull = (fc_event){.have = true, .z_m = z_m, .x_m = s->x_m, .f_n = f};
        t->pull_n = t->n - 1;
        t->left = !c;
    } else if (!c) {
        t->left = true;
    }
    /* the jump test needs the period after the minimum: decided while it is in the ring */
    if (t->n - 1 == t->pull_n + t->period) t->pull.jump = pull_jumped(t);
}

/* One record of the curve. */
typedef struct {
    double z_m, x_m, f_n, gap_m;
    bool retract, contact;
} fc_point;

static const char *json_config = "-", *json_integrator = "-";

static int emit_point(const fc_point *p, bool json) {
    if (!json) {
        printf("%-8s %12.6f %12.6f %12.6f %12.6f %3d\n", p->retract ? "retract" : "approach",
               p->z_m * 1e9, p->x_m * 1e9, p->f_n * 1e9, p->gap_m * 1e9, p->contact ? 1 : 0);
        return 0;
    }
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "z_m", p->z_m);
    cJSON_AddStringToObject(o, "direction", p->retract ? "retract" : "approach");
    cJSON_AddNumberToObject(o, "deflection_m", p->x_m);
    cJSON_AddNumberToObject(o, "force_n", p->f_n);
    cJSON_AddNumberToObject(o, "gap_m", p->gap_m);
    cJSON_AddBoolToObject(o, "contact", p->contact);
    return afmt_json_emit(o);
}

static int emit_event(const char *name, const fc_event *e, bool json) {
    if (!json) {
        printf("# %s: Z %.6f nm, deflection %.6f nm, force %.6f nN%s\n", name, e->z_m * 1e9,
               e->x_m * 1e9, e->f_n * 1e9, e->jump ? " (jump)" : " (no jump)");
        return 0;
    }
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "event", name);
    cJSON_AddNumberToObject(o, "z_m", e->z_m);
    cJSON_AddNumberToObject(o, "deflection_m", e->x_m);
    cJSON_AddNumberToObject(o, "force_n", e->f_n);
    cJSON_AddBoolToObject(o, "jump", e->jump);
    return afmt_json_emit(o);
}

/* Least-squares slope of deflection against Z over the approach records in contact whose
 * force is in the upper half of their range, as the deflection up (away from the sample)
 * per Z down: 1 on a hard sample. NaN with fewer than 3 such records. */
static double contact_slope(const fc_point *p, int n, int *used) {
    double fmin = HUGE_VAL, fmax = -HUGE_VAL;
    for (int i = 0; i < n; i++)
        if (p[i].contact) {
            fmin = fmin < p[i].f_n ? fmin : p[i].f_n;
            fmax = fmax > p[i].f_n ? fmax : p[i].f_n;
        }
    const double fmid = 0.5 * (fmin + fmax);
    double sz = 0, sx = 0;
    int m = 0;
    for (int i = 0; i < n; i++)
        if (p[i].contact && p[i].f_n >= fmid) {
            sz += p[i].z_m;
            sx += p[i].x_m;
            m++;
        }
    *used = m;
    if (m < 3) return NAN;
    const double mz = sz / m, mx = sx / m;
    double szz = 0, szx = 0;
    for (int i = 0; i < n; i++)
        if (p[i].contact && p[i].f_n >= fmid) {
            szz += (p[i].z_m - mz) * (p[i].z_m - mz);
            szx += (p[i].z_m - mz) * (p[i].x_m - mx);
        }
    return szz > 0 ? -szx / szz : NAN; /* deflection up per Z down */
}

/* The static equilibrium k x = F(Z, x) of the far branch at z, by fixed-point iteration
 * from x = 0 (it converges where the force gradient is below k). 0 ok (*x), -1 none. */
static int far_equilibrium(const afm_force_params *fp, double k, double z, double *x) {
    double xi = 0.0;
    for (int it = 0; it < 500; it++) {
        double xn = afm_force_cons(fp, z, xi) / k;
        if (!isfinite(xn)) return -1;
        if (fabs(xn - xi) <= 1e-15 * fmax(fabs(xn), 1e-12)) {
            if (xn * fp->cos_alpha + z < fp->a0_m) return -1;
            *x = xn;
            return 0;
        }
        xi = xn;
    }
    return -1;
}

/* Put the tip at rest in the static equilibrium under the tip force at `from`, or at rest
 * where there is none; then dwell. 0 ok, -1 simulation failure. */
static int start_state(afm_sim *sim, double from, long dwell) {
    const afm_modal *m = afm_sim_model(sim);
    const afm_force_params *fp = afm_sim_forces(sim);
    double x, q[AFM_MAX_MODES] = {0}, qd[AFM_MAX_MODES] = {0};
    if (far_equilibrium(fp, m->static_stiffness_n_m, from, &x) == 0) {
        const double f = x * m->static_stiffness_n_m; /* the tip force there */
        for (int i = 0; i < m->n; i++)                /* static: w_i^2 q_i = tip_i F */
            q[i] = m->tip[i] * f / (m->omega_rad_s[i] * m->omega_rad_s[i]);
        if (afm_sim_set_state(sim, q, qd) != AFM_SIM_OK) return -1;
    }
    return afm_sim_run(sim, (int)dwell, NULL) == AFM_SIM_OK ? 0 : -1;
}

static void print_summary(const fc_track *t, const fc_opts *o, double samples, double model_s,
                          double ramp_per_period, double slope, int slope_n) {
    const double kc = slope < 1.0 && slope > 0.0 ? t->k * slope / (1.0 - slope) : NAN;
    if (!o->json) {
        printf("# spring constant k %.6g N/m (static tip stiffness); %.0f samples, %.6g s of "
               "model time\n",
               t->k, samples, model_s);
        if (t->touched)
            printf("# first contact of the approach at Z %.6f nm\n", t->contact_z_m * 1e9);
        else
            printf("# no contact on the approach\n");
        if (t->snap.have)
            printf("# snap-in: Z %.6f nm, deflection %.6f nm, force %.6f nN\n", t->snap.z_m * 1e9,
                   t->snap.x_m * 1e9, t->snap.f_n * 1e9);
        else
            printf("# snap-in: none%s\n", t->touched ? " (contact reached without a jump)" : "");
        if (t->pull.have)
            printf("# pull-off: Z %.6f nm, deflection %.6f nm; adhesion force %.6f nN (%s)\n",
                   t->pull.z_m * 1e9, t->pull.x_m * 1e9, t->pull.f_n * 1e9,
                   t->pull.jump ? "jumped off" : "left contact without a jump");
        else
            printf("# pull-off: none (%s)\n", t->retract_touched
                                                  ? "the tip is still in contact at --from"
                                                  : "no contact on the retract");
        if (isnan(slope))
            printf("# contact slope: none (fewer than 3 approach records in contact)\n");
        else
            printf("# contact slope %.6f (deflection up per Z down, over %d records; 1: hard "
                   "sample); contact stiffness %.6g N/m\n",
                   slope, slope_n, kc);
        return;
    }
    cJSON *o_ = cJSON_CreateObject(), *s = cJSON_AddObjectToObject(o_, "summary");
#define NUM_OR_NULL(key, ok, v)                                                                    \
    ((ok) && isfinite(v) ? cJSON_AddNumberToObject(s, key, v) : cJSON_AddNullToObject(s, key))
    cJSON_AddStringToObject(s, "config", json_config);
    cJSON_AddStringToObject(s, "integrator", json_integrator);
    cJSON_AddNumberToObject(s, "speed_m_s", o->speed_m_s);
    cJSON_AddNumberToObject(s, "points", o->points);
    cJSON_AddNumberToObject(s, "samples", samples);
    cJSON_AddNumberToObject(s, "model_time_s", model_s);
    cJSON_AddNumberToObject(s, "ramp_per_period_m", ramp_per_period);
    cJSON_AddNumberToObject(s, "spring_constant_n_m", t->k);
    NUM_OR_NULL("contact_z_m", t->touched, t->contact_z_m);
    NUM_OR_NULL("snap_in_z_m", t->snap.have, t->snap.z_m);
    NUM_OR_NULL("snap_in_deflection_m", t->snap.have, t->snap.x_m);
    NUM_OR_NULL("snap_in_force_n", t->snap.have, t->snap.f_n);
    NUM_OR_NULL("pull_off_z_m", t->pull.have, t->pull.z_m);
    NUM_OR_NULL("pull_off_deflection_m", t->pull.have, t->pull.x_m);
    NUM_OR_NULL("adhesion_force_n", t->pull.have, t->pull.f_n);
    if (t->pull.have)
        cJSON_AddBoolToObject(s, "pull_off_jump", t->pull.jump);
    else
        cJSON_AddNullToObject(s, "pull_off_jump");
    NUM_OR_NULL("contact_slope", true, slope);
    cJSON_AddNumberToObject(s, "contact_slope_points", slope_n);
    NUM_OR_NULL("contact_stiffness_n_m", true, kc);
#undef NUM_OR_NULL
    afmt_json_emit(o_);
}

int afm_cmd_force_curve(int argc, char **argv) {
    fc_opts o;
    int rc = afmt_opts_done("force-curve", parse_args(argc, argv, &o), fc_usage);
    if (rc >= 0) return rc;
    static afm_config cfg;
    char err[AFM_ERR_LEN];
    if (afmt_config_load("force-curve", o.config, &cfg)) return 2;
    cfg.drive.separation_m = o.from_m;
    cfg.thermal.enabled = false;
    if (afm_config_validate(&cfg, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin force-curve: %s\n", err);
        return 2;
    }
    const double fs = cfg.sim.sample_rate_hz;
    /* samples per leg: Z moves by speed / fs per sample (at most), an integer count */
    const double legs = ceil((o.from_m - o.to_m) / o.speed_m_s * fs);
    if (2.0 * legs > MAX_SAMPLES) {
        fprintf(stderr,
                "afmtwin force-curve: %.3g samples at %g m/s over %g m each way (%.3g s of "
                "model time); at most %.3g: raise --speed or narrow --from..--to\n",
                2.0 * legs, o.speed_m_s, o.from_m - o.to_m, 2.0 * legs / fs, MAX_SAMPLES);
        return 2;
    }
    if (legs < o.points - 1) {
        fprintf(stderr,
                "afmtwin force-curve: --points %d is more than the %.0f samples of a leg at "
                "%g m/s: lower --points or --speed\n",
                o.points, legs, o.speed_m_s);
        return 2;
    }
    const long n_leg = (long)legs;
    afm_sim *sim = afm_twin_create(&cfg, NULL, NULL, err, sizeof err);
    if (!sim) {
        fprintf(stderr, "afmtwin force-curve: %s\n", err);
        return 1;
    }
    for (int j = 0; j < cfg.drive.n_tones; j++) /* the drive off */
        if (afm_sim_set_tone(sim, j, 0.0, cfg.drive.tones[j].frequency_hz) != AFM_SIM_OK) {
            fprintf(stderr, "afmtwin force-curve: cannot switch tone %d off\n", j);
            afm_sim_destroy(&sim);
            return 1;
        }
    const afm_modal *m = afm_sim_model(sim);
    const afm_force_params *fp = afm_sim_forces(sim);
    static fc_track t;
    t = (fc_track){.k = m->static_stiffness_n_m,
                   .cos_alpha = fp->cos_alpha,
                   .a0 = fp->a0_m,
                   .speed = o.speed_m_s};
    const double f1 = m->omega_rad_s[0] / TWO_PI;
    t.period = (long)ceil(fs / f1);
    if (t.period < 2) t.period = 2;
    t.cap = 16 * t.period;
    if (t.cap < 256) t.cap = 256;
    if (t.cap > (1L << 20)) t.cap = 1L << 20;
    if (t.period >= t.cap) t.period = t.cap - 1;
    t.ring = calloc((size_t)t.cap, sizeof *t.ring);
    fc_point *app = calloc((size_t)o.points, sizeof *app);
    if (!t.ring || !app) {
        fprintf(stderr, "afmtwin force-curve: out of memory\n");
        free(t.ring);
        free(app);
        afm_sim_destroy(&sim);
        return 1;
    }
    json_config = o.config;
    json_integrator = afm_sim_integrator_name(sim);
    const double ramp_per_period = o.speed_m_s / f1;
    if (!o.json) {
        printf("# afmtwin force-curve %s: integrator %s, drive off, Z %.6g -> %.6g -> %.6g nm "
               "at %g m/s (%.4g pm per lever period of %.6g Hz), k %.6g N/m\n",
               o.config, json_integrator, o.from_m * 1e9, o.to_m * 1e9, o.from_m * 1e9, o.speed_m_s,
               ramp_per_period * 1e12, f1, t.k);
        printf("%-8s %12s %12s %12s %12s %3s\n", "# dir", "Z_nm", "defl_nm", "force_nN", "gap_nm",
               "c");
    }
    afmt_progress pg; /* opts.h: stderr, terminals only, after the first second */
    afmt_progress_init(&pg);
    int status = 0;
    if (start_state(sim, o.from_m, DWELL_PERIODS * t.period) != 0) {
        fprintf(stderr, "afmtwin force-curve: simulation failed at Z = %g m\n", o.from_m);
        status = 1;
    }
    afm_sample smp = {0}, last = {0};
    double samples = 0;
    bool snap_said = false;
    for (int leg = 0; leg < 2 && status == 0; leg++) {
        const bool retract = leg == 1;
        const double z0 = retract ? o.to_m : o.from_m, z1 = retract ? o.from_m : o.to_m;
        int next = 0; /* the next record */
        long prog = 0;
        for (long j = 0; j <= n_leg && status == 0; j++) {
            /* Z_j on the exact grid; the retract's j = 0 is the approach's last sample */
            const double z = j == n_leg ? z1 : z0 + (z1 - z0) * ((double)j / (double)n_leg);
            if (retract && j == 0) {
                smp = last;
            } else {
                if (afm_sim_set_separation(sim, z) != AFM_SIM_OK ||
                    afm_sim_run(sim, 1, &smp) != AFM_SIM_OK) {
                    afmt_progress_end(&pg);
                    fprintf(stderr, "afmtwin force-curve: simulation failed at Z = %g m\n", z);
                    status = 1;
                    break;
                }
                samples += 1;
                track_push(&t, retract, z, &smp);
            }
            /* record i at sample round(i n_leg / (points - 1)) */
            while (next < o.points &&
                   (long)llround((double)next * (double)n_leg / (o.points - 1)) == j) {
                fc_point p = {.z_m = z,
                              .x_m = smp.x_m,
                              .f_n = t.k * smp.x_m,
                              .gap_m = smp.x_m * t.cos_alpha + z,
                              .retract = retract};
                p.contact = p.gap_m < t.a0;
                if (!retract) app[next] = p;
                afmt_progress_hide(&pg); /* stdout on the same terminal */
                if (emit_point(&p, o.json) != 0) {
                    fprintf(stderr, "afmtwin force-curve: out of memory writing JSON\n");
                    status = 1;
                }
                afmt_progress_redraw(&pg);
                next++;
            }
            if (!retract && t.snap.have && !snap_said) { /* said when found */
                snap_said = true;
                afmt_progress_hide(&pg);
                if (emit_event("snap_in", &t.snap, o.json) != 0) status = 1;
                afmt_progress_redraw(&pg);
            }
            if (pg.tty && j - prog >= n_leg / 100 + 1) {
                prog = j;
                afmt_progress_update(&pg, "force-curve: %s %3.0f %%, Z %.4f nm",
                                     retract ? "retract" : "approach",
                                     100.0 * (double)j / (double)n_leg, z * 1e9);
            }
        }
        last = smp;
    }
    afmt_progress_end(&pg);
    if (status == 0) {
        if (t.pull.have && !t.left) t.pull.have = false; /* still in contact at --from */
        if (t.pull.have) {
            if (t.n - 1 < t.pull_n + t.period) t.pull.jump = pull_jumped(&t);
            if (emit_event("pull_off", &t.pull, o.json) != 0) status = 1;
        }
        int slope_n = 0;
        double slope = contact_slope(app, o.points, &slope_n);
        print_summary(&t, &o, samples, samples / fs, ramp_per_period, slope, slope_n);
    }
    fflush(stdout);
    free(t.ring);
    free(app);
    afm_sim_destroy(&sim);
    return status;
}
