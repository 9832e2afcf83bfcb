/* SPDX-License-Identifier: MIT */
/* test_estimators.c -- the streaming estimators (afm_harm, afm_lockin, afm_cycle) on
 * synthetic series with known answers, the lock-in on a linear 1-mode simulation, and the
 * phasors that replace per-sample sin/cos against afm_drive_phase. */
#include "config/afm_config.h"
#include "estimators/afm_cycle.h"
#include "forces/afm_drive.h"
#include "forces/afm_force.h"
#include "estimators/afm_harm.h"
#include "estimators/afm_lockin.h"
#include "beam/afm_model.h"
#include "integrators/afm_sim.h"
#include "check.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static const double pi = 3.14159265358979323846;
static const double fs = 14.06e6;  /* OBD sample rate of the thesis experiments */
static const double fe = 84.053e3; /* Table 4.1 F3/F4: 167.27... samples per period */

static double wrap_rad(double a) {
    a = fmod(a, 2 * pi);
    if (a > pi) a -= 2 * pi;
    if (a <= -pi) a += 2 * pi;
    return a;
}

/* ---- afm_harm ---- */

/* Period of exactly N samples: the result must equal the DFT of those N samples. */
static void test_harm_dft(int n0) {
    enum { N = 100, NP = 4 };
    const int ks[] = {1, 2, 3, 5, 7, 11};
    const double ax[] = {3e-8, 1e-9, 4e-10, 2e-10, 7e-11, 3e-11},
                 px[] = {0.3, -2.0, 1.1, 2.9, -0.7, 0.2};
    const double af[] = {5e-9, 3e-9, 2e-9, 1e-9, 5e-10, 2e-10},
                 pf[] = {-1.0, 0.5, 2.5, -2.9, 1.7, -0.1};
    const int nk = 6;
    static double x[N * NP + 200], f[N * NP + 200];
    int total = N * NP + n0 + 1;
    for (int n = 0; n < total; n++) {
        x[n] = 1e-9; /* a mean: must not leak into any k */
        f[n] = -2e-9;
        for (int j = 0; j < nk; j++) {
            x[n] += ax[j] * cos(2 * pi * ks[j] * (double)(n - n0) / N + px[j]);
            f[n] += af[j] * cos(2 * pi * ks[j] * (double)(n - n0) / N + pf[j]);
        }
    }
    afm_harm h;
    char err[AFM_ERR_LEN];
    check_true(afm_harm_init(&h, ks, nk, err, sizeof err) == 0, "harm init");
    int periods = 0;
    double max_amp = 0, max_ph = 0, max_fa = 0, max_fp = 0, max_pd = 0;
    for (int n = 0; n < total; n++) {
        /* theta of sample n: the first sample lies n0 samples after a boundary */
        double th = 2 * pi * (double)(n - n0) / N + 2 * pi * 7;
        int rc = afm_harm_push(&h, x[n], f[n], th);
        if (rc != 1) continue;
        periods++;
        /* the period just completed: samples [n - N, n) */
        double phi1 = 0;
        for (int j = 0; j < nk; j++) {
            double xr = 0, xi = 0, fr = 0, fi = 0;
            for (int i = 0; i < N; i++) {
                double a = 2 * pi * ks[j] * (double)i / N;
                xr += x[n - N + i] * cos(a);
                xi -= x[n - N + i] * sin(a);
                fr += f[n - N + i] * cos(a);
                fi -= f[n - N + i] * sin(a);
            }
            double amp = 2 * hypot(xr, xi) / N, ph = atan2(xi, xr);
            if (j == 0) phi1 = ph;
            double pd = fmod(ks[j] * (pi - phi1) + ph, 2 * pi);
            if (pd < 0) pd += 2 * pi;
            const afm_orbit_harmonic *o = &h.out.h[j];
            max_amp = fmax(max_amp, fabs(o->x_amp_m / amp - 1));
            max_ph = fmax(max_ph, fabs(wrap_rad(o->x_phase_deg * pi / 180 - ph)));
            max_fa = fmax(max_fa, fabs(o->f_amp_n / (2 * hypot(fr, fi) / N) - 1));
            max_fp = fmax(max_fp, fabs(wrap_rad(o->f_phase_deg * pi / 180 - atan2(fi, fr))));
            max_pd = fmax(max_pd, fabs(wrap_rad((o->phase_diff_deg * pi / 180) - pd)));
        }
    }
    char what[128];
    snprintf(what, sizeof what,
             "DFT: whole periods of %d samples (first sample %d after a boundary)", N, n0);
    /* NP + 1 boundaries pass; the first counts only if theta lands exactly on it */
    check_true(periods == NP || periods == NP - 1, what);
    /* 1e-9 requested; only rounding separates the two sums (~1e-13 for the smallest line) */
    check_abs(max_amp, 0, 1e-9, "DFT: deflection amplitudes, max rel diff");
    check_abs(max_ph, 0, 1e-9, "DFT: deflection phases, max diff (rad)");
    check_abs(max_fa, 0, 1e-9, "DFT: force amplitudes, max rel diff");
    check_abs(max_fp, 0, 1e-9, "DFT: force phases, max diff (rad)");
    check_abs(max_pd, 0, 1e-9, "DFT: phase_diff eq. E.13, max diff (rad)");
    check_true(h.out.samples > N - 1e-9 && h.out.samples < N + 1e-9,
               "DFT: period length N samples");
}

/* The DFT check for harmonic lists of 1 to 16 harmonics, with and without harmonic 1 (then
 * carried in an extra lane for phi_1), i.e. 1 to 5 groups of 4 lanes, fed by
 * afm_harm_push_n in blocks of 1..61 samples (what the chain runs); every line k = 1..17 is
 * in the signal. */
