/* SPDX-License-Identifier: MIT */
/* afm_orbit.c -- steady-state orbit analysis over drive periods (contract in afm_orbit.h). */
#include "estimators/afm_orbit.h"
#include "config/afm_err.h"

#include "estimators/afm_est_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static const double two_pi = AFM_EST_TWO_PI;
static const double rad2deg = AFM_EST_RAD2DEG;

/* Stationary points of the cubic (roots of 3a s^2 + 2b s + c) into r; returns how many
 * (0..2), unfiltered: the caller keeps those in [0, 1]. */
static inline int afm_cubic_stationary(const afm_cubic *q, double r[2]) {
    double A = 3.0 * q->a, B = 2.0 * q->b, C = q->c;
    int nr = 0;
    if (fabs(A) < 1e-300) {
        if (fabs(B) > 1e-300) r[nr++] = -C / B;
    } else {
        double disc = B * B - 4.0 * A * C;
        if (disc >= 0) {
            double sq = sqrt(disc);
            double qq = -0.5 * (B + (B >= 0 ? sq : -sq));
            r[nr++] = qq / A;
            if (qq != 0) r[nr++] = C / qq;
        }
    }
    return nr;
}

/* Thesis eq. E.12-E.13: mod(k (pi - phi_1) + phi_k, 2 pi) in degrees, [0, 360); phi_1 and
 * phi_k are the deflection phases (rad) of A cos(k theta + phi). */
static inline double afm_phase_diff_deg(int k, double phi1_rad, double phik_rad) {
    double dphi = afm_clock_wrap((double)k * (AFM_EST_PI - phi1_rad) + phik_rad);
    double deg = dphi * AFM_EST_RAD2DEG;
    return deg >= 360.0 ? 0.0 : deg;
}

#define STENCIL 10 /* points of each end correction; exact for degree < STENCIL */

double afm_orbit_period_s(const afm_drive *d) {
    return d->n > 0 && d->omega_rad_s[0] > 0 ? two_pi / d->omega_rad_s[0] : 0.0;
}

/* Time at which tone 0's phase is 2 pi m. */
static double boundary_time(const afm_drive *d, long m) {
    return d->t0_s[0] + (two_pi * (double)m - d->phase_rad[0]) / d->omega_rad_s[0];
}

/* Extremum of x near sample i: the Hermite cubics on [i-1, i] and [i, i+1] are searched for
 * a stationary point; want_min selects min or max. Returns x_i if nothing better. */
static double refine_x_extremum(const afm_sample *buf, int n, double h, int i, bool want_min) {
    double best = buf[i].x_m;
    for (int j = i - 1; j <= i; j++) {
        if (j < 0 || j + 1 >= n) continue;
        afm_cubic q = afm_hermite(&buf[j], &buf[j + 1], h);
        double r[2];
        int nr = afm_cubic_stationary(&q, r);
        for (int k = 0; k < nr; k++) {
            if (!(r[k] >= 0.0 && r[k] <= 1.0)) continue;
            double x = afm_cubic_at(&q, r[k]);
            if (want_min ? x < best : x > best) best = x;
        }
    }
    return best;
}

/* Peak of f near a sample maximum i by the parabola through i-1, i, i+1. */
static double refine_f_max(const afm_sample *buf, int n, int i) {
    if (i < 1 || i + 1 >= n) return buf[i].f_n;
    return afm_parabola_peak(buf[i - 1].f_n, buf[i].f_n, buf[i + 1].f_n);
}

/* Crossing of x through xc inside [t_j, t_j+1] (x_j and x_j+1 on opposite sides): bisection
 * on the Hermite cubic. Writes the time and the velocity there. */
static void crossing(const afm_sample *buf, double h, int j, double xc, double *t, double *v) {
    double s;
    afm_hermite_crossing(&buf[j], &buf[j + 1], h, xc, &s, v);
    *t = buf[j].t_s + s * h;
}

/* Uniform step of the buffer, or 0 if the times are not uniform and increasing. */
static double uniform_step(const afm_sample *buf, int n) {
    if (n < 2) return 0.0;
    double t0 = buf[0].t_s, h = (buf[n - 1].t_s - t0) / (double)(n - 1);
    if (!(h > 0) || !isfinite(h)) return 0.0;
    for (int i = 1; i < n; i++)
        if (fabs(buf[i].t_s - (t0 + (double)i * h)) > 1e-6 * h) return 0.0;
    return h;
}

