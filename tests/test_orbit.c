/* SPDX-License-Identifier: MIT */
/* test_orbit.c -- afm_orbit on synthetic sample series: harmonics, phases, periodicity,
 * contacts. No integrator: the series are closed-form functions of the drive phase. */
#include "forces/afm_force.h"
#include "beam/afm_model.h"
#include "estimators/afm_orbit.h"
#include "check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static const double pi = 3.14159265358979323846;
static const double fs = 14.06e6;  /* OBD sample rate of the thesis experiments */
static const double fe = 84.053e3; /* Table 4.1 F3/F4: 167.27... samples per period */

/* x = sum a_j cos(q_j theta + ph_j), theta the drive phase of tone 0 (q_j may be
 * fractional: subharmonics); f likewise with its own terms. */
typedef struct {
    int n;
    double a[4], q[4], ph[4];
} series;

static double series_x(const series *s, double th, double w, double *v) {
    double x = 0, dx = 0;
    for (int j = 0; j < s->n; j++) {
        x += s->a[j] * cos(s->q[j] * th + s->ph[j]);
        dx -= s->a[j] * s->q[j] * w * sin(s->q[j] * th + s->ph[j]);
    }
    if (v) *v = dx;
    return x;
}

static void fill(afm_sample *buf, int n, double t_first, const afm_drive *d, const series *xs,
                 const series *fsr) {
    for (int i = 0; i < n; i++) {
        double t = t_first + (double)i / fs, th = afm_drive_phase(d, 0, t), v;
        buf[i].t_s = t;
        buf[i].x_m = series_x(xs, th, d->omega_rad_s[0], &buf[i].v_m_s);
        buf[i].f_n = fsr ? series_x(fsr, th, d->omega_rad_s[0], &v) : 0.0;
        buf[i].theta_rad = 0;
        buf[i].base_m = afm_drive_x(d, t, NULL);
    }
}

static afm_drive make_drive(double phase_rad) {
    afm_cfg_drive c = {.separation_m = 30e-9, .n_tones = 1};
    c.tones[0].amplitude_m = 0.7e-9;
    c.tones[0].frequency_hz = fe;
    c.tones[0].phase_rad = phase_rad;
    afm_drive d;
    afm_drive_init(&d, &c);
    return d;
}

static double deg(double r) {
    return r * 180.0 / pi;
}

/* Smallest angular distance in degrees, for phase checks across the +-180 wrap. */
static double ang_err(double got, double want) {
    double e = fmod(got - want, 360.0);
    if (e > 180) e -= 360;
    if (e < -180) e += 360;
    return e;
}