static void test_harm_dft_lanes(const int *ks, int nk, const char *what_list) {
    enum { N = 100, NP = 4, N0 = 13, KMAX = 17 };
    static double x[N * NP + N0 + 1], f[N * NP + N0 + 1], th[N * NP + N0 + 1];
    const int total = N * NP + N0 + 1;
    for (int n = 0; n < total; n++) {
        x[n] = 1e-9;
        f[n] = -2e-9;
        for (int k = 1; k <= KMAX; k++) {
            double a = 2 * pi * k * (double)(n - N0) / N;
            x[n] += 3e-8 / k * cos(a + 0.37 * k);
            f[n] += 5e-9 / (k * k) * cos(a - 0.61 * k);
        }
        th[n] = 2 * pi * (double)(n - N0) / N + 2 * pi * 3;
    }
    afm_harm h, hd; /* hd deferred: its polar form by afm_harm_polar, as the chain does */
    check_true(afm_harm_init(&h, ks, nk, NULL, 0) == 0, "harm init");
    afm_harm_init(&hd, ks, nk, NULL, 0);
    afm_harm_set_deferred(&hd, true);
    int periods = 0;
    bool same_deferred = true;
    long long rej = 0, rej_d = 0;
    double max_amp = 0, max_ph = 0, max_fa = 0, max_fp = 0, max_pd = 0;
    for (int n = 0, b = 0; n < total; b++) {
        int done, done_d, want = 1 + (b * 29) % 61;
        int m = want < total - n ? want : total - n;
        int md = afm_harm_push_n(&hd, x + n, f + n, th + n, m, &done_d, &rej_d);
        int c = afm_harm_push_n(&h, x + n, f + n, th + n, m, &done, &rej);
        n += c;
        same_deferred = same_deferred && md == c && done_d == done;
        if (!done) continue;
        periods++;
        afm_harm_polar(&hd, &hd.out);
        same_deferred = same_deferred && hd.out.samples == h.out.samples &&
                        !memcmp(hd.out.h, h.out.h, (size_t)nk * sizeof h.out.h[0]);
        /* sample n - 1 completed the period [n - 1 - N, n - 1); phi_1 from the DFT at k = 1 */
        const double *xp = x + n - 1 - N, *fp = f + n - 1 - N;
        double phi1 = 0;
        for (int j = -1; j < nk; j++) {
            int k = j < 0 ? 1 : ks[j];
            double xr = 0, xi = 0, fr = 0, fi = 0;
            for (int i = 0; i < N; i++) {
                double a = 2 * pi * k * (double)i / N;
                xr += xp[i] * cos(a);
                xi -= xp[i] * sin(a);
                fr += fp[i] * cos(a);
                fi -= fp[i] * sin(a);
            }
            double ph = atan2(xi, xr);
            if (j < 0) {
                phi1 = ph;
                continue;
            }
            double pd = fmod(k * (pi - phi1) + ph, 2 * pi);
            if (pd < 0) pd += 2 * pi;
            const afm_orbit_harmonic *o = &h.out.h[j];
            max_amp = fmax(max_amp, fabs(o->x_amp_m / (2 * hypot(xr, xi) / N) - 1) + (o->k != k));
            max_ph = fmax(max_ph, fabs(wrap_rad(o->x_phase_deg * pi / 180 - ph)));
            max_fa = fmax(max_fa, fabs(o->f_amp_n / (2 * hypot(fr, fi) / N) - 1));
            max_fp = fmax(max_fp, fabs(wrap_rad(o->f_phase_deg * pi / 180 - atan2(fi, fr))));
            max_pd = fmax(max_pd, fabs(wrap_rad((o->phase_diff_deg * pi / 180) - pd)));
        }
    }
    char what[160];
    snprintf(what, sizeof what, "DFT %s: %d periods through push_n, none rejected", what_list, NP);
    check_true(periods == NP && rej == 0 && h.out.n_harmonics == nk, what);
    snprintf(what, sizeof what, "DFT %s: deferred + afm_harm_polar = immediate, bit for bit",
             what_list);
    check_true(same_deferred && rej_d == 0, what);
    /* as test_harm_dft: rounding only (lines down to 5e-9 / 17^2 = 1.7e-11 of ~6e-8) */
    snprintf(what, sizeof what, "DFT %s: amplitudes x, F, max rel diff", what_list);
    check_abs(fmax(max_amp, max_fa), 0, 1e-9, what);
    snprintf(what, sizeof what, "DFT %s: phases x, F, phase_diff, max diff (rad)", what_list);
    check_abs(fmax(max_ph, fmax(max_fp, max_pd)), 0, 1e-9, what);
}

/* Non-integer samples per period, a pure tone locked to the drive phase, through a
 * phase-continuous frequency change: fractional-end trapezoid to ~1e-6. */
static void test_harm_fractional(void) {
    afm_cfg_drive c = {.separation_m = 30e-9, .n_tones = 1};
    c.tones[0].amplitude_m = 0.7e-9;
    c.tones[0].frequency_hz = fe;
    c.tones[0].phase_rad = 1.1;
    afm_drive d;
    afm_drive_init(&d, &c);
    const double a1 = 2.4e-8, p1 = 20.4 * pi / 180, a3 = 1e-9, p3 = -100 * pi / 180;
    const int ks[] = {1, 2, 3};
    afm_harm h;
    afm_harm_init(&h, ks, 3, NULL, 0);
    double e1 = 0, ep1 = 0, e3 = 0, ep3 = 0, e2 = 0, f1 = 0;
    int periods = 0;
    bool changed = false, straddle = false;
    for (long n = 0; n < 40 * 168; n++) {
        double t = 3.7e-6 + (double)n / fs;
        if (!changed && t > 100e-6) { /* 3 % step in fe, phase-continuous */
            afm_drive_set_tone(&d, t - 0.5 / fs, 0, 0.7e-9, fe * 1.03);
            changed = straddle = true;
        }
        double th = afm_drive_phase(&d, 0, t);
        double x = a1 * cos(th + p1) + a3 * cos(3 * th + p3);
        double f = 2e-9 * cos(th - 0.4);
        if (afm_harm_push(&h, x, f, th) != 1) continue;
        periods++;
        /* The period holding the change is not stationary: theta's rate changes inside it,
         * so cos(theta) e^{-i theta} does not average its 2 theta part to 0 over dt. */
        if (straddle) {
            straddle = false;
            continue;
        }
        e1 = fmax(e1, fabs(h.out.h[0].x_amp_m / a1 - 1));
        ep1 = fmax(ep1, fabs(wrap_rad(h.out.h[0].x_phase_deg * pi / 180 - p1)));
        e2 = fmax(e2, h.out.h[1].x_amp_m / a1);
        e3 = fmax(e3, fabs(h.out.h[2].x_amp_m / a3 - 1));
        ep3 = fmax(ep3, fabs(wrap_rad(h.out.h[2].x_phase_deg * pi / 180 - p3)));
        f1 = fmax(f1, fabs(h.out.h[0].f_amp_n / 2e-9 - 1));
    }
    check_true(periods >= 38, "fractional: periods completed across the fe change");
    /* Error bound (afm_harm.h): (2 k w h)^2 / (12 N) per period for the tone at its own k,
     * plus the other line leaking through the end pieces at about the same order. k = 1:
     * 2.8e-6 at 167 samples; k = 3 (3 % of the signal relative to tone 1's 24x larger
     * amplitude leaking in): bound 24 * 2.5e-5. */
    printf(
        "  fractional: k1 amp %.2e phase %.2e rad, k2 leak %.2e, k3 amp %.2e phase %.2e, F %.2e\n",
        e1, ep1, e2, e3, ep3, f1);
    check_abs(e1, 0, 3e-6, "fractional: |x|_1 rel error (pure tone ~1e-6)");
    check_abs(ep1, 0, 3e-6, "fractional: phi_1 error (rad)");
    check_abs(f1, 0, 3e-6, "fractional: |F|_1 rel error");
    check_abs(e2, 0, 3e-6, "fractional: |x|_2 leak / |x|_1");
    check_abs(e3, 0, 6e-4, "fractional: |x|_3 rel error");
    check_abs(ep3, 0, 6e-4, "fractional: phi_3 error (rad)");
}

static void test_harm_defaults_and_errors(void) {
    afm_modal m;
    memset(&m, 0, sizeof m);
    double w = 2 * pi * fe;
    m.n = 4;
    m.omega_rad_s[0] = 1.01 * w;
    m.omega_rad_s[1] = 6.3 * w;
    m.omega_rad_s[2] = 17.6 * w;
    m.omega_rad_s[3] = 34 * w;
    int ks[8];
    int n = afm_harm_default_list(&m, fe, ks);
    check_true(n == 5 && ks[0] == 1 && ks[1] == 2 && ks[2] == 3 && ks[3] == 6 && ks[4] == 18,
               "default list: 1, 2, 3, round(f2/fe) = 6, round(f3/fe) = 18");
    m.omega_rad_s[1] = 2.9 * w; /* duplicates 3 */
    m.omega_rad_s[2] = 1.2 * w; /* duplicates 1 */
    n = afm_harm_default_list(&m, fe, ks);
    check_true(n == 3 && ks[0] == 1 && ks[1] == 2 && ks[2] == 3, "default list de-duplicated");
    m.n = 1;
    n = afm_harm_default_list(&m, fe, ks);
    check_true(n == 3, "default list for a 1-mode model: 1, 2, 3");

    afm_harm h;
    char err[AFM_ERR_LEN] = "";
    int bad[] = {1, 0};
    check_true(afm_harm_init(&h, bad, 2, err, sizeof err) == -1 && err[0],
               "harm init rejects k = 0");
    int good[] = {1, 2};
    afm_harm_init(&h, good, 2, NULL, 0);
    afm_harm_push(&h, 1e-9, 0, 1.0);
    afm_harm_push(&h, 1e-9, 0, 1.1);
    afm_harm before = h;
    check_true(afm_harm_push(&h, NAN, 0, 1.2) == -1, "harm rejects NaN x");
    check_true(afm_harm_push(&h, 1e-9, 0, 1.1) == -1, "harm rejects non-increasing theta");
    check_true(afm_harm_push(&h, 1e-9, 0, 1.1 + 4.0) == -1, "harm rejects a theta step >= pi");
    check_true(afm_harm_push(&h, 1e-9, 0, INFINITY) == -1, "harm rejects infinite theta");
    check_true(memcmp(&before, &h, sizeof h) == 0, "harm unchanged after rejected samples");
}