/* Weights of the degree-7 Hermite interpolant on the nodes u = -1, 0, 1, 2 (value and
 * derivative at each) at u = s: x(s) = sum_m a[m] x_m + b[m] h v_m. Divided differences
 * with repeated nodes, applied to the 8 unit data vectors. */
static void hermite7_weights(double s, double *a, double *b) {
    static const double z[8] = {-1, -1, 0, 0, 1, 1, 2, 2};
    for (int e = 0; e < 8; e++) {
        double y[4] = {0}, dy[4] = {0};
        if (e < 4)
            y[e] = 1.0;
        else
            dy[e - 4] = 1.0;
        double c[8];
        for (int i = 0; i < 8; i++)
            c[i] = y[i / 2];
        /* order 1 */
        for (int i = 7; i >= 1; i--)
            c[i] = (i % 2 == 1) ? dy[i / 2] : (c[i] - c[i - 1]) / (z[i] - z[i - 1]);
        for (int k = 2; k < 8; k++)
            for (int i = 7; i >= k; i--)
                c[i] = (c[i] - c[i - 1]) / (z[i] - z[i - k]);
        double v = c[7];
        for (int i = 6; i >= 0; i--)
            v = v * (s - z[i]) + c[i];
        if (e < 4)
            a[e] = v;
        else
            b[e - 4] = v;
    }
}

/* One pass of range_diff: mode 0 judges only interpolants with no sample in contact,
 * mode 1 also those with all four in contact. Returns the max mismatch; *count the number
 * of samples judged. */
static double diff_pass(const afm_sample *buf, int n, double h, int i0, double t_hi, int q,
                        const double *a, const double *b, double x_contact_m, int mode,
                        int *count) {
    double dmax = 0.0;
    int cnt = 0;
    for (int i = i0; i < n && buf[i].t_s < t_hi; i++) {
        int j = i - q - 2; /* first stencil sample */
        if (j < 0 || j + 3 >= n) continue;
        const afm_sample *st = &buf[j];
        int in = (st[0].x_m < x_contact_m) + (st[1].x_m < x_contact_m) + (st[2].x_m < x_contact_m) +
                 (st[3].x_m < x_contact_m);
        if (in != 0 && (mode == 0 || in != 4)) continue;
        double x = 0.0;
        for (int m = 0; m < 4; m++)
            x += a[m] * st[m].x_m + b[m] * h * st[m].v_m_s;
        double dx = fabs(buf[i].x_m - x);
        if (dx > dmax) dmax = dx;
        cnt++;
    }
    *count = cnt;
    return dmax;
}

/* Max |x(t_i) - x(t_i - shift)| over samples with t_i in [t_lo, t_hi), x(t_i - shift) by
 * the degree-7 Hermite interpolant of the four samples around it (error ~ (w h)^8 / 1e4
 * relative to each harmonic w). Only samples whose interpolant lies out of contact
 * (x >= x_contact) are judged: the contact force switches on with a (a0 - d)^1.5 kink and
 * is stiff and steep just after, no polynomial follows that, and the kink's place on the
 * sample grid moves from period to period (measured on thesis-fig-4-2 with CVODE: mismatch
 * floor 6e-8 with in-contact samples, 1e-8 without). A transient decays in all of the
 * orbit, so the free part tells whether it is gone. If fewer than a quarter of the samples
 * are out of contact (near-permanent contact), the in-contact ones join, except where the
 * four straddle the contact line. *amp gets the half peak-to-peak of x over the samples;
 * returns -1 if nothing could be judged. The caller keeps t_lo - shift >= t_0 + 2 h. */
static double range_diff(const afm_sample *buf, int n, double h, double t_lo, double t_hi,
                         double shift, double x_contact_m, double *amp) {
    double qs = shift / h;
    int q = (int)floor(qs);
    double a[4], b[4];
    hermite7_weights(1.0 - (qs - (double)q), a, b);
    int i0 = (int)ceil((t_lo - buf[0].t_s) / h);
    if (i0 < 0) i0 = 0;
    double xmin = HUGE_VAL, xmax = -HUGE_VAL;
    int total = 0;
    for (int i = i0; i < n && buf[i].t_s < t_hi; i++, total++) {
        if (buf[i].x_m < xmin) xmin = buf[i].x_m;
        if (buf[i].x_m > xmax) xmax = buf[i].x_m;
    }
    *amp = xmax >= xmin ? 0.5 * (xmax - xmin) : 0.0;
    int cnt;
    double d = diff_pass(buf, n, h, i0, t_hi, q, a, b, x_contact_m, 0, &cnt);
    if (4 * cnt < total) d = diff_pass(buf, n, h, i0, t_hi, q, a, b, x_contact_m, 1, &cnt);
    return cnt > 0 ? d : -1.0;
}

