/* SPDX-License-Identifier: MIT */
/* test_fm.c -- FM-AFM control (issue 32, runner/afm_fm.h) on a lumped 1-DOF probe with van
 * der Waals attraction only:
 *  (a) the PLL locks from a 1 kHz offset within the settling its bandwidth predicts, holds
 *      the free resonance, follows a small frequency kick with the designed time constant,
 *      and the amplitude controller holds its set-point with the drive G^-1 A_set; with an
 *      unreachable set-point (the NCO window too narrow) it reports the lock lost;
 *  (b) at small amplitude the frequency shift is -(f0 / 2k) dF/dz of the model's own tip
 *      force (forces/afm_force.h) at the tip's rest gap, within 1 % over the attractive
 *      range;
 *  (c) at large amplitude (5 nm, 10x the closest gap) the frequency shift curve inverted
 *      with the Sader-Jarvis formula (analysis/afm_sader.h) gives back the model's
 *      conservative force within a few percent, on a synthetic curve (the first-order
 *      perturbation integral) and on the twin's own FM approach;
 *  the fm config group's checks (ranges, the lock-in margin rule, unknown keys). */
#include "analysis/afm_sader.h"
#include "config/afm_config.h"
#include "estimators/afm_lockin.h"
#include "forces/afm_force.h"
#include "integrators/afm_sim.h"
#include "runner/afm_fm.h"
#include "runner/afm_twin.h"
#include "check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846
#define CAP 4096

/* k N/m, f0 300 kHz, Q 300, vdW (Ha 1.29e-19 J, R 10 nm, a0 0.24 nm), no dissipation in
 * the tip force, Z and tone 0 filled in by the caller. */
static const char *conf_fmt = "model = { kind = \"lumped\"; lumped = { stiffness_n_m = %g; "
                              "resonance_hz = 300e3; }; quality_factor = [300.0]; };\n"
                              "forces = { inclination_deg = 0.0; radius_m = 1e-8;\n"
                              "  vdw_contact = { hamaker_j = 1.29e-19; a0_m = 2.4e-10; "
                              "reduced_modulus_pa = 7e10; }; };\n"
                              "drive = { separation_m = %g; tones = ( { amplitude_m = %g; "
                              "frequency_hz = %.17g; } ); };\n"
                              "sim = { sample_rate_hz = 14.06e6; integrator = \"rt\"; "
                              "rt_scheme = \"accurate\"; };\n"
                              "lockin = { time_constant_s = 1e-4; order = 4; };\n"
                              "fm = { %s };\n";

static afm_config cfg;
static afm_sample buf[CAP];
static afm_lockin lockin;

static int load(double k, double z, double ae, double fe, const char *fm) {
    char text[2048], err[AFM_ERR_LEN];
    snprintf(text, sizeof text, conf_fmt, k, z, ae, fe, fm);
    if (afm_config_parse(text, "test_fm", &cfg, err, sizeof err)) {
        printf("config: %s\n", err);
        return -1;
    }
    return 0;
}

/* Run n samples open loop through the lock-in. */
static int open_loop(afm_sim *s, long n) {
    const afm_drive *d = afm_sim_drive(s);
    while (n > 0) {
        int k = n > CAP ? CAP : (int)n;
        if (afm_sim_run(s, k, buf) != AFM_SIM_OK) return -1;
        for (int i = 0; i < k; i++)
            afm_lockin_push(&lockin, buf[i].x_m, afm_drive_phase(d, 0, buf[i].t_s));
        n -= k;
    }
    return 0;
}