/* ---- afm_lockin ---- */

/* Step response through the lock-in with the reference held at theta = pi/2: X = LPF(2u). */
static void test_lockin_filter(int order) {
    const double dt = 1.0 / fs, tau = 1000 * dt;
    afm_cfg_lockin c = {.time_constant_s = tau, .order = order};
    afm_lockin l;
    afm_lockin_init(&l, &c, dt, NULL, 0);
    double alpha = 1 - exp(-dt / tau), beta = 1 - alpha;
    double max_exact = 0, max_cont = 0, at_tau = 0;
    /* exact discrete response y_n = sum_{j<n} alpha^m C(j+m-1, m-1) beta^j */
    double sum = 0, term = pow(alpha, order); /* j = 0 */
    static double exact[10001];
    for (int n = 1; n <= 10000; n++) {
        afm_lockin_push(&l, 0.5, pi / 2);
        sum += term;
        term *= beta * (double)(n - 1 + order) / (double)n; /* term for j = n */
        double y = afm_lockin_x(&l), tt = n * dt / tau;
        double cont = 0, p = 1;
        for (int j = 0; j < order; j++) {
            cont += p;
            p *= tt / (j + 1);
        }
        cont = 1 - exp(-tt) * cont;
        max_exact = fmax(max_exact, fabs(y - sum));
        exact[n] = sum;
        max_cont = fmax(max_cont, fabs(y - cont));
        if (n == 1000) at_tau = y;
    }
    char what[128];
    snprintf(what, sizeof what, "lock-in order %d: step response = exact discrete cascade", order);
    check_abs(max_exact, 0, 1e-12, what);
    /* the same step through afm_lockin_push_n in blocks of 1..150 samples (block updates of
     * up to AFM_LOCKIN_TAB samples): the exact response at every block end, same tolerance */
    {
        afm_lockin lb;
        afm_lockin_init(&lb, &c, dt, NULL, 0);
        static double ub[10000], tb[10000];
        for (int n = 0; n < 10000; n++)
            ub[n] = 0.5, tb[n] = pi / 2;
        double max_blk = 0;
        int rej = 0;
        for (int n0 = 0, b = 0; n0 < 10000; b++) {
            int k = 1 + (b * 37) % 150;
            if (k > 10000 - n0) k = 10000 - n0;
            rej += afm_lockin_push_n(&lb, ub + n0, tb + n0, k);
            n0 += k;
            max_blk = fmax(max_blk, fabs(afm_lockin_x(&lb) - exact[n0]));
        }
        snprintf(what, sizeof what, "lock-in order %d: push_n in blocks = exact discrete cascade",
                 order);
        check_abs(max_blk + rej, 0, 1e-12, what);
    }
    /* The discretisation holds each stage's input over the step, so every stage leads the
     * continuous one by at most dt / tau of the unit step; tau = 1000 dt. */
    snprintf(what, sizeof what, "lock-in order %d: vs continuous Erlang step (tol order dt/tau)",
             order);
    check_abs(max_cont, 0, order * 1e-3, what);
    if (order == 1)
        check_abs(at_tau, 1 - exp(-1.0), 1e-12, "lock-in order 1: 1 - 1/e at t = tau");
    else {
        /* Erlang-4 CDF at t = tau: 1 - e^-1 (1 + 1 + 1/2 + 1/6) = 0.018988... */
        check_abs(at_tau, 1 - exp(-1.0) * (1 + 1 + 0.5 + 1.0 / 6), 4e-3,
                  "lock-in order 4: Erlang CDF at t = tau");
    }
    afm_lockin before = l;
    check_true(afm_lockin_push(&l, NAN, 0) == -1 && memcmp(&before, &l, sizeof l) == 0,
               "lock-in rejects NaN, unchanged");
    char err[AFM_ERR_LEN] = "";
    afm_cfg_lockin bad = {.time_constant_s = 0, .order = 2};
    check_true(afm_lockin_init(&l, &bad, dt, err, sizeof err) == -1 && err[0] &&
                   memcmp(&before, &l, sizeof l) == 0,
               "lock-in rejects tau = 0, unchanged");
}

/* Short time constants: the block update's length limit ln 2 / (2 alpha) falls below
 * AFM_LOCKIN_TAB (tau = 20 dt: 7 samples) or below 4 (tau = 2 dt: every sample by the
 * recursion). A step at theta = pi/2 through afm_lockin_push_n in blocks of 1..97 samples
 * must give the exact discrete response (as test_lockin_filter) at every block end, and a
 * rotating reference (0.3 rad per sample) the same state as pushes, bit for bit. */
static void test_lockin_short_tau(int order, double tau_dt) {
    enum { NS = 3000 };
    const double dt = 1.0 / fs;
    afm_cfg_lockin c = {.time_constant_s = tau_dt * dt, .order = order};
    afm_lockin l1, l2;
    afm_lockin_init(&l1, &c, dt, NULL, 0);
    afm_lockin_init(&l2, &c, dt, NULL, 0);
    double alpha = -expm1(-1.0 / tau_dt), beta = 1 - alpha;
    static double u[NS], th[NS], exact[NS + 1];
    double sum = 0, term = pow(alpha, order);
    for (int n = 1; n <= NS; n++) {
        u[n - 1] = 0.5;
        th[n - 1] = pi / 2;
        sum += term;
        term *= beta * (double)(n - 1 + order) / (double)n;
        exact[n] = sum;
    }
    double max_err = 0;
    int rej = 0;
    for (int n0 = 0, b = 0; n0 < NS; b++) {
        int k = 1 + (b * 41) % 97;
        if (k > NS - n0) k = NS - n0;
        rej += afm_lockin_push_n(&l1, u + n0, th + n0, k);
        n0 += k;
        max_err = fmax(max_err, fabs(afm_lockin_x(&l1) - exact[n0]));
    }
    char what[128];
    snprintf(what, sizeof what, "lock-in order %d, tau %g dt: push_n step = exact discrete cascade",
             order, tau_dt);
    check_abs(max_err + rej, 0, 1e-12, what);
    afm_lockin_reset(&l1);
    for (int n = 0; n < NS; n++) {
        th[n] = 1.0 + 0.3 * n;
        u[n] = 1e-9 * sin(th[n] - 0.7) + 2e-10 * cos(3 * th[n]);
        afm_lockin_push(&l2, u[n], th[n]);
    }
    for (int n0 = 0, b = 0; n0 < NS; b++) {
        int k = 1 + (b * 41) % 97;
        if (k > NS - n0) k = NS - n0;
        afm_lockin_push_n(&l1, u + n0, th + n0, k);
        n0 += k;
    }
    snprintf(what, sizeof what,
             "lock-in order %d, tau %g dt: push_n in blocks = pushes, bit for bit", order, tau_dt);
    check_true(memcmp(&l1, &l2, sizeof l1) == 0, what);
}

