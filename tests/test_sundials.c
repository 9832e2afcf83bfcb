/* SPDX-License-Identifier: MIT */
/* test_sundials.c -- the CVODE ("reference") and ARKODE ERK ("arkode-erk") backends of
 * afm_sim against closed-form linear steady states, across tone changes and NaN faults.
 *
 * Models are built by hand in the modal form of afm_model.h:
 *   q_i'' + 2 xi_i w_i q_i' + w_i^2 q_i = tip_i F - base_k_i ub - base_m_i ub''.
 * With F = 0 and ub = A sin(theta), theta = W t + phi, the steady state is
 *   q_i = A Im(H_i e^{i theta}),  H_i = (-base_k_i + base_m_i W^2) / (w_i^2 - W^2 + 2 i xi_i w_i
 * W), and the tip x = sum tip_i q_i = A |G| sin(theta + arg G), G = sum_i tip_i H_i. */
#include "integrators/afm_sim.h"
#include "check.h"
#include "fixtures.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

static const double two_pi = 6.283185307179586476925286766559;
static const double rate_hz = 14.06e6;

/* No tip force at all (every flag off). */

static afm_cfg_sim sim_cfg(afm_integrator_kind k) {
    afm_cfg_sim c;
    memset(&c, 0, sizeof c);
    c.sample_rate_hz = rate_hz;
    c.integrator = k;
    c.rt_substeps_contact = 0; /* backend default (ERK: 5) */
    c.ref_rtol = 0;            /* backend default (CVODE: 1e-10) */
    return c;
}

/* Analytic steady state of the linear model under drive d at time t. */
static void steady_state(const afm_modal *m, const afm_drive *d, double t, double *q, double *qd) {
    for (int i = 0; i < m->n; i++) {
        q[i] = qd[i] = 0.0;
        for (int j = 0; j < d->n; j++) {
            double w = d->omega_rad_s[j];
            double complex z =
                d->amp_m[j] * fixture_mode_h(m, i, w) * cexp(I * afm_drive_phase(d, j, t));
            q[i] += cimag(z);
            qd[i] += cimag(I * w * z);
        }
    }
}

static double analytic_x(const afm_modal *m, const afm_drive *d, double t) {
    double x = 0.0;
    for (int j = 0; j < d->n; j++) {
        double complex z = d->amp_m[j] * fixture_tip_gain(m, d->omega_rad_s[j]) *
                           cexp(I * afm_drive_phase(d, j, t));
        x += cimag(z);
    }
    return x;
}

/* Fit x = a sin(theta_j) + b cos(theta_j) over samples spanning whole periods of every
 * tone (exact for a sum of such tones): amplitude hypot(a, b), phase atan2(b, a). */
static void fit_tone(const afm_sample *o, int n, const afm_drive *d, int j, double *amp,
                     double *phase) {
    double a = 0, b = 0;
    for (int k = 0; k < n; k++) {
        double th = afm_drive_phase(d, j, o[k].t_s);
        a += o[k].x_m * sin(th);
        b += o[k].x_m * cos(th);
    }
    a *= 2.0 / n;
    b *= 2.0 / n;
    *amp = hypot(a, b);
    *phase = atan2(b, a);
}

static double wrap_pi(double a) {
    return remainder(a, two_pi);
}

#define NBUF 4000
static afm_sample buf[NBUF], buf2[NBUF];

/* Drive through the tones (freq as rate / divisor) and compare the steady state with the
 * FRF. start_at_rest: integrate from q = 0 and settle for n_settle samples (low-Q models);
 * else start on the analytic orbit. Tolerances: amplitude relative, phase in rad, samples
 * relative to the total amplitude. */