static void test_lock(void) {
    char err[AFM_ERR_LEN];
    const double f0 = 300e3, off = 1000.0, a_set = 10e-12;
    if (load(40.0, 1e-6, a_set / 300.0, f0 + off, "amplitude_setpoint_m = 1e-11;")) {
        check_true(false, "lock: config loads");
        return;
    }
    afm_modal m;
    afm_sim *s = afm_twin_create(&cfg, &m, NULL, err, sizeof err);
    if (!s || afm_lockin_init(&lockin, &cfg.lockin, afm_sim_dt(s), err, sizeof err)) {
        check_true(false, err);
        return;
    }
    afm_fm_plant p;
    afm_fm_plant_of(&m, &p);
    check_rel(p.f0_hz, f0, 1e-12, "plant: f0 of the lumped model");
    check_rel(p.q, 300.0, 1e-12, "plant: Q");
    check_rel(p.gain, 300.0, 1e-9, "plant: |G(f0)| = Q for the lumped model");
    /* steady at the 1 kHz offset first (20 envelope time constants) */
    const double tau_c = p.q / (PI * p.f0_hz);
    open_loop(s, (long)(20 * tau_c * cfg.sim.sample_rate_hz));
    afm_fm f;
    if (afm_fm_init(&f, &cfg.fm, &cfg.lockin, &p, cfg.sim.sample_rate_hz, f0 + off, f0 + off,
                    cfg.drive.tones[0].amplitude_m, err, sizeof err)) {
        check_true(false, err);
        return;
    }
    /* the prediction: the lock-in's delay (order tau), the first-order loop from the linear
     * error K_phi x 1 kHz down to the threshold, then the lock time inside the window */
    const double wc = 2 * PI * cfg.fm.pll_bandwidth_hz;
    const double t_pred = cfg.lockin.order * cfg.lockin.time_constant_s +
                          log(f.k_phi_deg_hz * off / cfg.fm.lock_threshold_deg) / wc +
                          f.lock_time_s;
    const double t_upd = cfg.fm.update_samples / cfg.sim.sample_rate_hz;
    long n_max = (long)(0.2 / t_upd);
    for (long u = 0; u < n_max && f.lock != AFM_FM_LOCKED; u++)
        if (afm_fm_run(&f, s, &lockin, buf, CAP, 1, NULL, NULL, err, sizeof err)) break;
    printf("# lock from +%g Hz: locked after %.3f ms, predicted %.3f ms (bandwidth %g Hz, "
           "kp %.4g Hz/deg, ki %.4g Hz/(deg s), lock time %.3f ms)\n",
           off, f.t_lock_s * 1e3, t_pred * 1e3, cfg.fm.pll_bandwidth_hz, f.kp, f.ki,
           f.lock_time_s * 1e3);
    check_true(f.lock == AFM_FM_LOCKED, "lock: the PLL locks from a 1 kHz offset");
    check_true(f.t_lock_s <= 1.2 * t_pred,
               "lock: within 1.2 x the settling its bandwidth predicts");
    check_true(f.t_lock_s >= 0.8 * t_pred, "lock: not before 0.8 x the prediction");
    check_true(fabs(f.phase_error_deg) <= cfg.fm.lock_threshold_deg,
               "lock: the phase error is inside the threshold when locked");
    /* hold: the free resonance (lag 90 exactly at f0 for the lumped model) */
    afm_fm_means mn;
    if (afm_fm_settle(&f, s, &lockin, buf, CAP, (long)(0.005 / t_upd), 40, 1e-4, 1e-5, NULL, NULL,
                      &mn, err, sizeof err))
        check_true(false, err);
    printf("# settled: f %.6f Hz (f0 %.6f), shift from the start %.4f Hz, A %.6g m, drive %.6g "
           "m, phase error %.3g deg, %d windows\n",
           mn.freq_hz, f0, mn.shift_hz, mn.amplitude_m, mn.drive_m, mn.phase_error_deg, mn.windows);
    check_true(mn.settled && mn.lock == AFM_FM_LOCKED, "hold: settled and locked");
    check_abs(mn.freq_hz, f0, 0.01, "hold: the PLL sits on the free resonance (Hz)");
    check_abs(mn.shift_hz, -off, 0.01, "hold: the shift from the start frequency is -1 kHz");
    check_rel(mn.amplitude_m, a_set, 1e-4, "amplitude: the set-point is held");
    check_rel(mn.drive_m, a_set / p.gain, 1e-3, "amplitude: the drive is A_set / |G(f0)|");
    /* cost: the lock-in restarts its phase tracker at each NCO step (afm_lockin_retune), so
     * that it rebuilds its tables once per step, not once per sample */
    afm_fm_run(&f, s, &lockin, buf, CAP, 20, NULL, NULL, err, sizeof err);
    open_loop(s, cfg.fm.update_samples); /* one update's samples after the last NCO step */
    printf("# lock-in table rebuilds since the last NCO step: %lld\n", lockin.trk.rate_changes);
    check_true(lockin.trk.rate_changes >= 1 && lockin.trk.rate_changes <= 4 && lockin.trk.locked,
               "cost: 1 to 4 lock-in table rebuilds per NCO step, then the fast path "
               "(tracker retuned)");
    /* a small kick of the integrator: the frequency returns with the designed time constant
     * (1 / wc, plus the lock-in's delay) */
    const double kick = 5.0;
    f.df_i_hz += kick;
    double t_e = NAN;
    for (long u = 0; u < (long)(0.05 / t_upd); u++) {
        afm_fm_run(&f, s, &lockin, buf, CAP, 1, NULL, NULL, err, sizeof err);
        if (isnan(t_e) && fabs(f.freq_hz - f0) <= kick * 0.36787944117144233) t_e = (u + 1) * t_upd;
    }
    double t_want = 1.0 / wc + cfg.lockin.order * cfg.lockin.time_constant_s;
    printf("# kick of %g Hz: back to 1/e after %.3f ms; 1/wc + order tau = %.3f ms\n", kick,
           t_e * 1e3, t_want * 1e3);
    check_rel(t_e, t_want, 0.25, "bandwidth: a kick decays to 1/e in 1/(2 pi bw) + order tau");
    check_abs(f.freq_hz, f0, 0.01, "bandwidth: and settles back on f0");
    /* an amplitude set-point step of 1 %: a first-order response of 1 / (2 pi bw) (plus the
     * lock-in's delay), as the derived amplitude gains promise */
    const double a_new = 1.01 * a_set;
    afm_fm_hold_amplitude(&f, a_new);
    double t_a = NAN;
    for (long u = 0; u < (long)(0.05 / t_upd); u++) {
        afm_fm_run(&f, s, &lockin, buf, CAP, 1, NULL, NULL, err, sizeof err);
        if (isnan(t_a) && fabs(f.amplitude_m - a_new) <= 0.01 * a_set * 0.36787944117144233)
            t_a = (u + 1) * t_upd;
    }
    double t_awant = 1.0 / (2 * PI * cfg.fm.amplitude_bandwidth_hz) +
                     cfg.lockin.order * cfg.lockin.time_constant_s;
    printf("# amplitude step of 1 %%: within 1/e after %.3f ms; 1/(2 pi bw) + order tau = %.3f "
           "ms\n",
           t_a * 1e3, t_awant * 1e3);
    check_rel(t_a, t_awant, 0.25,
              "amplitude bandwidth: a set-point step settles to 1/e in "
              "1/(2 pi bw) + order tau");
    check_rel(f.amplitude_m, a_new, 1e-4, "amplitude bandwidth: and holds the new set-point");
    afm_sim_destroy(&s);

    /* unreachable: the NCO may move 200 Hz, the resonance is 1 kHz away */
    if (load(40.0, 1e-6, a_set / 300.0, f0 + off, "max_shift_hz = 200.0;")) return;
    s = afm_twin_create(&cfg, &m, NULL, err, sizeof err);
    afm_lockin_init(&lockin, &cfg.lockin, afm_sim_dt(s), err, sizeof err);
    open_loop(s, (long)(20 * tau_c * cfg.sim.sample_rate_hz));
    afm_fm_init(&f, &cfg.fm, &cfg.lockin, &p, cfg.sim.sample_rate_hz, f0 + off, f0 + off,
                cfg.drive.tones[0].amplitude_m, err, sizeof err);
    bool ever_locked = false;
    for (long u = 0; u < (long)(0.1 / t_upd); u++) {
        afm_fm_run(&f, s, &lockin, buf, CAP, 1, NULL, NULL, err, sizeof err);
        ever_locked |= f.lock == AFM_FM_LOCKED;
    }
    printf("# unreachable: state %s, f %.3f Hz (limit %g), phase error %.2f deg\n",
           afm_fm_lock_name(f.lock), f.freq_hz, f0 + off - 200.0, f.phase_error_deg);
    check_true(f.lock == AFM_FM_LOST && !ever_locked,
               "unreachable set-point: reported lost, never locked");
    check_true(f.f_limited && fabs(f.freq_hz - (f0 + off - 200.0)) < 1e-9,
               "unreachable set-point: the NCO sits at its limit");
    afm_sim_destroy(&s);
}