/* afm_lockin_push_marks (the output chain's one pass per push) against a call of
 * afm_lockin_push_n per mark followed by afm_lockin_xy: the same X, Y, rejects and state bit for
 * bit, over marks 1..60 samples apart, a rejected sample, a phase jump and pushes of 512. */
static void test_lockin_marks(int order, double tau_dt) {
    const double dt = 1e-6;
    afm_cfg_lockin c = {.time_constant_s = tau_dt * dt, .order = order};
    afm_lockin a, b;
    afm_lockin_init(&a, &c, dt, NULL, 0);
    afm_lockin_init(&b, &c, dt, NULL, 0);
    enum { N = 3000 };
    static double u[N], th[N];
    for (int n = 0; n < N; n++) {
        th[n] = 0.37 * n + (n >= 1700 ? 2.5 : 0.0);
        u[n] = cos(th[n] - 0.3) + 0.01 * sin(0.05 * n);
    }
    u[900] = NAN;
    double xa[N], ya[N], xb[N], yb[N];
    int ra[N], rb[N], nmk = 0, rej_a = 0, rej_b = 0;
    for (int n0 = 0, s = 0; n0 < N; n0 += 512) {
        int n = N - n0 < 512 ? N - n0 : 512;
        afm_lockin_mark mk[512];
        int m = 0;
        for (int e = 0; e < n; s++) {
            e += 1 + (s * 29) % 60;
            if (e > n) e = n;
            mk[m] = (afm_lockin_mark){.end = e, .rejects = -1};
            if (s % 2) mk[m].x_m = &xa[nmk + m], mk[m].y_m = &ya[nmk + m];
            m++;
        }
        rej_a += afm_lockin_push_marks(&a, u + n0, th + n0, n, mk, m);
        for (int q = 0, e0 = 0; q < m; q++) {
            rb[nmk + q] = afm_lockin_push_n(&b, u + n0 + e0, th + n0 + e0, mk[q].end - e0);
            rej_b += rb[nmk + q];
            afm_lockin_xy(&b, &xb[nmk + q], &yb[nmk + q]);
            ra[nmk + q] = mk[q].rejects;
            if (!mk[q].x_m) xa[nmk + q] = xb[nmk + q], ya[nmk + q] = yb[nmk + q];
            e0 = mk[q].end;
        }
        nmk += m;
    }
    char what[128];
    snprintf(what, sizeof what,
             "lock-in order %d, tau %g dt: push_marks = push_n per mark (%d marks, bits)", order,
             tau_dt, nmk);
    check_true(memcmp(xa, xb, (size_t)nmk * sizeof xa[0]) == 0 &&
                   memcmp(ya, yb, (size_t)nmk * sizeof ya[0]) == 0 &&
                   memcmp(ra, rb, (size_t)nmk * sizeof ra[0]) == 0 && rej_a == 1 && rej_b == 1 &&
                   memcmp(&a, &b, sizeof a) == 0,
               what);
}

/* Linear 1-mode oscillator (lumped, Q = 100, f0 = 300 kHz, base excitation) at r = fe/f0,
 * started on its steady state; the lock-in (tau = 10 periods, order 4) must read the
 * analytic amplitude A / sqrt((1 - r^2)^2 + (2 xi r)^2) and lag atan2(2 xi r, 1 - r^2). */
static void test_lockin_oscillator(double r, const char *where) {
    const double f0 = 300e3, xi = 0.005, ae = 1e-9, k = 40.0;
    afm_cfg_model cm = {.kind = AFM_MODEL_LUMPED, .n_damping = 1};
    cm.lumped.stiffness_n_m = k;
    cm.lumped.resonance_hz = f0;
    cm.damping_ratio[0] = xi;
    afm_modal m;
    char err[AFM_ERR_LEN];
    if (afm_model_build(&cm, &m, err, sizeof err) != 0) {
        check_true(false, err);
        return;
    }
    afm_cfg_forces cf;
    memset(&cf, 0, sizeof cf);
    afm_force_params fp;
    if (afm_force_init(&fp, &cf, 0, 0, err, sizeof err) != 0) {
        check_true(false, err);
        return;
    }
    afm_cfg_drive cd = {.separation_m = 1e-6, .n_tones = 1};
    cd.tones[0].amplitude_m = ae;
    cd.tones[0].frequency_hz = r * f0;
    afm_cfg_sim cs = {
        .sample_rate_hz = fs, .integrator = AFM_INTEGRATOR_REFERENCE, .ref_rtol = 1e-11};
    afm_sim *s = afm_sim_create(&m, &fp, &cd, &cs, err, sizeof err);
    if (!s) {
        check_true(false, err);
        return;
    }
    double amp = ae / hypot(1 - r * r, 2 * xi * r), lag = atan2(2 * xi * r, 1 - r * r);
    double w = 2 * pi * r * f0;
    double q = amp * sin(-lag) / m.tip[0], qd = amp * w * cos(-lag) / m.tip[0];
    afm_sim_set_state(s, &q, &qd);
    double te = 1 / (r * f0);
    afm_cfg_lockin cl = {.time_constant_s = 10 * te, .order = 4};
    afm_lockin l;
    afm_lockin_init(&l, &cl, afm_sim_dt(s), NULL, 0);
    afm_sample buf[256];
    int total = (int)(400 * te * fs); /* 40 tau: the order-4 start-up is < 1e-12 */
    for (int done = 0; done < total;) {
        int n = total - done < 256 ? total - done : 256;
        afm_sim_run(s, n, buf);
        for (int i = 0; i < n; i++)
            afm_lockin_push(&l, buf[i].x_m, afm_drive_phase(afm_sim_drive(s), 0, buf[i].t_s));
        done += n;
    }
    char what[160];
    printf("  %s: lock-in %.8e m %.6f deg, analytic %.8e m %.6f deg\n", where,
           afm_lockin_amplitude(&l), afm_lockin_phase_deg(&l), amp, lag * 180 / pi);
    snprintf(what, sizeof what, "lock-in %s: amplitude (rel 1e-4)", where);
    check_rel(afm_lockin_amplitude(&l), amp, 1e-4, what);
    snprintf(what, sizeof what, "lock-in %s: phase lag vs analytic (1e-3 deg)", where);
    check_abs(afm_lockin_phase_deg(&l), lag * 180 / pi, 1e-3, what);
    snprintf(what, sizeof what, "lock-in %s: lag %s 90 deg", where,
             r < 1   ? "<"
             : r > 1 ? ">"
                     : "=");
    if (r < 1)
        check_true(afm_lockin_phase_deg(&l) < 89, what);
    else if (r > 1)
        check_true(afm_lockin_phase_deg(&l) > 91, what);
    else
        check_abs(afm_lockin_phase_deg(&l), 90, 1e-3, what);
    afm_sim_destroy(&s);
}

/* ---- afm_cycle ---- */

/* x = x0 + A cos(theta), v exact, f = -c v (a dashpot): E = c int v^2 = pi c A^2 w per
 * period; mean x0; min x0 - A; peak force c A w; no contact. */