static double rel_change(double diff, double amp) {
    if (amp > 0) return diff / amp;
    return diff > 0 ? HUGE_VAL : 0.0;
}

/* From the relative changes c[p - 1] (negative: not judged), p = 1..max_p: *settled gets
 * the smallest p with c <= tol, or 0 if there is none or if a proper divisor d of that p
 * is within 10 tol (then the orbit is most likely d-periodic and d is still settling, or
 * d's mismatch floor sits just above tol: the floor of a p-period comparison depends on
 * how p Te falls on the sample grid, so a period-2 orbit can pass at p = 8 first); *best
 * gets the smallest p within 3 times the smallest change, or 0 if nothing was judged. */
static void choose_p(const double *c, int max_p, double tol, int *settled, int *best) {
    double cmin = HUGE_VAL;
    for (int p = 1; p <= max_p; p++)
        if (c[p - 1] >= 0 && c[p - 1] < cmin) cmin = c[p - 1];
    *settled = *best = 0;
    for (int p = 1; p <= max_p && !*best; p++)
        if (c[p - 1] >= 0 && c[p - 1] <= 3.0 * cmin) *best = p;
    for (int p = 1; p <= max_p && !*settled; p++)
        if (c[p - 1] >= 0 && c[p - 1] <= tol) *settled = p;
    for (int dv = 1; *settled > 1 && dv < *settled; dv++)
        if (*settled % dv == 0 && c[dv - 1] >= 0 && c[dv - 1] <= 10.0 * tol) *settled = 0;
}

int afm_orbit_periodicity(const afm_sample *buf, int n, const afm_drive *d, int max_p,
                          double x_contact_m, double tol_rel, double *change_rel) {
    double c[AFM_ORBIT_MAX_P];
    int found = 0, best = 0;
    double h = uniform_step(buf, n), te = afm_orbit_period_s(d);
    if (max_p > AFM_ORBIT_MAX_P) max_p = AFM_ORBIT_MAX_P;
    for (int p = 0; p < AFM_ORBIT_MAX_P; p++)
        c[p] = -1.0;
    if (h > 0 && te > 0 && max_p >= 1 && n > 2) {
        double th = afm_drive_phase(d, 0, buf[n - 1].t_s);
        double t_end = boundary_time(d, (long)floor(th / two_pi));
        for (int p = 1; p <= max_p; p++) {
            double t_lo = t_end - (double)p * te;
            if (t_lo - (double)p * te < buf[0].t_s + 2.0 * h) break;
            double amp,
                diff = range_diff(buf, n, h, t_lo, t_end, (double)p * te, x_contact_m, &amp);
            if (diff >= 0) c[p - 1] = rel_change(diff, amp);
        }
        choose_p(c, max_p, tol_rel, &found, &best);
    }
    if (change_rel) *change_rel = found ? c[found - 1] : best ? c[best - 1] : HUGE_VAL;
    return found;
}

/* ---- harmonics: corrected trapezoid over a window whose ends lie between samples ---- */

/* Bernoulli numbers B_2 .. B_10 for the Euler-Maclaurin end terms. */
static const double bern[5] = {1.0 / 6.0, -1.0 / 30.0, 1.0 / 42.0, -1.0 / 30.0, 5.0 / 66.0};

/* Weights (units of h) on the STENCIL nodes u_j = u0 + j (sample index offsets relative to
 * the end sample) that, added to the plain sum of samples from the end sample inwards,
 * integrate every polynomial of degree < STENCIL exactly from the window end.
 * frac: (Ta - t_end_sample)/h in (-1, 0] on the left, (Tb - t_end_sample)/h in [0, 1) on
 * the right; right selects the side. */