/* The lock states on synthetic phase errors (afm_fm_update fed the lag directly): LOCKED
 * held for the lock time outside the window, then LOST; LOST back inside is ACQUIRING at
 * once (not LOST while the loop tracks), LOST again if it leaves before LOCKED, LOCKED after
 * the lock time inside. Errors of 0 and 3 deg against the 2 deg window; the NCO moves at
 * most ki x 3 deg x 2 lock times ~ 0.3 kHz of its 5 kHz, so never limited. */
static int feed(afm_fm *f, double e_deg, int n, double dt_s) {
    for (int i = 0; i < n; i++)
        afm_fm_update(f, f->a_set_m, f->c.phase_setpoint_deg + e_deg, dt_s);
    return (int)f->lock;
}

static void test_lock_states(void) {
    char err[AFM_ERR_LEN];
    const double f0 = 300e3, a_set = 10e-12;
    if (load(40.0, 1e-6, a_set / 300.0, f0, "amplitude_setpoint_m = 1e-11;")) {
        check_true(false, "lock states: config loads");
        return;
    }
    afm_modal m;
    afm_sim *s = afm_twin_create(&cfg, &m, NULL, err, sizeof err);
    if (!s) {
        check_true(false, err);
        return;
    }
    afm_fm_plant p;
    afm_fm_plant_of(&m, &p);
    afm_sim_destroy(&s);
    afm_fm f;
    if (afm_fm_init(&f, &cfg.fm, &cfg.lockin, &p, cfg.sim.sample_rate_hz, f0, f0,
                    cfg.drive.tones[0].amplitude_m, err, sizeof err)) {
        check_true(false, err);
        return;
    }
    const double dt = f.lock_time_s / 10.0; /* 10 updates per lock time (+1: rounding) */
    const int in = 0, out = 3;
    check_true(feed(&f, in, 5, dt) == AFM_FM_ACQUIRING, "lock states: acquiring at first");
    check_true(feed(&f, in, 6, dt) == AFM_FM_LOCKED, "lock states: locked after the lock time");
    check_true(feed(&f, out, 5, dt) == AFM_FM_LOCKED,
               "lock states: locked held for less than the lock time outside");
    check_true(feed(&f, out, 6, dt) == AFM_FM_LOST, "lock states: lost after the lock time out");
    check_true(feed(&f, in, 1, dt) == AFM_FM_ACQUIRING,
               "lock states: lost and back inside: acquiring at the first update");
    check_true(feed(&f, out, 1, dt) == AFM_FM_LOST,
               "lock states: a re-acquisition leaving the window is lost at once");
    check_true(feed(&f, in, 9, dt) == AFM_FM_ACQUIRING,
               "lock states: re-acquiring until the lock time inside");
    check_true(feed(&f, in, 2, dt) == AFM_FM_LOCKED && !f.f_limited,
               "lock states: locked again after the lock time inside (NCO off its limit)");
}