static void test_cycle_dashpot(double samples_per_period, const char *where, double tol) {
    const double A = 20e-9, x0 = -3e-9, cdamp = 2e-7;
    const double fe_here = fs / samples_per_period, w = 2 * pi * fe_here;
    afm_cycle c;
    afm_cycle_init(&c, -HUGE_VAL, 1.0, NULL, 0);
    double eE = 0, eM = 0, eMin = 0, eP = 0, eT = 0;
    int periods = 0;
    for (int n = 0; n < 12 * (int)samples_per_period; n++) {
        double t = 1.3e-7 + n / fs, th = w * t;
        afm_sample s = {.t_s = t, .x_m = x0 + A * cos(th), .v_m_s = -A * w * sin(th)};
        s.f_n = -cdamp * s.v_m_s;
        if (afm_cycle_push(&c, &s, th) != 1) continue;
        periods++;
        eE = fmax(eE, fabs(c.out.dissipated_energy_j / (pi * cdamp * A * A * w) - 1));
        eM = fmax(eM, fabs(c.out.mean_deflection_m - x0) / A);
        eMin = fmax(eMin, fabs(c.out.min_deflection_m - (x0 - A)) / A);
        eP = fmax(eP, fabs(c.out.peak_force_n / (cdamp * A * w) - 1));
        eT = fmax(eT, fabs(c.out.duration_s * fe_here - 1));
        if (c.out.contact_time_s != 0 || c.out.n_contacts != 0 || c.out.indentation_m != 0 ||
            !isnan(c.out.pre_contact_velocity_m_s))
            eT = 1;
    }
    printf("  dashpot %s: E %.2e mean %.2e min %.2e peak %.2e period %.2e\n", where, eE, eM, eMin,
           eP, eT);
    char what[128];
    snprintf(what, sizeof what, "cycle dashpot %s: >= 10 whole periods", where);
    check_true(periods >= 10, what);
    snprintf(what, sizeof what, "cycle dashpot %s: E = pi c A^2 w", where);
    check_abs(eE, 0, tol, what);
    snprintf(what, sizeof what, "cycle dashpot %s: mean deflection", where);
    check_abs(eM, 0, tol, what);
    /* Hermite cubic minimum: error <~ (w h)^4 / 384 relative (4e-8 at 100 samples per
     * period); the parabola through the peak sample and its neighbours: (w h)^2 / 24 at
     * worst times the offset of the peak from the sample, ~1e-7 here */
    snprintf(what, sizeof what, "cycle dashpot %s: min deflection (Hermite)", where);
    check_abs(eMin, 0, 1e-7, what);
    snprintf(what, sizeof what, "cycle dashpot %s: peak force (parabola)", where);
    check_abs(eP, 0, 1e-6, what);
    snprintf(what, sizeof what, "cycle dashpot %s: duration, no contact", where);
    check_abs(eT, 0, 1e-9, what);
}

/* A periodic parabolic dip x = x0 + b u^2, u the time from the dip centre wrapped into
 * [-T/2, T/2): the Hermite cubic reproduces a parabola, so the crossings are exact.
 * Contact line xc above x0: contact time 2 sqrt((xc - x0) / b), indentation
 * cos(alpha) (xc - x0), pre-contact velocity -2 sqrt(b (xc - x0)). centre: the dip centre
 * as a fraction of the period (0.01: the contact straddles the period boundary). */
static void test_cycle_dip(double centre, const char *where) {
    const double te = 167.27 / fs, x0 = -2e-9, xc = -1e-9, top = 5e-9;
    const double b = 4 * (top - x0) / (te * te), ca = cos(11 * pi / 180);
    afm_cycle c;
    afm_cycle_init(&c, xc, ca, NULL, 0);
    double eT = 0, eI = 0, eV = 0, eMin = 0;
    int periods = 0, nc_ok = 1;
    for (int n = 0; n < 6 * 168; n++) {
        double t = 2.1e-7 + n / fs, th = 2 * pi * t / te;
        double u = t / te - centre;
        u = (u - floor(u + 0.5)) * te;
        afm_sample s = {.t_s = t, .x_m = x0 + b * u * u, .v_m_s = 2 * b * u, .f_n = 0};
        if (afm_cycle_push(&c, &s, th) != 1) continue;
        periods++;
        double tc = 2 * sqrt((xc - x0) / b);
        eT = fmax(eT, fabs(c.out.contact_time_s / tc - 1));
        eI = fmax(eI, fabs(c.out.indentation_m / (ca * (xc - x0)) - 1));
        eV = fmax(eV, fabs(c.out.pre_contact_velocity_m_s / (-2 * sqrt(b * (xc - x0))) - 1));
        eMin = fmax(eMin, fabs(c.out.min_deflection_m - x0) / (xc - x0));
        nc_ok = nc_ok && c.out.n_contacts == 1;
    }
    printf("  dip %s: contact time %.2e indentation %.2e v_in %.2e min %.2e\n", where, eT, eI, eV,
           eMin);
    char what[128];
    snprintf(what, sizeof what, "cycle dip %s: 5 periods, one contact each", where);
    check_true(periods == 5 && nc_ok, what);
    /* exact up to the 1e-15 bisection and rounding */
    snprintf(what, sizeof what, "cycle dip %s: contact time 2 sqrt((xc - x0)/b)", where);
    check_abs(eT, 0, 1e-9, what);
    snprintf(what, sizeof what, "cycle dip %s: indentation cos(alpha)(xc - x0)", where);
    check_abs(eI, 0, 1e-9, what);
    snprintf(what, sizeof what, "cycle dip %s: pre-contact velocity", where);
    check_abs(eV, 0, 1e-9, what);
    snprintf(what, sizeof what, "cycle dip %s: min deflection x0", where);
    check_abs(eMin, 0, 1e-9, what);
}

static void test_cycle_errors(void) {
    afm_cycle c;
    char err[AFM_ERR_LEN] = "";
    check_true(afm_cycle_init(&c, NAN, 1.0, err, sizeof err) == -1 && err[0],
               "cycle init rejects NaN line");
    afm_cycle_init(&c, -1e-9, 1.0, NULL, 0);
    afm_sample s = {.t_s = 1e-6, .x_m = 0, .v_m_s = 0, .f_n = 0};
    afm_cycle_push(&c, &s, 1.0);
    s.t_s += 1e-7;
    afm_cycle_push(&c, &s, 1.1);
    afm_cycle before = c;
    afm_sample bad = s;
    bad.t_s += 1e-7;
    bad.f_n = NAN;
    check_true(afm_cycle_push(&c, &bad, 1.2) == -1, "cycle rejects NaN force");
    bad.f_n = 0;
    bad.t_s = s.t_s;
    check_true(afm_cycle_push(&c, &bad, 1.2) == -1, "cycle rejects non-increasing time");
    bad.t_s = s.t_s + 1e-7;
    check_true(afm_cycle_push(&c, &bad, 1.05) == -1, "cycle rejects decreasing theta");
    check_true(memcmp(&before, &c, sizeof c) == 0, "cycle unchanged after rejected samples");
}

/* ---- phase tracking (afm_phase_track, shared by the three estimators) ---- */

/* The phasors the estimators rotate instead of calling sin/cos per sample must follow
 * afm_drive_phase: 10^7 samples (0.71 s at 14.06 MHz, theta up to ~4e5 rad) with two
 * phase-continuous frequency changes (afm_drive re-wraps its phase there, so the unwrapped
 * theta jumps by 2 pi m). Harmonic 1's phasor of afm_harm is e^{-i (theta mod 2 pi)}, the
 * lock-in's is e^{i theta}; both within 1e-9 rad (the tracker's bound is 2e-11 rad + 8 eps
 * |theta| = 7e-10 rad at the end, plus the rotations' rounding). Nearly all samples must
 * take the fast path: at most ~1 resynchronisation per drive period plus a few per change. */