static void test_tones(void) {
    /* Thesis App. E.4 (Fig. E.3, point F4): phi_1 = 20.4 deg, phi_6 = 34.8 deg, amplitudes of
     * Table E.2 F4. Hand computation of eq. E.12-E.13: mod(6 (180 - 20.4) + 34.8, 360) =
     * mod(992.4, 360) = 272.4 deg, the Table E.2 value. */
    const double a1 = 2.3921e-8, a6 = 1.0226e-9, p1 = 20.4 * pi / 180, p6 = 34.8 * pi / 180;
    series xs = {2, {a1, a6}, {1, 6}, {p1, p6}};
    series fsr = {3, {3e-8, 2e-8, 5e-9}, {1, 2, 6}, {-2.0, 1.0, 3.0}};
    /* Drive with a start phase and a phase-continuous frequency change before the record, so
     * that period boundaries are not at t = k / fe. */
    afm_drive d = make_drive(1.1);
    afm_drive_set_tone(&d, 3.3e-6, 0, 0.7e-9, fe * 0.97);
    afm_drive_set_tone(&d, 7.7e-6, 0, 0.7e-9, fe);
    int n = 5 * 168;
    afm_sample *buf = malloc((size_t)n * sizeof *buf);
    fill(buf, n, 1.0e-5 + 0.37 / fs, &d, &xs, &fsr);

    int ks[] = {1, 2, 6, 17};
    afm_orbit o;
    char err[AFM_ERR_LEN] = "";
    int rc = afm_orbit_analyse(buf, n, &d, 1, -1.0, ks, 4, &o, err, sizeof err);
    check_true(rc == 0, "analyse tone + 6th harmonic");
    if (rc) {
        printf("  %s\n", err);
        free(buf);
        return;
    }
    /* Requested 1e-6 relative and 1e-4 deg; the corrected trapezoid reaches ~1e-10 here
     * ((12 we dt)^10 with 12 we dt = 0.45 at the stencil ends). */
    check_rel(o.fe_hz, fe, 1e-12, "fe from the drive");
    check_rel(o.harmonics[0].x_amp_m, a1, 1e-6, "|x|_1 (m)");
    check_abs(ang_err(o.harmonics[0].x_phase_deg, 20.4), 0, 1e-4, "phi_1 (deg)");
    check_rel(o.harmonics[2].x_amp_m, a6, 1e-6, "|x|_6 (m)");
    check_abs(ang_err(o.harmonics[2].x_phase_deg, 34.8), 0, 1e-4, "phi_6 (deg)");
    check_abs(o.harmonics[1].x_amp_m, 0, 1e-6 * a1, "|x|_2 = 0");
    check_abs(o.harmonics[3].x_amp_m, 0, 1e-6 * a1, "|x|_17 = 0");
    check_abs(o.harmonics[2].phase_diff_deg, 272.4, 1e-4, "(dphi)_S6 eq. E.13 (deg)");
    check_abs(o.harmonics[0].phase_diff_deg, 180.0, 1e-4, "(dphi)_S1 = pi (deg)");
    check_rel(o.harmonics[0].f_amp_n, 3e-8, 1e-6, "|F|_1 (N)");
    check_abs(ang_err(o.harmonics[0].f_phase_deg, deg(-2.0)), 0, 1e-4, "F phase 1 (deg)");
    check_rel(o.harmonics[1].f_amp_n, 2e-8, 1e-6, "|F|_2 (N)");
    check_abs(ang_err(o.harmonics[1].f_phase_deg, deg(1.0)), 0, 1e-4, "F phase 2 (deg)");
    check_rel(o.harmonics[2].f_amp_n, 5e-9, 1e-6, "|F|_6 (N)");
    check_abs(ang_err(o.harmonics[2].f_phase_deg, deg(3.0)), 0, 1e-4, "F phase 6 (deg)");
    /* Extrema by a dense scan of the closed form (1e6 points per period: step error
     * ~ (2 pi 6 / 1e6)^2 / 8 relative); the analysis refines samples by Hermite cubics. */
    double xlo = HUGE_VAL, xhi = -HUGE_VAL;
    for (int i = 0; i < 1000000; i++) {
        double x = series_x(&xs, 2 * pi * i / 1e6, 1, NULL);
        xlo = x < xlo ? x : xlo;
        xhi = x > xhi ? x : xhi;
    }
    /* Cubic Hermite error bound h^4 max|x^(4)| / 384 (6.8e-15 m here, 2.8e-7 relative). */
    double w = 2 * pi * fe, h4 = pow(1.0 / fs, 4);
    double herm = h4 * (a1 * pow(w, 4) + a6 * pow(6 * w, 4)) / 384.0;
    check_abs(o.min_deflection_m, xlo, herm, "min deflection (m)");
    check_abs(o.max_deflection_m, xhi, herm, "max deflection (m)");
    printf("  |x|_1 rel err %.2e, |x|_6 rel err %.2e, dphi_6 %.10f deg\n",
           fabs(o.harmonics[0].x_amp_m - a1) / a1, fabs(o.harmonics[2].x_amp_m - a6) / a6,
           o.harmonics[2].phase_diff_deg);

    /* Window start is a drive-phase-0 instant. */
    double th = afm_drive_phase(&d, 0, o.t_start_s) / (2 * pi);
    check_abs(th - round(th), 0, 1e-9, "window starts at drive phase 0");

    /* Pure tone, every window length p = 1..4. */
    series pure = {1, {a1}, {1}, {p1}};
    fill(buf, n, 1.0e-5 + 0.37 / fs, &d, &pure, NULL);
    for (int p = 1; p <= 3; p++) {
        rc = afm_orbit_analyse(buf, n, &d, p, -1.0, ks, 1, &o, err, sizeof err);
        char what[64];
        snprintf(what, sizeof what, "pure tone |x|_1 over %d periods", p);
        check_true(rc == 0 && fabs(o.harmonics[0].x_amp_m - a1) <= 1e-6 * a1, what);
    }
    check_true(afm_orbit_periodicity(buf, n, &d, 2, -HUGE_VAL, 1e-6, NULL) == 1,
               "pure tone: periodicity 1");

    /* Bad input changes nothing and says why. */
    check_true(afm_orbit_analyse(buf, n, &d, 0, -1.0, ks, 1, &o, err, sizeof err) == -1,
               "p = 0 rejected");
    check_true(afm_orbit_analyse(buf, n, &d, 5, -1.0, ks, 1, &o, err, sizeof err) == -1,
               "window longer than buffer rejected");
    int bad_k = 0;
    check_true(afm_orbit_analyse(buf, n, &d, 1, -1.0, &bad_k, 1, &o, err, sizeof err) == -1,
               "k = 0 rejected");
    buf[10].t_s += 0.5 / fs;
    check_true(afm_orbit_analyse(buf, n, &d, 1, -1.0, ks, 1, &o, err, sizeof err) == -1,
               "non-uniform sample times rejected");
    free(buf);
}