/* The tip's rest displacement under the tip force: k x = F(Z + x). */
static double rest_x(const afm_force_params *fp, double k, double z) {
    double x = 0.0;
    for (int i = 0; i < 200; i++)
        x = afm_force_cons(fp, z, x) / k;
    return x;
}

/* The twin of cfg with the file's lock-in reset and FM loops started at f0 (the tests of the
 * frequency shift against the force law); NULL after a failed check. */
static afm_sim *open_fm_twin(double f0, afm_force_params *fp, afm_fm *f) {
    char err[AFM_ERR_LEN];
    afm_modal m;
    afm_sim *s = afm_twin_create(&cfg, &m, fp, err, sizeof err);
    if (!s || afm_lockin_init(&lockin, &cfg.lockin, afm_sim_dt(s), err, sizeof err)) {
        check_true(false, err);
        return NULL;
    }
    afm_fm_plant p;
    afm_fm_plant_of(&m, &p);
    afm_fm_init(f, &cfg.fm, &cfg.lockin, &p, cfg.sim.sample_rate_hz, f0, f0,
                cfg.drive.tones[0].amplitude_m, err, sizeof err);
    return s;
}

/* the PLL's shifts at test_gradient's Z, for the self-excited drive to agree with */
#define NZ_GRAD 9
static double pll_shift_hz[NZ_GRAD];
static const double grad_zs[NZ_GRAD] = {6e-9, 4e-9,    3e-9,   2e-9,  1.5e-9,
                                        1e-9, 0.75e-9, 0.6e-9, 0.5e-9};