static void test_phase_tracking(void) {
    afm_cfg_drive c = {.separation_m = 30e-9, .n_tones = 1};
    c.tones[0].amplitude_m = 0.7e-9;
    c.tones[0].frequency_hz = fe;
    c.tones[0].phase_rad = 2.0;
    afm_drive d;
    afm_drive_init(&d, &c);
    const int ks[] = {1, 2, 3, 6, 18};
    afm_harm h;
    afm_harm_init(&h, ks, 5, NULL, 0);
    afm_cfg_lockin cl = {.time_constant_s = 10 / fe, .order = 4};
    afm_lockin l;
    afm_lockin_init(&l, &cl, 1 / fs, NULL, 0);
    const long total = 10000000;
    double eh = 0, el = 0;
    long slow_h = 0, slow_l = 0, rejects = 0;
    for (long n = 0; n < total; n++) {
        double t = 2.5e-6 + (double)n / fs;
        if (n == 3000000) afm_drive_set_tone(&d, t - 0.37 / fs, 0, 0.7e-9, fe * 1.0123);
        if (n == 7000000) afm_drive_set_tone(&d, t - 0.81 / fs, 0, 0.7e-9, fe * 0.97);
        double th = afm_drive_phase(&d, 0, t);
        if (afm_harm_push(&h, 1e-9, 0.0, th) < 0 || afm_lockin_push(&l, 1e-9, th) < 0) rejects++;
        slow_h += h.trk.n == 0;
        slow_l += l.trk.n == 0;
        double p = fmod(th, 2 * pi);
        double hr, hi;
        afm_harm_phasor1(&h, &hr, &hi);
        eh = fmax(eh, hypot(hr - cos(p), hi + sin(p)));
        double lc, ls;
        afm_lockin_phasor(&l, &lc, &ls);
        el = fmax(el, hypot(lc - cos(th), ls - sin(th)));
    }
    printf("  phase tracking: max |phasor - e^{i theta}| harm %.2e lock-in %.2e; exact samples "
           "harm %ld lock-in %ld of %ld\n",
           eh, el, slow_h, slow_l, total);
    check_true(rejects == 0, "phase tracking: no sample rejected");
    check_abs(eh, 0, 1e-9, "phase tracking: harm phasor vs afm_drive_phase over 1e7 samples (rad)");
    check_abs(el, 0, 1e-9, "phase tracking: lock-in phasor vs afm_drive_phase (rad)");
    /* periods: 0.71 s * ~84 kHz = 6e4; allow 2 per period for the harm (boundary + the
     * sample after a drift), and 1 per 1000 samples for the lock-in (every 4096 plus drift) */
    check_true(slow_h < 2 * total / 167, "phase tracking: harm fast path on all but ~1/period");
    check_true(slow_l < total / 1000, "phase tracking: lock-in fast path nearly always");
}

/* The same trackers after the twin has been up for t_up: the sample times are t_up + n dt
 * (as afm_sim makes them) and the tone changes happen at sample times. Changes: two
 * frequency steps, and one amplitude-only change (the drive re-wraps its phase: theta jumps
 * by whole turns at the same rate).
 *  - noisy: theta = phi + w (t - t0) carries the rounding of t, w ulp(t) / 2 ~ 4e-9 rad at
 *    20 s, even right after a change where theta itself is small (tol ~2e-11 rad there).
 *    The trackers must keep their lock: a few table rebuilds per change (relock, noise
 *    learnt, refinements), not one every other sample (the daemon's real-time collapse of
 *    issue 12: ~750 000 rebuilds over these samples before the fix). The phasors follow
 *    theta within the tracker's noise cap, 1e-6 rad (a one-step rate after a relock drifts
 *    by up to that before the average takes over).
 *  - exact: theta from the sample count, as the chain computes it (afm_chain.c): one
 *    rebuild per frequency change, none for the amplitude-only one, phasors within 2e-9
 *    (a few tol: 2.9e-10 rad at |theta| = 1.5e5, about the largest the chain's rebase of
 *    every 2^20 samples lets theta reach; measured 1.2e-9 there). */
static void test_phase_tracking_uptime(double t_up, bool exact) {
    afm_cfg_drive c = {.separation_m = 30e-9, .n_tones = 1};
    c.tones[0].amplitude_m = 0.7e-9;
    c.tones[0].frequency_hz = 338112.0;
    afm_drive d;
    afm_drive_init(&d, &c);
    const int ks[] = {1, 2, 3, 4, 5, 6, 7, 8};
    afm_harm h;
    afm_harm_init(&h, ks, 8, NULL, 0);
    afm_cfg_lockin cl = {.time_constant_s = 1e-4, .order = 4};
    afm_lockin l;
    afm_lockin_init(&l, &cl, 1 / fs, NULL, 0);
    afm_cycle cy;
    afm_cycle_init(&cy, -8e-9, 0.98, NULL, 0);
    const long total = 3000000, k0 = (long)llround(t_up * fs);
    const double dt = 1 / fs;
    double eh = 0, el = 0;
    long slow_h = 0, slow_l = 0, rejects = 0, n_ch = 0;
    for (long n = 0; n < total; n++) {
        double t = (double)(k0 + n) * dt; /* afm_sim's sample times from t = 0 */
        if (n == 500000) afm_drive_set_tone(&d, t, 0, 0.7e-9, 336000.0);
        if (n == 1200000) afm_drive_set_tone(&d, t, 0, 0.5e-9, 336000.0); /* amplitude only */
        if (n == 2000000) afm_drive_set_tone(&d, t, 0, 0.5e-9, 336400.0);
        if (n == 0 || n == 500000 || n == 1200000 || n == 2000000) n_ch = n;
        double th = exact ? fma(d.omega_rad_s[0] * dt, (double)(n - n_ch), d.phase_rad[0])
                          : afm_drive_phase(&d, 0, t);
        afm_sample smp = {.t_s = t, .x_m = 1e-9 * sin(th), .v_m_s = 0, .f_n = 0};
        if (afm_harm_push(&h, 1e-9, 0.0, th) < 0 || afm_lockin_push(&l, 1e-9, th) < 0 ||
            afm_cycle_push(&cy, &smp, th) < 0)
            rejects++;
        slow_h += h.trk.n == 0;
        slow_l += l.trk.n == 0;
        if (n % 7 == 0) {
            double p = fmod(th, 2 * pi), hr, hi, lc, ls;
            afm_harm_phasor1(&h, &hr, &hi);
            eh = fmax(eh, hypot(hr - cos(p), hi + sin(p)));
            afm_lockin_phasor(&l, &lc, &ls);
            el = fmax(el, hypot(lc - cos(th), ls - sin(th)));
        }
    }
    const char *how = exact ? "theta from the sample count" : "theta = phi + w (t - t0)";
    printf("  phase tracking at t = %g s, %s: rebuilds harm %lld lock-in %lld (cycle rate "
           "changes %lld); exact samples harm %ld lock-in %ld of %ld; max |phasor - e^{i theta}| "
           "%.2e %.2e\n",
           t_up, how, h.trk.rate_changes, l.trk.rate_changes, cy.trk.rate_changes, slow_h, slow_l,
           total, eh, el);
    /* the first lock and 3 changes: 1 + 2 (exact), or up to 5 each (noisy) */
    const long long most = exact ? 3 : 20;
    const double ptol = exact ? 2e-9 : 1e-6;
    char what[200];
    snprintf(what, sizeof what, "phase tracking at t = %g s, %s: no sample rejected", t_up, how);
    check_true(rejects == 0, what);
    snprintf(what, sizeof what,
             "phase tracking at t = %g s, %s: at most %lld table rebuilds per estimator", t_up, how,
             most);
    check_true(h.trk.rate_changes <= most && l.trk.rate_changes <= most &&
                   cy.trk.rate_changes <= most,
               what);
    snprintf(what, sizeof what, "phase tracking at t = %g s, %s: fast path on all but ~1/period",
             t_up, how);
    check_true(slow_h < 2 * total / 41 && slow_l < total / 500, what);
    snprintf(what, sizeof what, "phase tracking at t = %g s, %s: phasors within %g rad", t_up, how,
             ptol);
    check_true(eh < ptol && el < ptol, what);
}