static void test_periodicity(void) {
    afm_drive d = make_drive(0.3);
    int n = 20 * 168;
    afm_sample *buf = malloc((size_t)n * sizeof *buf);
    double change;
    /* Period doubling: a 1/2-subharmonic of 5% of the harmonic. */
    series p2 = {2, {2.4e-8, 1.2e-9}, {1, 0.5}, {0.2, 0.7}};
    fill(buf, n, 2e-7, &d, &p2, NULL);
    check_true(afm_orbit_periodicity(buf, n, &d, 8, -HUGE_VAL, 1e-6, &change) == 2,
               "1/2-subharmonic: p = 2");
    printf("  p = 2 mismatch %.2e\n", change);
    afm_orbit o;
    char err[AFM_ERR_LEN];
    int k1 = 1;
    check_true(afm_orbit_analyse(buf, n, &d, 2, -1, &k1, 1, &o, err, sizeof err) == 0 &&
                   fabs(o.harmonics[0].x_amp_m - 2.4e-8) <= 1e-6 * 2.4e-8,
               "p = 2 window: subharmonic does not leak into |x|_1");
    /* A 1/3 subharmonic. */
    series p3 = {2, {2.4e-8, 1e-10}, {1, 1.0 / 3.0}, {0.2, 0.7}};
    fill(buf, n, 2e-7, &d, &p3, NULL);
    check_true(afm_orbit_periodicity(buf, n, &d, 8, -HUGE_VAL, 1e-6, NULL) == 3,
               "1/3-subharmonic: p = 3");
    /* Quasi-periodic (incommensurate second tone): no p <= 8. */
    series qp = {2, {2.4e-8, 1e-9}, {1, 0.5 * (sqrt(5.0) - 1.0)}, {0.2, 0.7}};
    fill(buf, n, 2e-7, &d, &qp, NULL);
    check_true(afm_orbit_periodicity(buf, n, &d, 8, -HUGE_VAL, 1e-6, &change) == 0,
               "quasi-periodic: no periodicity");
    check_true(change > 1e-3, "quasi-periodic: mismatch reported");
    /* A 17th harmonic of 1% (thesis Table E.4 has 0.85%): the degree-7 interpolation keeps
     * the mismatch of a period-1 signal far below 1e-6. */
    series h17 = {2, {2.4e-8, 2.4e-10}, {1, 17}, {0.2, 0.7}};
    fill(buf, n, 2e-7, &d, &h17, NULL);
    check_true(afm_orbit_periodicity(buf, n, &d, 8, -HUGE_VAL, 1e-6, &change) == 1,
               "harmonic 17 at 1%: p = 1");
    check_abs(change, 0, 1e-8, "harmonic 17 at 1%: mismatch");
    /* A contact-like kink: x = A cos(theta) + B s^2.5, s = max(0, xc - A cos(theta)), the
     * shape a Hertz force (a0 - d)^1.5 gives the displacement. Straddling interpolants are
     * skipped when the contact line is given. */
    double A = 2.4e-8, xc = -0.9 * A, B = 0.02 * A / pow(0.1 * A, 2.5), w = d.omega_rad_s[0];
    for (int i = 0; i < n; i++) {
        double t = 2e-7 + i / fs, th = afm_drive_phase(&d, 0, t);
        double x = A * cos(th), v = -A * w * sin(th), s = xc - x;
        buf[i].t_s = t;
        buf[i].x_m = x + (s > 0 ? B * pow(s, 2.5) : 0.0);
        buf[i].v_m_s = v + (s > 0 ? -2.5 * B * pow(s, 1.5) * v : 0.0);
        buf[i].f_n = buf[i].theta_rad = buf[i].base_m = 0;
    }
    double change_all;
    afm_orbit_periodicity(buf, n, &d, 1, -HUGE_VAL, 1e-6, &change_all);
    check_true(afm_orbit_periodicity(buf, n, &d, 8, xc, 1e-6, &change) == 1,
               "kinked orbit: p = 1 with the contact line given");
    check_abs(change, 0, 1e-8, "kinked orbit: mismatch away from the kink");
    printf("  kinked orbit: mismatch %.2e with the kink skipped, %.2e with it\n", change,
           change_all);
    /* Too short for p = 2 judged: 3 periods only. */
    fill(buf, n, 2e-7, &d, &p2, NULL);
    check_true(afm_orbit_periodicity(buf, 3 * 168, &d, 8, -HUGE_VAL, 1e-6, NULL) == 0,
               "3 periods cannot show p = 2");
    free(buf);
}