static void test_gradient(void) {
    char err[AFM_ERR_LEN];
    const double f0 = 300e3, k = 200.0, a_set = 10e-12;
    const double *zs = grad_zs;
    const int nz = NZ_GRAD;
    if (load(k, zs[0], a_set / 300.0, f0,
             "amplitude_setpoint_m = 1e-11; pll_bandwidth_hz = 200.0; "
             "amplitude_bandwidth_hz = 100.0;")) {
        check_true(false, "gradient: config loads");
        return;
    }
    afm_force_params fp;
    afm_fm f;
    afm_sim *s = open_fm_twin(f0, &fp, &f);
    if (!s) return;
    const double t_upd = cfg.fm.update_samples / cfg.sim.sample_rate_hz;
    double worst = 0.0, worst_x = 0.0;
    int n_ok = 0;
    printf("# %8s %12s %12s %12s %9s %9s\n", "Z_nm", "gap_nm", "shift_Hz", "-f0F'/2k_Hz", "rel",
           "A_pm");
    for (int i = 0; i < nz; i++) {
        afm_sim_set_separation(s, zs[i]);
        afm_fm_means mn;
        if (afm_fm_settle(&f, s, &lockin, buf, CAP, (long)(0.005 / t_upd), 60, 2e-3, 1e-4, NULL,
                          NULL, &mn, err, sizeof err)) {
            check_true(false, err);
            break;
        }
        double x = rest_x(&fp, k, zs[i]), h = 1e-13;
        double grad = (afm_force_cons(&fp, zs[i] + h, x) - afm_force_cons(&fp, zs[i] - h, x)) /
                      (2 * h); /* dF/dz at the rest gap Z + x */
        double want = -(f0 / (2 * k)) * grad, rel = (mn.freq_hz - f0) / want - 1.0;
        /* the linear resonance of the stiffness k - F' itself (no first-order expansion) */
        double exact = f0 * (sqrt(1.0 - grad / k) - 1.0);
        double rel_x = (mn.freq_hz - f0) / exact - 1.0;
        if (fabs(rel_x) > worst_x) worst_x = fabs(rel_x);
        printf("  %8.3f %12.5f %12.5f %12.5f %9.2e %9.4f%s\n", zs[i] * 1e9, (zs[i] + x) * 1e9,
               mn.freq_hz - f0, want, rel, mn.amplitude_m * 1e12, mn.settled ? "" : " unsettled");
        if (!mn.settled || mn.lock != AFM_FM_LOCKED) break;
        pll_shift_hz[i] = mn.freq_hz - f0;
        n_ok++;
        if (fabs(rel) > worst) worst = fabs(rel);
    }
    check_true(n_ok == nz, "gradient: settled and locked at every Z (6 nm down to 0.5 nm)");
    printf("# worst |shift / (-(f0/2k) dF/dz) - 1| = %.3g\n", worst);
    check_abs(worst, 0.0, 0.01,
              "gradient: shift = -(f0/2k) dF/dz within 1 % over the attractive range");
    printf("# worst |shift / (f0 (sqrt(1 - F'/k) - 1)) - 1| = %.3g\n", worst_x);
    check_abs(worst_x, 0.0, 1e-3,
              "gradient: shift = f0 (sqrt(1 - F'/k) - 1) within 0.1 % (small amplitude)");
    afm_sim_destroy(&s);
}

/* The first-order (Giessibl) shift of vdW at rest gap D and amplitude A: -(f0 / (2 pi k A))
 * int F(D + A cos p) cos p dp. */
static double vdw_shift(double C, double D, double A, double f0, double k) {
    const int n = 4096;
    double s = 0.0;
    for (int i = 0; i < n; i++) {
        double ph = 2 * PI * i / n, d = D + A * cos(ph);
        s += -C / (d * d) * cos(ph);
    }
    return -(f0 / (2 * PI * k * A)) * s * (2 * PI / n);
}

/* The closest-approach grid (m): 0.05 nm steps to 2 nm, then coarser to 80 nm. */
static int sader_grid(double *z, int max, double z0, double z1, double fine) {
    int n = 0;
    for (double t = z0; t < z1 && n < max; t += t < 2e-9    ? fine
                                                : t < 5e-9  ? 2 * fine
                                                : t < 15e-9 ? 10 * fine
                                                            : 40 * fine)
        z[n++] = t;
    return n;
}

static void test_sader_synthetic(void) {
    const double C = 1.29e-19 * 1e-8 / 6, A = 5e-9, f0 = 3e5, k = 200;
    static double z[512], df[512], F[512];
    int n = sader_grid(z, 512, 0.3e-9, 80e-9, 0.05e-9);
    for (int i = 0; i < n; i++)
        df[i] = vdw_shift(C, z[i] + A, A, f0, k);
    check_true(afm_sader_jarvis(z, df, n, f0, k, A, F) == 0, "sader: inverts a synthetic curve");
    double worst = 0.0;
    for (int i = 0; i < n; i++)
        if (z[i] >= 0.5e-9 && z[i] <= 5e-9)
            worst = fmax(worst, fabs(F[i] / (-C / (z[i] * z[i])) - 1));
    printf("# sader, synthetic vdW curve (A 5 nm): worst |F / F_vdW - 1| over 0.5-5 nm = %.3g\n",
           worst);
    check_abs(worst, 0.0, 0.01, "sader: synthetic vdW curve, force within 1 % over 0.5-5 nm");
    check_true(isnan(F[n - 1]) && isnan(F[n - 2]), "sader: the last two points are NAN");
    double zb[3] = {1e-9, 1e-9, 2e-9};
    check_true(afm_sader_jarvis(zb, df, 3, f0, k, A, F) == -1, "sader: a non-increasing z refused");
}