static void end_weights(int u0, double frac, bool right, double *w) {
    double fun[STENCIL]; /* the correction functional applied to u^m */
    double pw = frac;
    for (int m = 0; m < STENCIL; m++) {
        double integral = right ? pw / (m + 1) : -pw / (m + 1);
        pw *= frac;
        double em = 0.0;
        if (m % 2 == 1) em = bern[m / 2] / (double)(m + 1);
        fun[m] = integral - (m == 0 ? 0.5 : 0.0) + (right ? -em : em);
    }
    for (int j = 0; j < STENCIL; j++) {
        /* monomial coefficients of the Lagrange basis polynomial of node j */
        double c[STENCIL] = {1.0};
        int deg = 0;
        double den = 1.0;
        for (int k = 0; k < STENCIL; k++) {
            if (k == j) continue;
            double uk = (double)(u0 + k);
            for (int m = deg + 1; m > 0; m--)
                c[m] = c[m - 1] - uk * c[m];
            c[0] = -uk * c[0];
            deg++;
            den *= (double)(j - k);
        }
        double s = 0.0;
        for (int m = 0; m < STENCIL; m++)
            s += fun[m] * c[m];
        w[j] = s / den;
    }
}

int afm_orbit_analyse(const afm_sample *buf, int n, const afm_drive *d, int p, double x_contact_m,
                      const int *ks, int nk, afm_orbit *out, char *err, size_t errlen) {
    if (!buf || !d || !out || (nk > 0 && !ks)) {
        afm_err_set(err, errlen, "afm_orbit_analyse: NULL argument");
        return -1;
    }
    if (p < 1 || p > AFM_ORBIT_MAX_P) {
        afm_err_set(err, errlen, "afm_orbit_analyse: periodicity out of 1..AFM_ORBIT_MAX_P");
        return -1;
    }
    if (nk < 0 || nk > AFM_MAX_HARMONICS) {
        afm_err_set(err, errlen, "afm_orbit_analyse: too many harmonics");
        return -1;
    }
    for (int j = 0; j < nk; j++)
        if (ks[j] < 1) {
            afm_err_set(err, errlen, "afm_orbit_analyse: harmonic numbers must be >= 1");
            return -1;
        }
    if (isnan(x_contact_m)) {
        afm_err_set(err, errlen, "afm_orbit_analyse: contact displacement is NaN");
        return -1;
    }
    double h = uniform_step(buf, n), te = afm_orbit_period_s(d);
    if (!(h > 0) || !(te > 0)) {
        afm_err_set(err, errlen, "afm_orbit_analyse: sample times not uniform, or no tone 0");
        return -1;
    }
    double w0 = d->omega_rad_s[0];
    long m_lo = (long)ceil(afm_drive_phase(d, 0, buf[0].t_s + AFM_ORBIT_MARGIN * h) / two_pi);
    long m_hi = (long)floor(afm_drive_phase(d, 0, buf[n - 1].t_s - AFM_ORBIT_MARGIN * h) / two_pi);
    long m_a;
    if (m_hi - m_lo >= p + 1)
        m_a = m_hi - 1 - p;
    else if (m_hi - m_lo >= p)
        m_a = m_hi - p;
    else {
        afm_err_set(err, errlen,
                    "afm_orbit_analyse: buffer shorter than p drive periods + margins");
        return -1;
    }
    double ta = boundary_time(d, m_a), tb = boundary_time(d, m_a + p);
    double period = tb - ta;

    memset(out, 0, sizeof *out);
    out->p = p;
    out->fe_hz = w0 / two_pi;
    out->t_start_s = ta;

    /* first sample >= ta, last <= tb */
    double t0 = buf[0].t_s;
    int ia = (int)ceil((ta - t0) / h), ib = (int)floor((tb - t0) / h);
    while (ia > 0 && buf[ia - 1].t_s >= ta)
        ia--;
    while (buf[ia].t_s < ta)
        ia++;
    while (ib + 1 < n && buf[ib + 1].t_s <= tb)
        ib++;
    while (buf[ib].t_s > tb)
        ib--;

    /* extrema over the window */
    int imin = ia, imax = ia, ifmax = ia;
    for (int i = ia; i <= ib; i++) {
        if (buf[i].x_m < buf[imin].x_m) imin = i;
        if (buf[i].x_m > buf[imax].x_m) imax = i;
        if (buf[i].f_n > buf[ifmax].f_n) ifmax = i;
    }
    out->min_deflection_m = refine_x_extremum(buf, n, h, imin, true);
    out->max_deflection_m = refine_x_extremum(buf, n, h, imax, false);
    out->max_force_n = refine_f_max(buf, n, ifmax);

    /* contacts: inward crossings of x_contact with crossing time in [ta, tb) */
    for (int i = ia > 0 ? ia : 1; i <= ib + 1 && i < n; i++) {
        if (!(buf[i - 1].x_m >= x_contact_m && buf[i].x_m < x_contact_m)) continue;
        double t_in, v_in;
        crossing(buf, h, i - 1, x_contact_m, &t_in, &v_in);
        if (t_in < ta || t_in >= tb) continue;
        if (out->n_contacts >= AFM_ORBIT_MAX_CONTACTS) {
            out->contacts_truncated = true;
            break;
        }
        int j = i, jmin = i, jf = i;
        while (j < n && buf[j].x_m < x_contact_m) {
            if (buf[j].x_m < buf[jmin].x_m) jmin = j;
            if (buf[j].f_n > buf[jf].f_n) jf = j;
            j++;
        }
        afm_orbit_contact *c = &out->contacts[out->n_contacts++];
        c->t_in_s = t_in;
        c->pre_contact_velocity_m_s = v_in;
        c->min_deflection_m = refine_x_extremum(buf, n, h, jmin, true);
        c->max_force_n = refine_f_max(buf, n, jf);
        if (j < n) {
            double v_out;
            crossing(buf, h, j - 1, x_contact_m, &c->t_out_s, &v_out);
        } else {
            c->t_out_s = buf[n - 1].t_s;
            out->contacts_truncated = true;
        }
    }

    /* harmonics */
    int kk[AFM_MAX_HARMONICS + 1];
    int nkk = 0;
    kk[nkk++] = 1;
    for (int j = 0; j < nk; j++)
        kk[nkk++] = ks[j];
    double ua = (ta - buf[ia].t_s) / h, ub = (tb - buf[ib].t_s) / h;
    int la = ia - STENCIL / 2, lb = ib - STENCIL / 2 + 1; /* first stencil index, each end */
    if (la < 0) la = 0;
    if (la + STENCIL > n) la = n - STENCIL;
    if (lb + STENCIL > n) lb = n - STENCIL;
    if (lb < 0) lb = 0;
    double wl[STENCIL], wr[STENCIL];
    end_weights(la - ia, ua, false, wl);
    end_weights(lb - ib, ub, true, wr);
    int lo = la < ia ? la : ia, hi = lb + STENCIL - 1 > ib ? lb + STENCIL - 1 : ib;
    double xr[AFM_MAX_HARMONICS + 1] = {0}, xi[AFM_MAX_HARMONICS + 1] = {0};
    double fr[AFM_MAX_HARMONICS + 1] = {0}, fi[AFM_MAX_HARMONICS + 1] = {0};
    for (int i = lo; i <= hi; i++) {
        double w = (i >= ia && i <= ib) ? 1.0 : 0.0;
        if (i >= la && i < la + STENCIL) w += wl[i - la];
        if (i >= lb && i < lb + STENCIL) w += wr[i - lb];
        if (w == 0.0) continue;
        double ph = w0 * (buf[i].t_s - ta);
        for (int j = 0; j < nkk; j++) {
            double c = cos(kk[j] * ph), s = sin(kk[j] * ph);
            xr[j] += w * buf[i].x_m * c;
            xi[j] -= w * buf[i].x_m * s;
            fr[j] += w * buf[i].f_n * c;
            fi[j] -= w * buf[i].f_n * s;
        }
    }
    double scale = 2.0 * h / period;
    double phi1 = atan2(xi[0], xr[0]);
    out->n_harmonics = nk;
    for (int j = 1; j < nkk; j++) {
        afm_orbit_harmonic *o = &out->harmonics[j - 1];
        o->k = kk[j];
        o->x_amp_m = scale * hypot(xr[j], xi[j]);
        double phk = atan2(xi[j], xr[j]);
        o->x_phase_deg = phk * rad2deg;
        o->f_amp_n = scale * hypot(fr[j], fi[j]);
        o->f_phase_deg = atan2(fi[j], fr[j]) * rad2deg;
        o->phase_diff_deg = afm_phase_diff_deg(kk[j], phi1, phk);
    }
    return 0;
}