/* A parabola-shaped dip per period: x = x0 + c (tau - Te/2)^2 (tau time since the period
 * start), with the contact line crossed at tau = Te/2 - delta with velocity -2 c delta.
 * Hermite interpolation reproduces a quadratic exactly, so the crossing time and velocity
 * are exact up to the bisection (1e-15 of a step). */
static void test_contacts(void) {
    afm_drive d = make_drive(0.0);
    double te = 1.0 / fe, x0 = -31.352e-9, c = 50e-9 / (0.25 * te * te);
    double vc = -5.5534e-3, delta = -vc / (2 * c), xc = x0 + c * delta * delta;
    double fmax = 1.08321e-7, b = fmax / (delta * delta);
    int n = 4 * 168;
    afm_sample *buf = malloc((size_t)n * sizeof *buf);
    for (int i = 0; i < n; i++) {
        double t = 3e-7 + i / fs, th = afm_drive_phase(&d, 0, t);
        double tau = fmod(th, 2 * pi) / (2 * pi) * te - 0.5 * te;
        buf[i].t_s = t;
        buf[i].x_m = x0 + c * tau * tau;
        buf[i].v_m_s = 2 * c * tau;
        buf[i].f_n = fabs(tau) < delta ? fmax - b * tau * tau : -1e-9;
        buf[i].theta_rad = buf[i].base_m = 0;
    }
    afm_orbit o;
    char err[AFM_ERR_LEN];
    int k1 = 1;
    int rc = afm_orbit_analyse(buf, n, &d, 1, xc, &k1, 1, &o, err, sizeof err);
    check_true(rc == 0 && o.n_contacts == 1 && !o.contacts_truncated, "one contact per period");
    if (rc == 0 && o.n_contacts == 1) {
        check_rel(o.contacts[0].pre_contact_velocity_m_s, vc, 1e-9, "pre-contact velocity (m/s)");
        check_rel(o.contacts[0].t_in_s - o.t_start_s, 0.5 * te - delta, 1e-9,
                  "crossing time after period start (s)");
        check_rel(o.contacts[0].t_out_s - o.contacts[0].t_in_s, 2 * delta, 1e-9,
                  "contact duration (s)");
        check_rel(o.contacts[0].min_deflection_m, x0, 1e-12, "contact min deflection (m)");
        check_rel(o.contacts[0].max_force_n, fmax, 1e-12, "contact max force (N)");
        check_rel(o.min_deflection_m, x0, 1e-12, "orbit min deflection (m)");
        check_rel(o.max_force_n, fmax, 1e-12, "orbit max force (N)");
    }
    rc = afm_orbit_analyse(buf, n, &d, 2, xc, &k1, 1, &o, err, sizeof err);
    check_true(rc == 0 && o.n_contacts == 2, "two contacts over two periods");
    rc = afm_orbit_analyse(buf, n, &d, 1, x0 - 1e-9, &k1, 1, &o, err, sizeof err);
    check_true(rc == 0 && o.n_contacts == 0, "no contact when the line is below the dip");
    free(buf);
}

/* The dwell driver on a simulator: the lumped 1-DOF model far from the sample is linear,
 * x'' + 2 xi w0 x' + w0^2 x = w0^2 x_dit (afm_model.h, afm_cfg_lumped), so the settled
 * orbit must be A |H| cos(we t - 90 deg + arg H), H = w0^2 / (w0^2 - we^2 + 2 i xi w0 we). */