typedef struct {
    double x_min;
} min_track;

static void track_min(void *ctx, const afm_sim *s, const afm_sample *smp, int n) {
    (void)s;
    min_track *t = ctx;
    for (int i = 0; i < n; i++)
        if (smp[i].x_m < t->x_min) t->x_min = smp[i].x_m;
}

static void test_sader_twin(void) {
    char err[AFM_ERR_LEN];
    const double f0 = 300e3, k = 200.0, A = 5e-9;
    static double zg[512], zc[512], df[512], F[512];
    int n = sader_grid(zg, 512, 0.5e-9, 45e-9, 0.1e-9);
    if (load(k, zg[n - 1] + A, A / 300.0, f0,
             "amplitude_setpoint_m = 5e-9; pll_bandwidth_hz = 200.0; "
             "amplitude_bandwidth_hz = 100.0;")) {
        check_true(false, "sader twin: config loads");
        return;
    }
    afm_force_params fp;
    afm_fm f;
    afm_sim *s = open_fm_twin(f0, &fp, &f);
    if (!s) return;
    const double t_upd = cfg.fm.update_samples / cfg.sim.sample_rate_hz;
    const long win = (long)(0.004 / t_upd);
    int ok = 0;
    for (int j = n - 1; j >= 0; j--) { /* approach: far to near */
        afm_sim_set_separation(s, zg[j] + A);
        afm_fm_means mn;
        if (afm_fm_settle(&f, s, &lockin, buf, CAP, win, 40, 2e-4, 1e-4, NULL, NULL, &mn, err,
                          sizeof err) ||
            !mn.settled)
            break;
        min_track t = {HUGE_VAL};
        afm_fm_run(&f, s, &lockin, buf, CAP, win, track_min, &t, err, sizeof err);
        zc[j] = zg[j] + A + t.x_min; /* the gap at the lower turning point */
        df[j] = f.freq_hz - f0;
        ok++;
    }
    check_true(ok == n, "sader twin: the FM approach settles at every Z");
    if (ok == n && afm_sader_jarvis(zc, df, n, f0, k, A, F) == 0) {
        double worst = 0.0;
        printf("# %8s %12s %12s %12s %9s\n", "z_nm", "df_Hz", "F_SJ_nN", "F_model_nN", "rel");
        for (int j = 0; j < n - 2; j++) {
            double fm = afm_force_cons(&fp, zc[j], 0.0), rel = F[j] / fm - 1;
            if (zc[j] <= 5e-9) worst = fmax(worst, fabs(rel));
            if (j % 4 == 0 || zc[j] <= 0.8e-9)
                printf("  %8.4f %12.5f %12.6f %12.6f %9.2e\n", zc[j] * 1e9, df[j], F[j] * 1e9,
                       fm * 1e9, rel);
        }
        printf("# sader on the twin's FM curve (A 5 nm): worst |F_SJ / F_model - 1| over z "
               "0.5-5 nm = %.3g\n",
               worst);
        check_abs(
            worst, 0.0, 0.03,
            "sader twin: the inverted FM curve gives the model's force within 3 % (0.5-5 nm)");
    } else {
        check_true(false, "sader twin: the closest-approach gaps increase");
    }
    afm_sim_destroy(&s);
}