/* ---- dwell until steady ---- */

int afm_orbit_settle_capacity(double sample_rate_hz, double fe_min_hz, int max_p) {
    if (!(sample_rate_hz > 0) || !(fe_min_hz > 0) || max_p < 1) return 0;
    double per = ceil(sample_rate_hz / fe_min_hz) + 1.0;
    double c = (double)(max_p + 3) * per + 4.0 * AFM_ORBIT_MARGIN + 8.0;
    return c < 1e9 ? (int)c : 0;
}

int afm_orbit_settle_begin(afm_orbit_settler *st, afm_sample *buf, int cap, int max_p,
                           double tol_rel, const afm_sim *s) {
    if (!st || !buf || !s || max_p < 1 || max_p > AFM_ORBIT_MAX_P || !(tol_rel > 0)) return -1;
    const afm_drive *d = afm_sim_drive(s);
    double te = afm_orbit_period_s(d), dt = afm_sim_dt(s);
    if (!(te > 0) || cap < afm_orbit_settle_capacity(1.0 / dt, 1.0 / te, max_p)) return -1;
    memset(st, 0, sizeof *st);
    st->buf = buf;
    st->cap = cap;
    st->max_p = max_p;
    st->tol_rel = tol_rel;
    st->m_next = (long)floor(afm_drive_phase(d, 0, afm_sim_time(s)) / two_pi) + 1;
    st->p_best = 1;
    st->change_rel = HUGE_VAL;
    st->x_contact_m = afm_force_contact_x(afm_sim_forces(s), afm_sim_separation(s));
    for (int p = 0; p < AFM_ORBIT_MAX_P; p++)
        for (int j = 0; j < AFM_ORBIT_MAX_P; j++)
            st->diff[p][j] = -1.0;
    return 0;
}