static void frf_case(const char *label, afm_integrator_kind kind, const afm_modal *m, int ntones,
                     const int *div, const double *amp_m, bool start_at_rest, int n_settle,
                     int n_fit, double tol) {
    afm_force_params f = fixture_no_forces();
    afm_cfg_drive dc;
    memset(&dc, 0, sizeof dc);
    dc.separation_m = 100e-9;
    dc.n_tones = ntones;
    for (int j = 0; j < ntones; j++) {
        dc.tones[j].amplitude_m = amp_m[j];
        dc.tones[j].frequency_hz = rate_hz / div[j];
        dc.tones[j].phase_rad = 0.3 + j;
    }
    afm_cfg_sim sc = sim_cfg(kind);
    char err[AFM_ERR_LEN], what[AFM_ERR_LEN + 256];
    afm_sim *s = afm_sim_create(m, &f, &dc, &sc, err, sizeof err);
    snprintf(what, sizeof what, "%s: create (%s)", label, s ? "ok" : err);
    if (!check_true(s != NULL, what)) return;
    const afm_drive *d = afm_sim_drive(s);
    if (!start_at_rest) {
        double q[AFM_MAX_MODES], qd[AFM_MAX_MODES];
        steady_state(m, d, 0.0, q, qd);
        check_true(afm_sim_set_state(s, q, qd) == AFM_SIM_OK, "set_state on the analytic orbit");
    }
    int rc = AFM_SIM_OK;
    for (int done = 0; done < n_settle && rc == AFM_SIM_OK; done += NBUF)
        rc = afm_sim_run(s, n_settle - done < NBUF ? n_settle - done : NBUF, NULL);
    if (rc == AFM_SIM_OK) rc = afm_sim_run(s, n_fit, buf);
    snprintf(what, sizeof what, "%s: run rc %d", label, rc);
    check_true(rc == AFM_SIM_OK, what);
    double xamp = 0.0, emax = 0.0;
    for (int j = 0; j < ntones; j++)
        xamp += d->amp_m[j] * cabs(fixture_tip_gain(m, d->omega_rad_s[j]));
    for (int k = 0; k < n_fit; k++)
        emax = fmax(emax, fabs(buf[k].x_m - analytic_x(m, d, buf[k].t_s)));
    snprintf(what, sizeof what, "%s: max |x - x_analytic| / amplitude", label);
    check_abs(emax / xamp, 0.0, tol, what);
    for (int j = 0; j < ntones; j++) {
        double a, ph;
        fit_tone(buf, n_fit, d, j, &a, &ph);
        double complex g = fixture_tip_gain(m, d->omega_rad_s[j]);
        snprintf(what, sizeof what, "%s: tone %d (%.4g Hz) amplitude (m)", label, j,
                 d->omega_rad_s[j] / two_pi);
        check_rel(a, d->amp_m[j] * cabs(g), tol, what);
        /* The integrators control the error of the sum, so a weak tone's phase is only as
         * good as tol times (total amplitude / its amplitude). */
        double share = xamp / (d->amp_m[j] * cabs(g));
        snprintf(what, sizeof what, "%s: tone %d phase error (rad)", label, j);
        check_abs(wrap_pi(ph - carg(g)), 0.0, tol * share, what);
    }
    afm_sim_destroy(&s);
    check_true(s == NULL, "destroy clears the handle");
}

/* (2) A frequency change mid-run: the state is untouched by the change, the first sample
 * after it shows no jump, and the continuation equals a fresh run started from the same
 * state with the new tone (phase-continuous) to within the integrator's accuracy. */