static void test_config(void) {
    char err[AFM_ERR_LEN];
    static afm_config c;
    afm_config_defaults(&c);
    check_true(!c.fm.enabled && c.fm.phase_setpoint_deg == 90.0,
               "config: fm off by default, set-point 90 deg");
    static const struct {
        const char *fm, *want;
    } bad[] = {
        {"phase_setpoint_deg = 180.0;", "fm.phase_setpoint_deg"},
        {"pll_bandwidth_hz = 0.0;", "fm.pll_bandwidth_hz"},
        {"pll_bandwidth_hz = 2000.0;", "too fast for the lock-in"},
        {"amplitude_bandwidth_hz = 5000.0;", "fm.amplitude_bandwidth_hz"},
        {"max_shift_hz = -1.0;", "fm.max_shift_hz"},
        {"lock_threshold_deg = 90.0;", "fm.lock_threshold_deg"},
        {"drive_max_m = 2e-6;", "fm.drive_max_m"},
        {"update_samples = 0;", "fm.update_samples"},
        {"amplitude_kp = -1.0;", "fm.amplitude_kp"},
        {"pll_gain = 1.0;", "unknown key"},
        {"update_samples = 1.5;", "expected an integer"},
        {"drive = \"loop\";", "fm.drive"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char text[2048], what[1024];
        snprintf(text, sizeof text, conf_fmt, 40.0, 1e-8, 1e-13, 3e5, bad[i].fm);
        afm_config_defaults(&c);
        static afm_config before;
        before = c;
        int rc = afm_config_parse(text, "t.conf", &c, err, sizeof err);
        snprintf(what, sizeof what, "config: '%s' refused with '%s' (%s), nothing changed",
                 bad[i].fm, bad[i].want, err);
        check_true(rc == -1 && strstr(err, bad[i].want) && strstr(err, "t.conf:") &&
                       memcmp(&c, &before, sizeof c) == 0,
                   what);
    }
    char text[2048];
    snprintf(text, sizeof text, conf_fmt, 40.0, 1e-8, 1e-13, 3e5,
             "pll_bandwidth_hz = 150.0; enabled = false;");
    check_true(afm_config_parse(text, "t.conf", &c, err, sizeof err) == 0 && !c.fm.enabled &&
                   c.fm.pll_bandwidth_hz == 150.0,
               "config: a valid fm group loads (enabled = false honoured)");
    /* afm_fm_init applies the margin rule whether or not the group is enabled */
    afm_fm f;
    afm_fm_plant p = {3e5, 300, 300};
    afm_cfg_fm fc = c.fm;
    fc.pll_bandwidth_hz = 2000.0;
    check_true(afm_fm_init(&f, &fc, &c.lockin, &p, 14.06e6, 3e5, 3e5, 1e-13, err, sizeof err) ==
                       -1 &&
                   strstr(err, "too fast"),
               "afm_fm_init: a bandwidth too fast for the lock-in is refused");
    fc = c.fm;
    check_true(afm_fm_init(&f, &fc, &c.lockin, &p, 14.06e6, 3e5, 3e5 + 6000.0, 1e-13, err,
                           sizeof err) == -1 &&
                   strstr(err, "max_shift_hz"),
               "afm_fm_init: a start outside the NCO window is refused");
}

/* Self-excited drive (fm.drive = "self", runner/afm_fm_self.h): free, from a 1 kHz offset,
 * the oscillation runs where the lag is 90 deg -- the lumped model's resonance_hz exactly
 * (phase of 1 / (w0^2 - w^2 + 2 i xi w0 w) is -90 deg at w0; the damped natural frequency
 * f0 sqrt(1 - xi^2) is 0.42 Hz lower, the amplitude peak 0.83 Hz) -- with the amplitude at
 * its set-point and the drive A_set / |G(f0)|; then the frequency shift on the attractive
 * range against -(f0/2k) dF/dz (1 %, as the PLL) and against the PLL's own shifts. */
static void test_self(void) {
    char err[AFM_ERR_LEN];
    const double f0 = 300e3, off = 1000.0, a_set = 10e-12;
    if (load(40.0, 1e-6, a_set / 300.0, f0 + off,
             "drive = \"self\"; amplitude_setpoint_m = 1e-11;")) {
        check_true(false, "self: config loads");
        return;
    }
    check_true(cfg.fm.drive == AFM_FM_DRIVE_SELF, "self: fm.drive = \"self\" loads");
    afm_modal m;
    afm_sim *s = afm_twin_create(&cfg, &m, NULL, err, sizeof err);
    if (!s || afm_lockin_init(&lockin, &cfg.lockin, afm_sim_dt(s), err, sizeof err)) {
        check_true(false, err);
        return;
    }
    afm_fm_plant p;
    afm_fm_plant_of(&m, &p);
    const double tau_c = p.q / (PI * p.f0_hz);
    open_loop(s, (long)(20 * tau_c * cfg.sim.sample_rate_hz));
    afm_fm f;
    if (afm_fm_init(&f, &cfg.fm, &cfg.lockin, &p, cfg.sim.sample_rate_hz, f0 + off, f0 + off,
                    cfg.drive.tones[0].amplitude_m, err, sizeof err)) {
        check_true(false, err);
        return;
    }
    const double t_upd = cfg.fm.update_samples / cfg.sim.sample_rate_hz;
    afm_fm_means mn;
    if (afm_fm_settle(&f, s, &lockin, buf, CAP, (long)(0.005 / t_upd), 60, 1e-4, 1e-5, NULL, NULL,
                      &mn, err, sizeof err))
        check_true(false, err);
    printf("# self, free from +%g Hz: f %.6f Hz (f0 %.6f, damped natural %.6f), A %.6g m, drive "
           "%.6g m, lag - 90 %.3g deg, %s, %d windows, delay %d samples\n",
           off, mn.freq_hz, f0, f0 * sqrt(1 - 1 / (4 * p.q * p.q)), mn.amplitude_m, mn.drive_m,
           mn.phase_error_deg, afm_fm_lock_name(mn.lock), mn.windows, f.self.delay_samples);
    check_true(mn.settled && mn.lock == AFM_FM_LOCKED, "self: settled and locked");
    /* 0.01 Hz: the PLL test's, 1/40 of the gap to the damped natural frequency */
    check_abs(mn.freq_hz, f0, 0.01,
              "self: free oscillation at f0 (lag 90 deg) within 0.01 Hz, not at f0 sqrt(1 - xi^2)");
    check_rel(mn.amplitude_m, a_set, 1e-4, "self: the amplitude set-point is held");
    check_rel(mn.drive_m, a_set / p.gain, 1e-3, "self: the drive is A_set / |G(f0)|");
    check_abs(mn.phase_error_deg, 0.0, 0.1, "self: the lock-in sees lag 90 deg (0.1 deg)");
    afm_sim_destroy(&s);

    /* the frequency shift against the force gradient and the PLL (test_gradient first) */
    const double k = 200.0;
    if (load(k, grad_zs[0], a_set / 300.0, f0,
             "drive = \"self\"; amplitude_setpoint_m = 1e-11; pll_bandwidth_hz = 200.0; "
             "amplitude_bandwidth_hz = 100.0;")) {
        check_true(false, "self gradient: config loads");
        return;
    }
    afm_force_params fp;
    s = open_fm_twin(f0, &fp, &f);
    if (!s) return;
    double worst = 0.0, worst_pll = 0.0, worst_pll_hz = 0.0;
    int n_ok = 0;
    printf("# %8s %12s %12s %12s %9s %9s\n", "Z_nm", "self_Hz", "pll_Hz", "-f0F'/2k_Hz", "rel",
           "rel_pll");
    for (int i = 0; i < NZ_GRAD; i++) {
        afm_sim_set_separation(s, grad_zs[i]);
        if (afm_fm_settle(&f, s, &lockin, buf, CAP, (long)(0.005 / t_upd), 60, 2e-3, 1e-4, NULL,
                          NULL, &mn, err, sizeof err)) {
            check_true(false, err);
            break;
        }
        double x = rest_x(&fp, k, grad_zs[i]), h = 1e-13;
        double grad =
            (afm_force_cons(&fp, grad_zs[i] + h, x) - afm_force_cons(&fp, grad_zs[i] - h, x)) /
            (2 * h);
        double want = -(f0 / (2 * k)) * grad, rel = (mn.freq_hz - f0) / want - 1.0;
        double rel_pll = (mn.freq_hz - f0) / pll_shift_hz[i] - 1.0;
        printf("  %8.3f %12.5f %12.5f %12.5f %9.2e %9.2e%s\n", grad_zs[i] * 1e9, mn.freq_hz - f0,
               pll_shift_hz[i], want, rel, rel_pll, mn.settled ? "" : " unsettled");
        if (!mn.settled || mn.lock != AFM_FM_LOCKED) break;
        n_ok++;
        worst = fmax(worst, fabs(rel));
        worst_pll = fmax(worst_pll, fabs(rel_pll));
        worst_pll_hz = fmax(worst_pll_hz, fabs(mn.freq_hz - f0 - pll_shift_hz[i]));
        check_rel(mn.amplitude_m, a_set, 1e-3, "self gradient: amplitude at the set-point");
    }
    check_true(n_ok == NZ_GRAD, "self gradient: settled and locked at every Z (6 nm to 0.5 nm)");
    printf("# self: worst |shift / (-(f0/2k) dF/dz) - 1| = %.3g, |shift / PLL shift - 1| = %.3g, "
           "|shift - PLL shift| = %.3g Hz\n",
           worst, worst_pll, worst_pll_hz);
    check_abs(worst, 0.0, 0.01, "self gradient: shift = -(f0/2k) dF/dz within 1 % (as the PLL)");
    /* both settled to 2e-3 Hz per window: they may differ by the two tolerances */
    check_abs(worst_pll_hz, 0.0, 4e-3, "self gradient: shift = the PLL's within 4 mHz at every Z");
    check_abs(worst_pll, 0.0, 1e-3, "self gradient: shift = the PLL's within 0.1 %");
    afm_sim_destroy(&s);
}

int main(void) {
    test_config();
    test_lock();
    test_lock_states();
    test_gradient();
    test_self();
    test_sader_synthetic();
    test_sader_twin();
    return check_done();
}