int afm_orbit_settle_period(afm_orbit_settler *st, afm_sim *s) {
    const afm_drive *d = afm_sim_drive(s);
    double h = afm_sim_dt(s), te = afm_orbit_period_s(d);
    double tb = boundary_time(d, st->m_next);
    int steps = (int)ceil((tb - afm_sim_time(s)) / h - 1e-9) + AFM_ORBIT_MARGIN;
    if (steps < 1) steps = 1;
    if (st->n + steps > st->cap) {
        /* keep what the comparisons and a later analysis can use */
        double t_keep = tb - (double)(st->max_p + 1) * te - (AFM_ORBIT_MARGIN + 2) * h;
        int drop = 0;
        while (drop < st->n && st->buf[drop].t_s < t_keep)
            drop++;
        memmove(st->buf, st->buf + drop, (size_t)(st->n - drop) * sizeof *st->buf);
        st->n -= drop;
        if (st->n + steps > st->cap) return AFM_SIM_EINVAL;
    }
    int rc = afm_sim_run(s, steps, st->buf + st->n);
    if (rc != AFM_SIM_OK) {
        st->n = 0;
        return rc;
    }
    st->n += steps;

    int slot = st->periods % st->max_p;
    double t_lo = tb - te, first = st->n > 0 ? st->buf[0].t_s : tb;
    bool judged = false;
    for (int p = 1; p <= st->max_p; p++) {
        st->diff[p - 1][slot] = -1.0;
        if (t_lo - (double)p * te < first + 2.0 * h) continue;
        double amp;
        st->diff[p - 1][slot] =
            range_diff(st->buf, st->n, h, t_lo, tb, (double)p * te, st->x_contact_m, &amp);
        st->amp[slot] = amp;
        judged = judged || st->diff[p - 1][slot] >= 0;
    }
    if (judged) st->judged++;
    st->periods++;
    st->m_next++;

    /* relative change of each p over its last p periods */
    double c[AFM_ORBIT_MAX_P];
    for (int p = 1; p <= st->max_p; p++) {
        double dmax = 0.0, amax = 0.0;
        bool ok = p <= st->periods;
        for (int a = 0; a < p && ok; a++) {
            int sl = (st->periods - 1 - a) % st->max_p;
            ok = st->diff[p - 1][sl] >= 0;
            if (ok && st->diff[p - 1][sl] > dmax) dmax = st->diff[p - 1][sl];
            if (ok && st->amp[sl] > amax) amax = st->amp[sl];
        }
        c[p - 1] = ok ? rel_change(dmax, amax) : -1.0;
    }
    int settled, best;
    choose_p(c, st->max_p, st->tol_rel, &settled, &best);
    if (best) {
        st->p_best = best;
        st->change_rel = c[best - 1];
    }
    if (settled) {
        st->p = st->p_best = settled;
        st->change_rel = c[settled - 1];
        return 1;
    }
    return 0;
}

double afm_orbit_lag_deg(double phase_deg) {
    double lag = fmod(-(phase_deg + 90.0), 360.0);
    return lag <= -180.0 ? lag + 360.0 : lag > 180.0 ? lag - 360.0 : lag;
}