static void tone_change_case(const char *label, afm_integrator_kind kind, double tol) {
    afm_modal m = fixture_model(4, 0, 0);
    afm_force_params f = fixture_no_forces();
    afm_cfg_drive dc;
    memset(&dc, 0, sizeof dc);
    dc.separation_m = 100e-9;
    dc.n_tones = 1;
    dc.tones[0].amplitude_m = 0.1e-9;
    dc.tones[0].frequency_hz = rate_hz / 38;
    afm_cfg_sim sc = sim_cfg(kind);
    char err[AFM_ERR_LEN], what[AFM_ERR_LEN + 256];
    afm_sim *s = afm_sim_create(&m, &f, &dc, &sc, err, sizeof err);
    if (!check_true(s != NULL, "tone change: create")) return;
    double q[AFM_MAX_MODES], qd[AFM_MAX_MODES], q2[AFM_MAX_MODES], qd2[AFM_MAX_MODES];
    steady_state(&m, afm_sim_drive(s), 0.0, q, qd);
    afm_sim_set_state(s, q, qd);
    const int n0 = 380, n1 = 400;
    check_true(afm_sim_run(s, n0, buf) == AFM_SIM_OK, "tone change: run before");
    afm_sim_get_state(s, q, qd);
    double t0 = afm_sim_time(s);
    const double f2 = rate_hz / 40, a2 = 0.07e-9;
    check_true(afm_sim_set_tone(s, 0, a2, f2) == AFM_SIM_OK, "tone change: set_tone accepted");
    afm_sim_get_state(s, q2, qd2);
    bool same = afm_sim_time(s) == t0;
    for (int i = 0; i < m.n; i++)
        same = same && q2[i] == q[i] && qd2[i] == qd[i];
    snprintf(what, sizeof what, "%s tone change: state and time unchanged by set_tone", label);
    check_true(same, what);
    double phase_at_change = afm_sim_drive(s)->phase_rad[0];
    check_true(afm_sim_run(s, n1, buf + n0) == AFM_SIM_OK, "tone change: run after");
    /* Jump: the step across the change against the largest step of the last period. */
    double dmax = 0.0;
    for (int k = n0 - 38; k < n0 - 1; k++)
        dmax = fmax(dmax, fabs(buf[k + 1].x_m - buf[k].x_m));
    snprintf(what, sizeof what, "%s tone change: |dx| across the change / largest |dx| before",
             label);
    check_abs(fabs(buf[n0].x_m - buf[n0 - 1].x_m) / dmax, 0.5, 0.5, what);
    /* Fresh run from the same state with the new tone starting at its continued phase. */
    dc.tones[0].amplitude_m = a2;
    dc.tones[0].frequency_hz = f2;
    dc.tones[0].phase_rad = phase_at_change;
    afm_sim *r = afm_sim_create(&m, &f, &dc, &sc, err, sizeof err);
    if (!check_true(r != NULL, "tone change: create fresh run")) return;
    afm_sim_set_state(r, q, qd);
    check_true(afm_sim_run(r, n1, buf2) == AFM_SIM_OK, "tone change: fresh run");
    double xamp = 0.0, emax = 0.0;
    for (int k = 0; k < n0 + n1; k++)
        xamp = fmax(xamp, fabs(buf[k].x_m));
    for (int k = 0; k < n1; k++)
        emax = fmax(emax, fabs(buf[n0 + k].x_m - buf2[k].x_m));
    snprintf(what, sizeof what, "%s tone change: continuation vs fresh run, max |dx| / amplitude",
             label);
    check_abs(emax / xamp, 0.0, tol, what);
    /* The model time runs on: t = t0 + k dt. */
    snprintf(what, sizeof what, "%s tone change: sample times continue", label);
    check_rel(buf[n0 + n1 - 1].t_s, t0 + n1 / rate_hz, 1e-12, what);
    afm_sim_destroy(&r);
    afm_sim_destroy(&s);
}

/* (3) A tip force that turns NaN in contact (Hertz coefficient NaN): the run fails with
 * an error, the state is reset to rest with time kept, and after moving the sample away
 * the same handle runs normally. Then a model that is NaN everywhere (base_m), which
 * fails every run without crashing. */