/* Issue 32, FM: tone 0's frequency stepped every 64 samples (an NCO at its fastest: a random
 * walk of steps up to 20 Hz around 338 kHz, 1 kHz every 50th step), at model time 20 s, theta
 * from the sample count in each step's frame as the chain computes it, and the estimators told
 * of every step as afm_chain's retune tells them (afm_harm_rebase, afm_lockin_rebase,
 * afm_track_rebase for the cycle's clock). O(1) per step: one rate change per estimator and
 * step, the fast path on every sample but the period boundaries (harm) and the 1024-sample
 * windows (lock-in); and the numbers follow the NCO's phase exactly: phasors within 2e-9 rad
 * of e^{i theta}, the lock-in's X, Y those of the filter cascade run with sin and cos of every
 * theta (1e-8 relative), the harmonics of a tone locked to the drive its amplitude and phase.
 * A rebase to a theta that is not the last sample's phase is refused, nothing changed.
 * Before (no rebase: the trackers learnt each step's rate from the increments): ~1.5 rate
 * changes per step and estimator and a slow sample or more per step. */
static void test_fm_retune(void) {
    afm_cfg_drive c = {.separation_m = 30e-9, .n_tones = 1};
    c.tones[0].amplitude_m = 0.7e-9;
    c.tones[0].frequency_hz = 338112.0;
    afm_drive d;
    afm_drive_init(&d, &c);
    afm_drive_set_grid(&d, 0.0, 1 / fs); /* as afm_sim: the NCO's phase exact at each step */
    const int ks[] = {1, 2, 3, 4, 5, 6, 7, 8};
    afm_harm h;
    afm_harm_init(&h, ks, 8, NULL, 0);
    afm_cfg_lockin cl = {.time_constant_s = 1e-4, .order = 4};
    afm_lockin l;
    afm_lockin_init(&l, &cl, 1 / fs, NULL, 0);
    afm_cycle cy;
    afm_cycle_init(&cy, -8e-9, 0.98, NULL, 0);
    const long total = 1000000, k0 = (long)llround(20.0 * fs);
    const double dt = 1 / fs, u = 1e-9, ph0 = 0.3;
    double wdt = d.omega_rad_s[0] * dt, ph = afm_drive_phase_mod(&d, 0, (double)k0 * dt);
    long n_org = 0, steps = 0, refused = 0, rejects = 0, slow_h = 0, slow_l = 0, periods = 0;
    double eh = 0, el = 0, exy = 0, ea = 0, ep = 0, z[4][2] = {{0}};
    unsigned rng = 12345u;
    bool refuse_ok = true;
    for (long n = 0; n < total; n++) {
        double t = (double)(k0 + n) * dt;
        if (n > 0 && n % 64 == 0) { /* the step, at the last sample's time */
            rng = rng * 1103515245u + 12345u;
            double df = ((double)(rng >> 8) / 16777216.0 - 0.5) * 40.0;
            if (steps % 50 == 49) df = steps % 100 == 99 ? -1000.0 : 1000.0;
            afm_drive_set_tone(&d, t - dt, 0, 0.7e-9, d.freq_hz[0] + df);
            wdt = d.omega_rad_s[0] * dt;
            ph = d.phase_rad[0];
            n_org = n - 1;
            const double th_prev = fma(wdt, (double)(n - n_org), ph) - wdt; /* chain: th[0] - wdt */
            if (steps == 10) { /* not the last sample's phase: refused, nothing changed */
                afm_harm hh = h;
                afm_lockin ll = l;
                refuse_ok = !afm_harm_rebase(&h, th_prev + 0.1, wdt) &&
                            !afm_lockin_rebase(&l, th_prev + 0.1, wdt) &&
                            memcmp(&hh, &h, sizeof h) == 0 && memcmp(&ll, &l, sizeof l) == 0;
            }
            refused += !afm_harm_rebase(&h, th_prev, wdt);
            refused += !afm_lockin_rebase(&l, th_prev, wdt);
            refused += !afm_track_rebase(&cy.trk, th_prev, wdt);
            steps++;
        }
        const double th = fma(wdt, (double)(n - n_org), ph);
        const double x = u * cos(th + ph0);
        afm_sample smp = {.t_s = t, .x_m = x, .v_m_s = 0, .f_n = 0};
        int hr = afm_harm_push(&h, x, 0.0, th);
        if (hr < 0 || afm_lockin_push(&l, x, th) < 0 || afm_cycle_push(&cy, &smp, th) < 0)
            rejects++;
        slow_h += h.trk.n == 0;
        slow_l += l.trk.n == 0;
        if (hr == 1 && h.periods > 2) { /* harmonic 1: x = u cos(theta + 0.3) */
            ea = fmax(ea, fabs(h.out.h[0].x_amp_m / u - 1.0));
            ep = fmax(ep, fabs(wrap_rad(h.out.h[0].x_phase_deg * pi / 180.0 - ph0)));
            periods++;
        }
        double in[2] = {2.0 * x * sin(th), 2.0 * x * cos(th)}; /* the cascade, exactly */
        for (int i = 0; i < 4; i++)
            for (int k = 0; k < 2; k++) {
                z[i][k] = fma(l.alpha, in[k] - z[i][k], z[i][k]);
                in[k] = z[i][k];
            }
        if (n % 7 == 0) {
            double p = fmod(th, 2 * pi), pr, pi_, lc, ls, lx, ly;
            afm_harm_phasor1(&h, &pr, &pi_);
            eh = fmax(eh, hypot(pr - cos(p), pi_ + sin(p)));
            afm_lockin_phasor(&l, &lc, &ls);
            el = fmax(el, hypot(lc - cos(th), ls - sin(th)));
            afm_lockin_xy(&l, &lx, &ly);
            exy = fmax(exy, hypot(lx - z[3][0], ly - z[3][1]) / u);
        }
    }
    printf("  FM retune: %ld steps of tone 0 (every 64 samples); rate changes harm %lld lock-in "
           "%lld cycle %lld; slow samples harm %ld lock-in %ld of %ld; max |phasor - e^{i "
           "theta}| %.2e %.2e; lock-in vs exact cascade %.2e; harmonic 1 over %ld periods: "
           "amplitude %.2e, phase %.2e rad\n",
           steps, h.trk.rate_changes, l.trk.rate_changes, cy.trk.rate_changes, slow_h, slow_l,
           total, eh, el, exy, periods, ea, ep);
    check_true(rejects == 0 && refused == 0, "FM retune: every sample taken, every step rebased");
    check_true(refuse_ok, "FM retune: a rebase off the last sample's phase is refused, unchanged");
    check_true(h.trk.rate_changes <= steps + 2 && l.trk.rate_changes <= steps + 2 &&
                   cy.trk.rate_changes <= steps + 2,
               "FM retune: one rate change (O(1) work) per step and estimator");
    check_true(slow_h < total / 41 + total / 500 && slow_l < total / 500,
               "FM retune: fast path on all but the period boundaries (harm), windows (lock-in)");
    check_true(eh < 2e-9 && el < 2e-9, "FM retune: phasors follow the NCO's phase within 2e-9 rad");
    check_abs(exy, 0, 1e-8, "FM retune: lock-in X, Y = the cascade with exact sin, cos (rel.)");
    /* a period is integrated in time, the tone is locked to theta: where the rate steps by 1
     * kHz inside a period (3e-3 of it) the two differ by a few 1e-4 (measured 4e-4) */
    check_true(periods > 20000 && ea < 1e-3 && ep < 1e-3,
               "FM retune: harmonic 1 of a tone locked to the drive: its amplitude and phase");
}