static void test_settle_linear(afm_integrator_kind kind, double tol_amp, double tol_deg) {
    /* Set-up as a caller of the engine does it (tools/cmd_sweep.c). */
    static afm_config cfg;
    afm_config_defaults(&cfg);
    cfg.model.kind = AFM_MODEL_LUMPED;
    cfg.model.lumped.stiffness_n_m = 40.0;
    cfg.model.lumped.resonance_hz = 300e3;
    cfg.model.n_damping = 1;
    cfg.model.damping_ratio[0] = 0.005; /* Q = 100 */
    cfg.forces.radius_m = 1e-8;
    cfg.drive.separation_m = 1e-4; /* 0.1 mm: no tip force reaches */
    cfg.drive.n_tones = 1;
    cfg.drive.tones[0].amplitude_m = 2e-10;
    cfg.drive.tones[0].frequency_hz = 310e3;
    cfg.sim.integrator = kind;
    char err[AFM_ERR_LEN], what[128];
    afm_modal m;
    afm_force_params f;
    afm_sim *s = NULL;
    if (afm_config_validate(&cfg, err, sizeof err) ||
        afm_model_build(&cfg.model, &m, err, sizeof err) ||
        afm_force_init(&f, &cfg.forces, 0, 0, err, sizeof err) ||
        !(s = afm_sim_create(&m, &f, &cfg.drive, &cfg.sim, err, sizeof err))) {
        check_true(false, "linear settle: set-up");
        printf("  %s\n", err);
        return;
    }
    int cap = afm_orbit_settle_capacity(fs, 300e3, AFM_ORBIT_MAX_P);
    afm_sample *buf = malloc((size_t)cap * sizeof *buf);
    afm_orbit_settler st;
    /* two steps of a sweep: the second one starts from the first one's orbit */
    double fe2[2] = {310e3, 305e3};
    for (int step = 0; step < 2; step++) {
        afm_sim_set_tone(s, 0, 2e-10, fe2[step]);
        int rc = afm_orbit_settle_begin(&st, buf, cap, AFM_ORBIT_MAX_P, 1e-10, s);
        while (rc == 0 && st.periods < 20000)
            rc = afm_orbit_settle_period(&st, s);
        snprintf(what, sizeof what, "%s %.0f Hz: settled with p = 1 (%d periods)",
                 afm_sim_integrator_name(s), fe2[step], st.periods);
        check_true(rc == 1 && st.p == 1, what);
        afm_orbit o;
        int k1 = 1;
        rc = afm_orbit_analyse(st.buf, st.n, afm_sim_drive(s), 1, -HUGE_VAL, &k1, 1, &o, err,
                               sizeof err);
        if (rc) printf("  %s\n", err);
        double w0 = 2 * pi * 300e3, we = 2 * pi * fe2[step];
        double re = w0 * w0 - we * we, im = 2 * 0.005 * w0 * we;
        double gain = w0 * w0 / hypot(re, im), arg = -atan2(im, re);
        snprintf(what, sizeof what, "%s %.0f Hz: |x|_1 = Ae |H| (m)", afm_sim_integrator_name(s),
                 fe2[step]);
        check_rel(rc == 0 ? o.harmonics[0].x_amp_m : NAN, 2e-10 * gain, tol_amp, what);
        snprintf(what, sizeof what, "%s %.0f Hz: phi_1 = arg H - 90 (deg)",
                 afm_sim_integrator_name(s), fe2[step]);
        check_abs(ang_err(o.harmonics[0].x_phase_deg, deg(arg) - 90.0), 0, tol_deg, what);
        check_true(o.n_contacts == 0, "no contact far from the sample");
    }
    free(buf);
    afm_sim_destroy(&s);
}

int main(void) {
    test_tones();
    test_periodicity();
    test_contacts();
    /* rt propagates the linear modes exactly out of contact (afm_rt.c); settling to 1e-10
     * per period leaves at most Q / pi * 1e-10 = 3e-9 of the orbit, so the analysis's own
     * 1e-6 / 1e-4 deg targets apply. */
    test_settle_linear(AFM_INTEGRATOR_RT, 1e-6, 1e-4);
    return check_done();
}