static void nan_case(const char *label, afm_integrator_kind kind) {
    afm_modal m = fixture_model(1, 0, 0);
    afm_force_params f = fixture_no_forces();
    f.vdw_contact = true;
    f.a0_m = 0.476e-9;
    f.vdw_coef = 1.52e-19 * 8e-9 / 6.0;
    f.f_adhesion_n = f.vdw_coef / (f.a0_m * f.a0_m);
    f.hertz_coef = NAN;
    afm_cfg_drive dc;
    memset(&dc, 0, sizeof dc);
    dc.separation_m = 20e-9; /* the 42.7 nm orbit reaches the sample */
    dc.n_tones = 1;
    dc.tones[0].amplitude_m = 0.1e-9;
    dc.tones[0].frequency_hz = rate_hz / 38;
    afm_cfg_sim sc = sim_cfg(kind);
    char err[AFM_ERR_LEN], what[AFM_ERR_LEN + 256];
    afm_sim *s = afm_sim_create(&m, &f, &dc, &sc, err, sizeof err);
    if (!check_true(s != NULL, "nan: create")) return;
    double q[AFM_MAX_MODES], qd[AFM_MAX_MODES];
    steady_state(&m, afm_sim_drive(s), 0.0, q, qd);
    double bad[AFM_MAX_MODES];
    memcpy(bad, q, sizeof bad);
    bad[0] = NAN;
    check_true(afm_sim_set_state(s, bad, qd) == AFM_SIM_EINVAL, "nan: set_state rejects NaN");
    afm_sim_set_state(s, q, qd);
    int rc = afm_sim_run(s, 76, buf);
    snprintf(what, sizeof what, "%s nan: run into NaN contact force fails (rc %d)", label, rc);
    check_true(rc == AFM_SIM_ESOLVER || rc == AFM_SIM_EBLOWUP, what);
    afm_sim_get_state(s, q, qd);
    snprintf(what, sizeof what, "%s nan: state reset to rest, time kept (t = %.3g s)", label,
             afm_sim_time(s));
    check_true(q[0] == 0.0 && qd[0] == 0.0 && afm_sim_time(s) > 0.0, what);
    check_true(afm_sim_set_separation(s, 1e-6) == AFM_SIM_OK, "nan: move the sample away");
    rc = afm_sim_run(s, 380, buf);
    snprintf(what, sizeof what, "%s nan: same handle runs again out of contact (rc %d)", label, rc);
    check_true(rc == AFM_SIM_OK && isfinite(buf[379].x_m) && fabs(buf[379].x_m) > 1e-9, what);
    afm_sim_destroy(&s);

    /* NaN everywhere in the model: every run fails cleanly, handle stays usable. */
    m.base_m[0] = NAN;
    f = fixture_no_forces();
    s = afm_sim_create(&m, &f, &dc, &sc, err, sizeof err);
    if (!check_true(s != NULL, "nan model: create")) return;
    int rc1 = afm_sim_run(s, 10, buf), rc2 = afm_sim_run(s, 10, buf);
    snprintf(what, sizeof what, "%s nan model: runs fail (rc %d, %d), no crash", label, rc1, rc2);
    check_true(rc1 < 0 && rc2 < 0, what);
    afm_sim_destroy(&s);
}

int main(void) {
    const int div1[1] = {38};
    const double amp1[1] = {0.1e-9};
    const int div2[2] = {38, 6};
    const double amp2[2] = {0.1e-9, 0.5e-9};
    afm_modal m1 = fixture_model(1, 0, 0), m1lo = fixture_model(1, 10, 0),
              m4 = fixture_model(4, 0, 0);
    /* Tolerances. CVODE at rtol 1e-10 over ~30 periods of a Q 427 oscillator: the global
     * error grows about linearly with the number of steps (~1e4 here), so ~1e-7 of the
     * amplitude is expected (measured 2e-7); 1e-6 leaves room. BDF and Adams at 1e-12 agree
     * to 1e-7 in numerics.md. ERK, 5 substeps of the order-4 table: w h = 0.033 for the
     * 370 kHz mode, so a linear run is good to ~1e-6 (measured 2e-6); 1e-3 is the level
     * numerics.md measured while tapping, which a linear run must not exceed. */
    frf_case("cvode 1 mode Q 427, analytic start", AFM_INTEGRATOR_REFERENCE, &m1, 1, div1, amp1,
             false, 760, 380, 1e-6);
    frf_case("cvode 1 mode Q 10, from rest", AFM_INTEGRATOR_REFERENCE, &m1lo, 1, div1, amp1, true,
             38 * 150, 380, 1e-6);
    frf_case("cvode 4 modes, 2 tones", AFM_INTEGRATOR_REFERENCE, &m4, 2, div2, amp2, false, 228,
             570, 1e-6);
    frf_case("erk 1 mode Q 427, analytic start", AFM_INTEGRATOR_ARKODE_ERK, &m1, 1, div1, amp1,
             false, 760, 380, 1e-3);
    frf_case("erk 1 mode Q 10, from rest", AFM_INTEGRATOR_ARKODE_ERK, &m1lo, 1, div1, amp1, true,
             38 * 150, 380, 1e-3);
    frf_case("erk 4 modes, 2 tones", AFM_INTEGRATOR_ARKODE_ERK, &m4, 2, div2, amp2, false, 228, 570,
             1e-3);
    tone_change_case("cvode", AFM_INTEGRATOR_REFERENCE, 1e-7);
    tone_change_case("erk", AFM_INTEGRATOR_ARKODE_ERK, 1e-9);
    nan_case("cvode", AFM_INTEGRATOR_REFERENCE);
    nan_case("erk", AFM_INTEGRATOR_ARKODE_ERK);
    return check_done();
}