/* The block functions (afm_harm_push_n, afm_cycle_push_n, afm_lockin_push_n: what the
 * chain runs) against sample-by-sample pushes: the same state bit for bit, over a clipped
 * (tapping-like) orbit with contact crossings, two tone changes, a NaN sample and blocks of
 * odd lengths that end anywhere in a period. */
static void test_block_equivalence(bool law) {
    afm_cfg_drive c = {.separation_m = 30e-9, .n_tones = 1};
    c.tones[0].amplitude_m = 0.7e-9;
    c.tones[0].frequency_hz = fe;
    c.tones[0].phase_rad = 1.0;
    afm_drive d;
    afm_drive_init(&d, &c);
    const int ks[] = {1, 2, 3, 7};
    afm_harm h1, h2;
    afm_harm_init(&h1, ks, 4, NULL, 0);
    afm_harm_init(&h2, ks, 4, NULL, 0);
    afm_cfg_lockin cl = {.time_constant_s = 10 / fe, .order = 3};
    afm_lockin l1, l2;
    afm_lockin_init(&l1, &cl, 1 / fs, NULL, 0);
    afm_lockin_init(&l2, &cl, 1 / fs, NULL, 0);
    afm_cycle c1, c2;
    afm_cycle_init(&c1, -8e-9, 0.98, NULL, 0);
    afm_cycle_init(&c2, -8e-9, 0.98, NULL, 0);
    /* law: a DMT contact whose line is x = -8 nm (Z = a0 + 8 nm cos alpha, alpha = 0): the
     * local maxima in contact go through local_peak's Hermite path, in both functions */
    static afm_force_params fl;
    afm_cfg_forces cf = {.radius_m = 8e-9,
                         .vdw_contact = true,
                         .hamaker_j = 1.5e-19,
                         .a0_m = 0.3e-9,
                         .reduced_modulus_pa = 5e10};
    if (law && (afm_force_init(&fl, &cf, 0, 0, NULL, 0) != 0 ||
                afm_cycle_set_forces(&c1, &fl, 8.3e-9) != 0 ||
                afm_cycle_set_forces(&c2, &fl, 8.3e-9) != 0)) {
        check_true(false, "block functions with the force law: set up");
        return;
    }
    enum { NB = 4000 };
    static afm_sample s[NB];
    static double th[NB], x[NB], f[NB];
    long long rej_h = 0, rej_c = 0, per_h = 0, per_c = 0;
    int rej_l = 0, rej1 = 0, same = 1;
    long n0 = 0;
    for (int blk = 0; blk < 60; blk++) {
        int nb = 1 + (blk * 997) % NB;
        for (int i = 0; i < nb; i++, n0++) {
            double t = 1.5e-6 + (double)n0 / fs;
            if (n0 == 20000) afm_drive_set_tone(&d, t - 0.4 / fs, 0, 0.7e-9, fe * 1.01);
            if (n0 == 50000) afm_drive_set_tone(&d, t - 0.3 / fs, 0, 0.7e-9, fe * 0.98);
            th[i] = afm_drive_phase(&d, 0, t);
            double w = 2 * pi * fe, a = 10e-9 * sin(th[i] - 0.3), v = 10e-9 * w * cos(th[i] - 0.3);
            double xc = a < -9e-9 ? -9e-9 + 0.2 * (a + 9e-9) : a; /* flattened bottom */
            s[i] = (afm_sample){.t_s = t,
                                .x_m = xc,
                                .v_m_s = a < -9e-9 ? 0.2 * v : v,
                                .f_n = xc < -8e-9 ? 1e-7 * (-8e-9 - xc) / 1e-9 : -1e-10};
            if (n0 == 33333) s[i].x_m = NAN;
            x[i] = s[i].x_m;
            f[i] = s[i].f_n;
        }
        for (int i = 0; i < nb; i++) { /* one sample at a time */
            int a = afm_harm_push(&h1, x[i], f[i], th[i]);
            int b = afm_cycle_push(&c1, &s[i], th[i]);
            int e = afm_lockin_push(&l1, x[i], th[i]);
            rej1 += (a < 0) + (b < 0) + (e < 0);
        }
        for (int i = 0, done; i < nb;) { /* blocks */
            int k = afm_harm_push_n(&h2, x + i, f + i, th + i, nb - i, &done, &rej_h);
            per_h += done;
            for (int j = 0; j < k;) {
                j += afm_cycle_push_n(&c2, s + i + j, th + i + j, k - j, &done, &rej_c);
                per_c += done;
            }
            rej_l += afm_lockin_push_n(&l2, x + i, th + i, k);
            i += k;
            if (done && !(h2.periods == per_h)) same = 0;
        }
    }
    same = same && memcmp(&h1, &h2, sizeof h1) == 0 && memcmp(&l1, &l2, sizeof l1) == 0 &&
           memcmp(&c1, &c2, sizeof c1) == 0;
    const char *how = law ? " (force law)" : "";
    char what[160];
    printf("  block functions%s: %ld samples, %ld harm / %ld cycle periods, rejects %lld %lld %d "
           "(per sample %d), last peak %.4g N\n",
           how, n0, h1.periods, c1.periods, rej_h, rej_c, rej_l, rej1, c1.out.peak_force_n);
    snprintf(what, sizeof what, "block functions%s: periods completed", how);
    check_true(h1.periods > 100 && c1.periods > 100, what);
    snprintf(what, sizeof what, "block functions%s: period flags", how);
    check_true(per_h == h1.periods && per_c == c1.periods, what);
    snprintf(what, sizeof what, "block functions%s: the same rejects", how);
    check_true(rej_h + rej_c + rej_l == rej1 && rej1 == 3, what);
    snprintf(what, sizeof what, "block functions%s: state bit for bit as sample-by-sample pushes",
             how);
    check_true(same, what);
}

int main(void) {
    test_harm_dft(0);
    test_harm_dft(37);
    {
        static const int k3[] = {3}, k8[] = {1, 2, 3, 4, 5, 6, 7, 8},
                         k10[] = {2, 3, 4, 5, 6, 7, 8, 9, 10, 11},
                         k16[] = {16, 15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1},
                         k17[] = {2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17};
        test_harm_dft_lanes(k3, 1, "{3}");
        test_harm_dft_lanes(k8, 8, "{1..8}");
        test_harm_dft_lanes(k10, 10, "{2..11}");
        test_harm_dft_lanes(k16, 16, "{16..1}");
        test_harm_dft_lanes(k17, 16, "{2..17}");
    }
    test_harm_fractional();
    test_harm_defaults_and_errors();
    test_lockin_filter(1);
    test_lockin_filter(4);
    test_lockin_short_tau(4, 20.0);
    test_lockin_short_tau(3, 2.0);
    test_lockin_marks(4, 1000.0);
    test_lockin_marks(3, 2.0);
    test_lockin_marks(1, 40.0);
    test_lockin_oscillator(1.0, "at resonance");
    test_lockin_oscillator(0.99, "below resonance");
    test_lockin_oscillator(1.01, "above resonance");
    test_cycle_dashpot(100.0, "100 samples/period", 1e-12);
    test_cycle_dashpot(167.27, "167.27 samples/period", 3e-6);
    test_cycle_dip(0.5, "mid-period");
    test_cycle_dip(0.01, "across the boundary");
    test_cycle_errors();
    test_phase_tracking();
    test_phase_tracking_uptime(20.0, false);
    test_phase_tracking_uptime(60.0, false);
    test_phase_tracking_uptime(60.0, true);
    test_fm_retune();
    test_block_equivalence(false);
    test_block_equivalence(true);
    return check_done();
}
