/* SPDX-License-Identifier: MIT */
/* afm_cycle.c -- streaming per-period tapping metrics (contract in afm_cycle.h). */
#include "estimators/afm_cycle.h"

#include "config/afm_clones.h"
#include "forces/afm_force_inline.h"

#include <stdio.h>
#include <string.h>

#if defined(__GNUC__)
#define CYCLE_INLINE inline __attribute__((always_inline))
#else
#define CYCLE_INLINE inline
#endif

/* *d = *s (afm_sample: 6 doubles) without the string copy the compiler picks. */
typedef double cycle_v2 __attribute__((vector_size(16), aligned(8), may_alias));
static CYCLE_INLINE void copy_sample(afm_sample *d, const afm_sample *s) {
    _Static_assert(sizeof(afm_sample) == 6 * sizeof(double), "afm_sample: 6 doubles");
    AFM_V4_ST(&d->t_s, AFM_V4_LD(&s->t_s));
    *(cycle_v2 *)(void *)&d->theta_rad = *(const cycle_v2 *)(const void *)&s->theta_rad;
}

int afm_cycle_init(afm_cycle *c, double x_contact_m, double cos_alpha, char *err, size_t errlen) {
    if (!c || isnan(x_contact_m) || x_contact_m == HUGE_VAL || !(cos_alpha > 0) ||
        !(cos_alpha <= 1)) {
        if (err && errlen)
            snprintf(err, errlen,
                     "cycle: contact line must be a number or -inf (got %g), cos(alpha) in (0, 1] "
                     "(got %g)",
                     x_contact_m, cos_alpha);
        return -1;
    }
    memset(c, 0, sizeof *c);
    c->x_contact_m = x_contact_m;
    c->cos_alpha = cos_alpha;
    c->x_near_m = x_contact_m + AFM_CYCLE_NEAR_GAP_M / cos_alpha;
    afm_track_init(&c->trk, true);
    return 0;
}

int afm_cycle_set_contact(afm_cycle *c, double x_contact_m) {
    if (isnan(x_contact_m) || x_contact_m == HUGE_VAL) return -1;
    if (c->active && c->n_prev > 0) { /* the whole steps in contact so far, by the old line */
        if (c->prev.x_m < c->x_contact_m) c->cur.contact_time_s += c->prev.t_s - c->t_in;
        c->t_in = c->prev.t_s;
    }
    c->x_contact_m = x_contact_m;
    c->x_near_m = x_contact_m + AFM_CYCLE_NEAR_GAP_M / c->cos_alpha;
    return 0;
}

static CYCLE_INLINE double squeeze_force(const afm_cycle *c, double x, double v);
static void def_resolve(afm_cycle *c, double *ec, double *pk);

int afm_cycle_set_forces(afm_cycle *c, const afm_force_params *f, double z_m) {
    if (!f || !isfinite(z_m)) return -1;
    const double xc = afm_force_contact_x(f, z_m);
    if (isnan(xc) || xc == HUGE_VAL) return -1;
    /* the pending entries under the law they were flagged under (f may be that law's
     * storage, changed already: the copy) */
    if (c->pend.n > 0 && memcmp(&c->fsnap, f, sizeof *f) != 0)
        def_resolve(c, &c->e_corr, &c->cur.peak_force_n);
    c->fsnap = *f;
    c->law_id++;
    afm_cycle_set_contact(c, xc);
    bool was_split = c->split;
    c->forces = f;
    c->z_m = z_m;
    c->split = f->squeeze != AFM_SQUEEZE_NONE;
    if (f->squeeze == AFM_SQUEEZE_STARR) { /* as rt_changed_z: rebuilt when it no longer fits */
        double key[5] = {f->sq_coef, f->sq_lambda_m, f->sq_offset_m, f->a0_m, f->cos_alpha};
        if (memcmp(key, c->starr_key, sizeof key) != 0 || !c->starr.on ||
            !(fabs(afm_force_starr_h(f, z_m, 0.0) - c->starr.h0) <=
              AFM_RT_STARR_KEEP * c->starr.hw)) {
            afm_rt_starr_build(&c->starr, f, z_m);
            memcpy(c->starr_key, key, sizeof key);
        }
    } else {
        c->starr.on = false;
    }
    if (c->split && !was_split) { /* the kept samples (the old law had no film, so their f is
                                     the tip-sample force): their squeeze power, for the sums */
        c->prev.theta_rad = squeeze_force(c, c->prev.x_m, c->prev.v_m_s) * c->prev.v_m_s;
        c->prev2.theta_rad = squeeze_force(c, c->prev2.x_m, c->prev2.v_m_s) * c->prev2.v_m_s;
    }
    return 0;
}

void afm_cycle_reset(afm_cycle *c) {
    double xc = c->x_contact_m, ca = c->cos_alpha, z = c->z_m, key[5];
    const afm_force_params *f = c->forces;
    bool split = c->split, defer = c->defer;
    afm_rt_starr st = c->starr;
    afm_force_params fsnap = c->fsnap;
    unsigned long long law_id = c->law_id;
    memcpy(key, c->starr_key, sizeof key);
    memset(c, 0, sizeof *c);
    c->x_contact_m = xc;
    c->cos_alpha = ca;
    c->x_near_m = xc + AFM_CYCLE_NEAR_GAP_M / ca;
    c->forces = f;
    c->z_m = z;
    c->split = split;
    c->starr = st;
    memcpy(c->starr_key, key, sizeof key);
    c->defer = defer;
    c->fsnap = fsnap;
    c->law_id = law_id;
    afm_track_init(&c->trk, true);
}

/* ---- forces by origin ----
 *
 * With split (the force law has a squeeze film), every sample is split on entry: its f_n
 * becomes the tip-sample force f - F_sq(x, v), and its theta_rad (the tip rotation, which
 * no metric here uses) carries the squeeze film's power F_sq v (W). Everything below then
 * works on the tip-sample force; the sums of w F_sq v give squeeze_dissipated_energy_j.
 * afm_cycle_push splits a sample by split_sample, the runs read the split from
 * afm_cycle_split_forces (its loops are split_sample's operations, the same bits): the
 * chain's, or one afm_cycle_push_n takes here (split_here). */

/* The squeeze film's force on the tip at (x, v) (N): afm_force_squeeze_term's expressions
 * (the linear film's verbatim, without the partials), Starr's coefficient from the
 * interpolant on its window (as the rt integrator, rt_squeeze). */
static CYCLE_INLINE double squeeze_force(const afm_cycle *c, double x, double v) {
    const afm_force_params *f = c->forces;
    if (f->squeeze == AFM_SQUEEZE_LINEAR) {
        double cq = f->p1 * (c->z_m + x) + f->p2;
        return cq > 0.0 ? -cq * v : 0.0;
    }
    double kx, kv;
    if (c->starr.on) {
        double dcdh, cq = afm_rt_starr_eval(&c->starr, afm_force_starr_h(f, c->z_m, x), &dcdh);
        if (cq >= 0.0) return -cq * v;
    }
    return afm_force_squeeze_term(f, c->z_m, x, v, &kx, &kv);
}

/* *d = s split (with split): f_n the tip-sample force, theta_rad the squeeze film's power. */
static CYCLE_INLINE void split_sample(const afm_cycle *c, const afm_sample *s, afm_sample *d) {
    double fs = squeeze_force(c, s->x_m, s->v_m_s);
    copy_sample(d, s);
    d->f_n = s->f_n - fs;
    d->theta_rad = fs * s->v_m_s;
}

AFM_CLONES void afm_cycle_split_forces(const afm_cycle *c, const afm_sample *restrict s, int n,
                                       double *restrict f_ts, double *restrict p_sq) {
    if (!c->split) {
        for (int j = 0; j < n; j++)
            f_ts[j] = s[j].f_n;
        return;
    }
    const afm_force_params *f = c->forces;
    if (f->squeeze == AFM_SQUEEZE_LINEAR) { /* squeeze_force's, the constants hoisted */
        const double p1 = f->p1, p2 = f->p2, z = c->z_m;
        int j = 0;
        /* 4 samples at a time: (x, v) and (f, theta) of samples 0, 2 and 1, 3 side by side,
         * then transposed; the scalar loop's operations lane by lane (issue 12: 17 -> ~6
         * instructions a sample) */
        const afm_v4 vp1 = AFM_V4_SET1(p1), vp2 = AFM_V4_SET1(p2), vz = AFM_V4_SET1(z);
        for (; j + 4 <= n; j += 4) {
#define XV(i) (*(const cycle_v2 *)(const void *)&s[j + (i)].x_m)
#define FT(i) (*(const cycle_v2 *)(const void *)&s[j + (i)].f_n)
            afm_v4 u0 = __builtin_shufflevector(XV(0), XV(2), 0, 1, 2, 3);
            afm_v4 u1 = __builtin_shufflevector(XV(1), XV(3), 0, 1, 2, 3);
            afm_v4 w0 = __builtin_shufflevector(FT(0), FT(2), 0, 1, 2, 3);
            afm_v4 w1 = __builtin_shufflevector(FT(1), FT(3), 0, 1, 2, 3);
#undef XV
#undef FT
            afm_v4 X = __builtin_shufflevector(u0, u1, 0, 4, 2, 6);
            afm_v4 V = __builtin_shufflevector(u0, u1, 1, 5, 3, 7);
            afm_v4 F = __builtin_shufflevector(w0, w1, 0, 4, 2, 6);
            afm_v4 cq = vp1 * (vz + X) + vp2;
            afm_v4 fs = (afm_v4)((afm_v4i)(cq > 0.0) & (afm_v4i)(-cq * V));
            AFM_V4_ST(f_ts + j, F - fs);
            AFM_V4_ST(p_sq + j, fs * V);
        }
        for (; j < n; j++) {
            double cq = p1 * (z + s[j].x_m) + p2, v = s[j].v_m_s;
            double fs = cq > 0.0 ? -cq * v : 0.0;
            f_ts[j] = s[j].f_n - fs;
            p_sq[j] = fs * v;
        }
        return;
    }
    for (int j = 0; j < n; j++) { /* split_sample's */
        double fs = squeeze_force(c, s[j].x_m, s[j].v_m_s);
        f_ts[j] = s[j].f_n - fs;
        p_sq[j] = fs * s[j].v_m_s;
    }
}

/* The force law a step is taken under: the cycle's (eager), or a deferred step's own (its
 * record's copy of the law, its separation and contact line). */
typedef struct {
    const afm_force_params *forces;
    double z_m, x_contact_m;
} cycle_law;

static inline cycle_law law_of(const afm_cycle *c) {
    return (cycle_law){c->forces, c->z_m, c->x_contact_m};
}

/* Length of [a, b] inside [lo, hi]. */
static double overlap(double a, double b, double lo, double hi) {
    double l = a > lo ? a : lo, r = b < hi ? b : hi;
    return r > l ? r - l : 0.0;
}

/* One Halley step from s on g(s) = ((a s + b) s + c) s + d. */
static inline double halley(double a, double b, double c, double d, double s) {
    double g = fma(fma(fma(a, s, b), s, c), s, d);
    double d1 = fma(fma(3.0 * a, s, 2.0 * b), s, c);
    return s - 2.0 * g * d1 / fma(2.0 * d1, d1, -g * fma(6.0 * a, s, 2.0 * b));
}

/* The bracketed iteration for crossing (bisection when a Halley step leaves the bracket),
 * from s. */
AFM_EST_COLD static double crossing_robust(double a, double b, double c, double d, double s) {
    double lo = 0.0, hi = 1.0;
    bool pos0 = d >= 0;
    for (int it = 0; it < 100; it++) {
        double g = fma(fma(fma(a, s, b), s, c), s, d);
        if (g == 0.0) break;
        if ((g >= 0) == pos0)
            lo = s;
        else
            hi = s;
        double sn = halley(a, b, c, d, s);
        if (!(sn > lo && sn < hi)) {
            s = 0.5 * (lo + hi);
            if (hi - lo <= 1e-15) break;
            continue;
        }
        bool last = fabs(sn - s) <= 1e-6;
        s = sn;
        if (last) break;
    }
    return s;
}

/* Crossing of the step's Hermite cubic through xc (p and q on opposite sides): *frac in
 * (0, 1), *v the cubic's slope there / h. The same root as the safeguarded Newton iteration it
 * replaced (from the secant guess, bisection outside the bracket), to
 * within ~1e-15 of the step (closer to the exact root than it: the cubic is evaluated in
 * g = x - xc without cancelling the large x), in fewer evaluations: two steps of Halley's
 * iteration (cubic convergence) from the root of the quadratic through g0 with slope h v0
 * and g1 (within ~3e-3 of the step on tapping orbits; the secant if it has none in (0, 1)),
 * kept when they stay in (0, 1) and the second corrects by at most 1e-6 (its error is then
 * ~1e-18 times the ratio of the cubic's derivatives); else the bracketed iteration. The
 * bisection of afm_hermite_crossing when the Bernstein control polygon g0, gb1, gb2, g1
 * changes sign three times (the cubic may have three roots). */
static CYCLE_INLINE void crossing(const afm_sample *p, const afm_sample *q, double h, double xc,
                                  double *frac, double *v) {
    double g0 = p->x_m - xc, g1 = q->x_m - xc, hv0 = h * p->v_m_s, hv1 = h * q->v_m_s;
    double gb1 = g0 + (1.0 / 3.0) * hv0, gb2 = g1 - (1.0 / 3.0) * hv1;
    bool pos0 = g0 >= 0;
    if ((gb1 >= 0) != pos0 && (gb2 >= 0) == pos0) { /* signs alternate: 3 changes */
        afm_hermite_crossing(p, q, h, xc, frac, v);
        return;
    }
    /* g(s) = ((a s + b) s + hv0) s + g0: afm_hermite's cubic less xc */
    double dg = g1 - g0, a = hv0 + hv1 - 2.0 * dg, b = 3.0 * dg - 2.0 * hv0 - hv1;
    double s = -g0 / dg; /* the secant */
    double qa = dg - hv0, disc = fma(hv0, hv0, -4.0 * qa * g0);
    if (disc >= 0.0) { /* roots of qa s^2 + hv0 s + g0 (stable form) */
        double sq = sqrt(disc), qq = -0.5 * (hv0 + (hv0 >= 0 ? sq : -sq));
        double r0 = qq / qa, r1 = g0 / qq;
        if (r0 > 0.0 && r0 < 1.0)
            s = r0;
        else if (r1 > 0.0 && r1 < 1.0)
            s = r1;
    }
    if (!(s > 0.0 && s < 1.0)) s = 0.5;
    double s1 = halley(a, b, hv0, g0, s), s2 = halley(a, b, hv0, g0, s1);
    if (!(s1 > 0.0 && s1 < 1.0 && s2 > 0.0 && s2 < 1.0 && fabs(s2 - s1) <= 1e-6))
        s2 = crossing_robust(a, b, hv0, g0, s);
    *frac = s2;
    *v = fma(fma(3.0 * a, s2, 2.0 * b), s2, hv0) / h;
}

/* The cubic with Bernstein control points b0..b3 is strictly monotone on [0, 1] (no
 * stationary point inside) when the differences b1 - b0, b2 - b1, b3 - b2 have one strict
 * sign (its derivative is a positive combination of them). */
static inline bool hermite_monotone(double b0, double b1, double b2, double b3) {
    double d0 = b1 - b0, d1 = b2 - b1, d2 = b3 - b2;
    return (d0 > 0.0 && d1 > 0.0 && d2 > 0.0) || (d0 < 0.0 && d1 < 0.0 && d2 < 0.0);
}

/* Minimum of xmin and the step's Hermite cubic in (x, v) at its stationary points inside
 * (lo, hi) of [0, 1]: the roots of the derivative 3 a s^2 + 2 b s + h v0 (stable form), the
 * cubic ((a s + b) s + h v0) s + x0 by Horner. Its coefficients come from x1 - x0 (not
 * from x0, x1 apart as afm_hermite's, which cancel ~1e-16 |x|). */
static CYCLE_INLINE double hermite_min(const afm_sample *p, const afm_sample *q, double h,
                                       double lo, double hi, double xmin) {
    double hv0 = h * p->v_m_s, hv1 = h * q->v_m_s, dx = q->x_m - p->x_m;
    double a = hv0 + hv1 - 2.0 * dx, b = 3.0 * dx - 2.0 * hv0 - hv1;
    double A = 3.0 * a, B = 2.0 * b, r[2];
    int nr = 0;
    if (fabs(A) < 1e-300) {
        if (fabs(B) > 1e-300) r[nr++] = -hv0 / B;
    } else {
        double disc = fma(B, B, -4.0 * A * hv0);
        if (disc >= 0) {
            double sq = sqrt(disc), qq = -0.5 * (B + (B >= 0 ? sq : -sq));
            r[nr++] = qq / A;
            if (qq != 0) r[nr++] = hv0 / qq;
        }
    }
    for (int k = 0; k < nr; k++) {
        if (!(r[k] > lo && r[k] < hi)) continue;
        double x = fma(fma(fma(a, r[k], b), r[k], hv0), r[k], p->x_m);
        if (x < xmin) xmin = x;
    }
    return xmin;
}

/* Minimum of xmin and the step's Hermite cubic at its stationary points inside (0, 1), for
 * a step with a Bernstein control point (x0 + h v0 / 3 or x1 - h v1 / 3) below both ends:
 * the control polygon then changes direction, so the cubic is not monotone (no test). */
static CYCLE_INLINE double step_min(const afm_sample *p, const afm_sample *q, double xmin) {
    return hermite_min(p, q, q->t_s - p->t_s, 0.0, 1.0, xmin);
}

/* The step p -> q's Hermite cubic in (x, v) at s in [0, 1]: x and its slope v. */
static inline void hermite_at(const afm_sample *p, const afm_sample *q, double s, double *x,
                              double *v) {
    double h = q->t_s - p->t_s, hv0 = h * p->v_m_s, hv1 = h * q->v_m_s, dx = q->x_m - p->x_m;
    double a = hv0 + hv1 - 2.0 * dx, b = 3.0 * dx - 2.0 * hv0 - hv1;
    *x = fma(fma(fma(a, s, b), s, hv0), s, p->x_m);
    *v = fma(fma(3.0 * a, s, 2.0 * b), s, hv0) / h;
}

/* The tip-sample force (every term but the squeeze film) at (x, v): afm_force_tip less
 * afm_force_squeeze_term (the same bits as afm_force_tip without a squeeze film). */
static inline double ts_force(const cycle_law *c, double x, double v) {
    const afm_force_params *f = c->forces;
    double fc, fv, jx, jv;
    return afm_force_near_terms(f, fma(x, f->cos_alpha, c->z_m), v, &fc, &fv, &jx, &jv);
}

/* The peak of f around a local maximum of the samples' f at p (steps m -> p -> q): the
 * parabola through the three forces; with the force law and p in contact, the largest of
 * f(x, v) on both steps' Hermite cubics at quarter steps (9 values, 6 evaluated), refined by
 * the parabola through it and its neighbours. A contact lasts a few samples, so the force
 * law sees its shape where the samples' parabola cannot (afm_cycle.h). (Midpoints first and
 * quarter steps only beside the larger: 4 evaluations, but the viscoelastic term's steep
 * rise after the contact starts then misleads the first stage: 1 % scatter on thesis-1dof.) */
static AFM_CLONES_NOINLINE double local_peak(const cycle_law *c, const afm_sample *m,
                                             const afm_sample *p, const afm_sample *q) {
    if (!c->forces || !(p->x_m < c->x_contact_m)) return afm_parabola_peak(m->f_n, p->f_n, q->f_n);
    double g[9], x, v;
    g[0] = m->f_n;
    g[4] = p->f_n;
    g[8] = q->f_n;
    for (int i = 1; i < 4; i++) {
        hermite_at(m, p, 0.25 * i, &x, &v);
        g[i] = ts_force(c, x, v);
        hermite_at(p, q, 0.25 * i, &x, &v);
        g[4 + i] = ts_force(c, x, v);
    }
    int k = 0;
    for (int i = 1; i < 9; i++)
        if (g[i] > g[k]) k = i;
    return k > 0 && k < 8 ? afm_parabola_peak(g[k - 1], g[k], g[k + 1]) : g[k];
}

/* The tip-sample velocity term's power (viscoelastic; the squeeze film is split off) on the
 * step's Hermite cubic at u (W). */
static CYCLE_INLINE double vel_power(const cycle_law *c, const afm_sample *p, const afm_sample *q,
                                     double u) {
    const afm_force_params *f = c->forces;
    double x, v, fc, fv, jx, jv;
    hermite_at(p, q, u, &x, &v);
    afm_force_near_terms(f, fma(x, f->cos_alpha, c->z_m), v, &fc, &fv, &jx, &jv);
    return fv * v;
}

/* Work (J) of the tip-sample force over [lo, hi] of the step p -> q on the continuous path:
 * the conservative part exactly (afm_force_cons_work between the Hermite cubic's points);
 * the velocity terms by Gauss-Legendre on the cubic, on each side of a contact crossing at
 * fr (none when fr is outside (lo, hi)): 2 points out of contact (the squeeze film is
 * smooth there), 4 in contact, where the viscoelastic term grows as sqrt(indentation) from
 * the crossing: the side that starts or ends there in t = fr +- s^2 (smooth in s). (Plain
 * 2-point rule in contact: +1.4 % of thesis-1dof's dissipated energy; 4 points: +0.1 %.) */
static CYCLE_INLINE double path_work(const cycle_law *c, const afm_sample *p, const afm_sample *q,
                                     double lo, double hi, double fr) {
    static const double g2[2] = {-0.57735026918962576451, 0.57735026918962576451};
    static const double w2[2] = {1.0, 1.0};
    static const double g4[4] = {-0.86113631159405257522, -0.33998104358485626480,
                                 0.33998104358485626480, 0.86113631159405257522};
    static const double w4[4] = {0.34785484513745385737, 0.65214515486254614263,
                                 0.65214515486254614263, 0.34785484513745385737};
    const afm_force_params *f = c->forces;
    double h = q->t_s - p->t_s, xa = p->x_m, xb = q->x_m, v;
    if (lo > 0.0) hermite_at(p, q, lo, &xa, &v);
    if (hi < 1.0) hermite_at(p, q, hi, &xb, &v);
    double w = afm_force_cons_work(f, c->z_m, xa, xb);
    if (!f->viscoelastic) return w;
    bool cut = fr > lo && fr < hi;
    double edge[3] = {lo, cut ? fr : hi, hi};
    for (int k = 0; k < 1 + cut; k++) {
        double a = edge[k], b = edge[k + 1], xm, vm;
        hermite_at(p, q, 0.5 * (a + b), &xm, &vm);
        bool in = xm < c->x_contact_m;
        int n = in ? 4 : 2;
        const double *gx = in ? g4 : g2, *gw = in ? w4 : w2;
        /* in contact from a crossing at a (k = 1) or to one at b (k = 0) */
        int from = in && cut ? (k == 1 ? 1 : -1) : 0;
        for (int g = 0; g < n; g++) {
            double sg = 0.5 * (1.0 + gx[g]), u, jac;
            if (from == 0) {
                u = a + (b - a) * sg;
                jac = b - a;
            } else {
                u = from > 0 ? a + (b - a) * sg * sg : b - (b - a) * sg * sg;
                jac = 2.0 * (b - a) * sg;
            }
            w += h * 0.5 * gw[g] * jac * vel_power(c, p, q, u);
        }
    }
    return w;
}

/* A step's work on the continuous path less its trapezoid (what the sums by sample already
 * hold): the correction the period's dissipated energy takes for the steps near the surface
 * (afm_cycle.h). Above the contact with velocity terms only the conservative part is
 * corrected (exact work less its own trapezoid); the smooth squeeze film stays with the
 * trapezoid. Without them the sample's own force is the conservative one. */
static AFM_CLONES_NOINLINE double contact_work_corr(const cycle_law *c, const afm_sample *p,
                                                    const afm_sample *q) {
    double h = q->t_s - p->t_s, fr = -1.0, v, xc = c->x_contact_m;
    if (c->forces->viscoelastic && !(p->x_m < xc) && !(q->x_m < xc)) { /* above the contact:
                                                     the conservative part's trapezoid */
        double fp = afm_force_cons(c->forces, c->z_m, p->x_m);
        double fq = afm_force_cons(c->forces, c->z_m, q->x_m);
        return afm_force_cons_work(c->forces, c->z_m, p->x_m, q->x_m) -
               0.5 * h * (fp * p->v_m_s + fq * q->v_m_s);
    }
    if ((p->x_m < xc) != (q->x_m < xc)) crossing(p, q, h, xc, &fr, &v);
    return path_work(c, p, q, 0.0, 1.0, fr) - 0.5 * h * (p->f_n * p->v_m_s + q->f_n * q->v_m_s);
}

/* ---- deferred steps (afm_cycle_set_defer) ----
 *
 * With defer, local_peak in contact, the force at the period's minimum and contact_work_corr
 * are not computed when their step is met: an entry records the step (the samples' t, x, v,
 * f and the law's Z and contact line) in c->pend, in the order of the stream, and the
 * period's record takes them (c->out_def) for afm_cycle_finish. The work corrections are a
 * sum in stream order: a correction already known (the integrator's, afm_cycle_push_ev) is
 * added at once while no computed one waits, else kept as an entry in its place. When
 * c->pend is full or the force law changes, the pending entries are finished at once (into
 * the running sums) under the law they were flagged under (c->fsnap). */

static inline void pt_of(afm_cycle_pt *d, const afm_sample *s) {
    *d = (afm_cycle_pt){s->t_s, s->x_m, s->v_m_s, s->f_n};
}
static inline void sample_of(afm_sample *d, const afm_cycle_pt *p) {
    *d = (afm_sample){.t_s = p->t_s, .x_m = p->x_m, .v_m_s = p->v_m_s, .f_n = p->f_n};
}

/* Entry e's figure under the law f: into the work corrections *ec or the peak *pk. */
static void def_take(const afm_force_params *f, const afm_cycle_step *e, double *ec, double *pk) {
    const cycle_law law = {f, e->z_m, e->x_contact_m};
    afm_sample a[3];
    double v;
    switch (e->kind) {
    case AFM_CYCLE_DEF_PEAK:
        for (int i = 0; i < 3; i++)
            sample_of(&a[i], &e->p[i]);
        v = local_peak(&law, &a[0], &a[1], &a[2]);
        if (v > *pk) *pk = v;
        break;
    case AFM_CYCLE_DEF_TIP:
        v = afm_force_tip(f, e->z_m, e->p[0].x_m, 0.0, NULL, NULL);
        if (v > *pk) *pk = v;
        break;
    case AFM_CYCLE_DEF_WORK:
        sample_of(&a[0], &e->p[0]);
        sample_of(&a[1], &e->p[1]);
        *ec += contact_work_corr(&law, &a[0], &a[1]);
        break;
    default:
        *ec += e->p[0].f_n;
        break;
    }
}

/* The pending entries, in order, into *ec and *pk (the running sums of the period). Out of
 * line: def_new, on every deferred step, then saves its registers only when full. */
AFM_EST_COLD static void def_resolve(afm_cycle *c, double *ec, double *pk) {
    for (int i = 0; i < c->pend.n; i++)
        def_take(&c->fsnap, &c->pend.st[i], ec, pk);
    c->pend.n = c->pend.n_energy = 0;
}

/* A new entry of kind (room made by finishing the pending ones into *ec, *pk). */
static afm_cycle_step *def_new(afm_cycle *c, int kind, double *ec, double *pk) {
    if (c->pend.n == AFM_CYCLE_DEFER_MAX) {
        def_resolve(c, ec, pk);
        c->def_overflows++;
    }
    afm_cycle_step *e = &c->pend.st[c->pend.n++];
    e->kind = kind;
    e->z_m = c->z_m;
    e->x_contact_m = c->x_contact_m;
    if (kind == AFM_CYCLE_DEF_WORK || kind == AFM_CYCLE_DEF_VALUE) c->pend.n_energy++;
    return e;
}

/* The peak around a local maximum of f at p (m -> p -> q) into *pk: local_peak, deferred
 * when it needs the force law. */
static void peak_add(afm_cycle *c, const afm_sample *m, const afm_sample *p, const afm_sample *q,
                     double *ec, double *pk) {
    if (c->defer && c->forces && p->x_m < c->x_contact_m) {
        afm_cycle_step *e = def_new(c, AFM_CYCLE_DEF_PEAK, ec, pk);
        pt_of(&e->p[0], m);
        pt_of(&e->p[1], p);
        pt_of(&e->p[2], q);
        return;
    }
    const cycle_law law = law_of(c);
    double v = local_peak(&law, m, p, q);
    if (v > *pk) *pk = v;
}

/* A near-contact step's work correction (contact_work_corr, or the integrator's work of the
 * step during afm_cycle_push_ev) into *ec, in stream order. */
static void work_add(afm_cycle *c, const afm_sample *p, const afm_sample *q, double *ec,
                     double *pk) {
    const bool known = c->ev && isfinite(c->ev->work_ts_j);
    double w = 0.0;
    if (known)
        w = c->ev->work_ts_j - 0.5 * (q->t_s - p->t_s) * (p->f_n * p->v_m_s + q->f_n * q->v_m_s);
    if (!c->defer || (known && c->pend.n_energy == 0)) {
        if (!known) {
            const cycle_law law = law_of(c);
            w = contact_work_corr(&law, p, q);
        }
        *ec += w;
        return;
    }
    afm_cycle_step *e = def_new(c, known ? AFM_CYCLE_DEF_VALUE : AFM_CYCLE_DEF_WORK, ec, pk);
    if (known) {
        e->p[0].f_n = w;
    } else {
        pt_of(&e->p[0], p);
        pt_of(&e->p[1], q);
    }
}

void afm_cycle_set_defer(afm_cycle *c, bool on) {
    if (!on && c->pend.n > 0) def_resolve(c, &c->e_corr, &c->cur.peak_force_n);
    c->defer = on;
    if (c->forces) {
        c->fsnap = *c->forces;
        c->law_id++;
    }
}

void afm_cycle_finish(afm_cycle_metrics *m, afm_cycle_deferred *d) {
    if (d->n > 0) {
        double ec = d->e_corr, pk = m->peak_force_n;
        for (int i = 0; i < d->n; i++)
            def_take(&d->f, &d->st[i], &ec, &pk);
        m->peak_force_n = pk;
        if (d->n_energy > 0) m->dissipated_energy_j = d->e_part - ec;
    }
    /* all of it: a finished record is the same bytes however it was copied (the copies take
     * the used entries only) */
    memset(d, 0, sizeof *d);
}

/* d[0 .. n-1] = s[0 .. n-1] by vector moves, 120 bytes an entry (a memcpy call took ~100
 * instructions a period; issue 12). */
static CYCLE_INLINE void copy_steps(afm_cycle_step *restrict d, const afm_cycle_step *restrict s,
                                    int n) {
    _Static_assert(sizeof(afm_cycle_step) == 15 * sizeof(double), "afm_cycle_step: 120 bytes");
    for (int i = 0; i < n; i++) {
        const char *a = (const char *)(const void *)(s + i);
        char *b = (char *)(void *)(d + i);
        AFM_V4_ST(b, AFM_V4_LD(a));
        AFM_V4_ST(b + 32, AFM_V4_LD(a + 32));
        AFM_V4_ST(b + 64, AFM_V4_LD(a + 64));
        AFM_V4_ST(b + 88, AFM_V4_LD(a + 88)); /* bytes 88 .. 119 (88 .. 95 twice) */
    }
}

/* A step from c->prev to s inside the active period (no boundary): the previous sample's
 * trapezoid weight into the sums of its index, s's x into the samples' minimum, and the
 * step's flags: the parabola at a local maximum of f at prev, a Bernstein control point
 * below both ends of the step (the cubic may dip below them: its minimum, step_min;
 * otherwise the cubic stays above the samples' minimum), a contact crossing (its part of the
 * step; the whole steps of a contact are added when it ends, as one difference of times).
 * The runs (run_block, run_events) do the same, operation for operation. */
/* A step p -> q (length h) across the contact line xc: the contact time *ct (the step's part
 * in contact; an outward step adds the whole steps since *t_in as well), and for an inward
 * crossing inside the step the count *nc and, at the first, the pre-contact velocity *v_in.
 * step_plain and run_events keep these in different places. */
static CYCLE_INLINE void cross_step(const afm_sample *p, const afm_sample *q, double h, double xc,
                                    double *ct, double *t_in, int *nc, double *v_in) {
    double fr, v;
    crossing(p, q, h, xc, &fr, &v);
    if (q->x_m < xc) { /* inward: [fr, 1] of the step is in contact */
        *ct += h * overlap(fr, 1.0, 0.0, 1.0);
        if (fr >= 0.0 && fr < 1.0) {
            if (*nc == 0) *v_in = v;
            (*nc)++;
        }
        *t_in = q->t_s;
    } else { /* outward: the whole steps since t_in, then [0, fr] */
        *ct += (p->t_s - *t_in) + h * fr;
    }
}

/* ---- the integrator's record of a step (afm_cycle_push_ev) ---- */

/* ev's crossings agree with the samples' sides of the contact line (in0 -> in1). */
static inline bool ev_sides_agree(const afm_step_events *ev, bool in0, bool in1) {
    return ev->n_in - ev->n_out == (int)in1 - (int)in0;
}

/* cross_step from the integrator's crossings: the step's time in contact (with the whole
 * steps since *t_in, as cross_step counts them), its inward crossings and the velocity at the
 * first. Also a contact that starts and ends inside the step (both samples out), or a break
 * inside it (both in). */
static void ev_contact(const afm_step_events *ev, const afm_sample *p, const afm_sample *q,
                       double h, double xc, double *ct, double *t_in, int *nc, double *v_in) {
    bool in0 = p->x_m < xc, in1 = q->x_m < xc;
    if (in0 && in1) { /* counted whole when the contact ends: less the break */
        *ct -= h * (1.0 - ev->contact_frac);
    } else if (in0) {
        *ct += (p->t_s - *t_in) + h * ev->contact_frac;
    } else {
        *ct += h * ev->contact_frac;
        if (in1) *t_in = q->t_s;
    }
    if (ev->n_in > 0) {
        if (*nc == 0) *v_in = ev->v_in_m_s;
        *nc += ev->n_in;
    }
}

static void step_plain(afm_cycle *c, const afm_sample *s) {
    afm_cycle_metrics *m = &c->cur;
    const afm_sample *p = &c->prev;
    double h = s->t_s - p->t_s, w = s->t_s - c->t_before, h3 = h * (1.0 / 3.0);
    int l = (int)(c->k & 3);
    c->sum_fv[l] = fma(w, p->f_n * p->v_m_s, c->sum_fv[l]);
    c->sum_x[l] = fma(w, p->x_m, c->sum_x[l]);
    c->sum_sq[l] = fma(w, p->theta_rad, c->sum_sq[l]);
    if (s->x_m < c->smin) c->smin = s->x_m;
    double b1 = fma(h3, p->v_m_s, p->x_m), b2 = fma(-h3, s->v_m_s, s->x_m);
    const afm_step_events *ev = c->ev;
    if (ev && !isnan(ev->x_min_m)) { /* the integrator's pieces */
        if (ev->x_min_m < m->min_deflection_m) m->min_deflection_m = ev->x_min_m;
    } else if ((b1 < b2 ? b1 : b2) < (p->x_m < s->x_m ? p->x_m : s->x_m)) {
        m->min_deflection_m = step_min(p, s, m->min_deflection_m);
    }
    if (c->n_prev >= 2 && p->f_n >= c->prev2.f_n && p->f_n >= s->f_n)
        peak_add(c, &c->prev2, p, s, &c->e_corr, &m->peak_force_n);
    if (s->f_n > m->peak_force_n) m->peak_force_n = s->f_n;
    double xc = c->x_contact_m;
    bool in0 = p->x_m < xc, in1 = s->x_m < xc;
    if (ev && ev->n_in + ev->n_out > 0 && ev_sides_agree(ev, in0, in1))
        ev_contact(ev, p, s, h, xc, &m->contact_time_s, &c->t_in, &m->n_contacts,
                   &m->pre_contact_velocity_m_s);
    else if (in0 != in1)
        cross_step(p, s, h, xc, &m->contact_time_s, &c->t_in, &m->n_contacts,
                   &m->pre_contact_velocity_m_s);
    if (c->forces && (p->x_m < c->x_near_m || s->x_m < c->x_near_m))
        work_add(c, p, s, &c->e_corr, &m->peak_force_n);
    copy_sample(&c->prev2, p);
    c->t_before = p->t_s;
    c->k++;
    copy_sample(&c->prev, s);
}

/* A period boundary at frac of the step from c->prev to s (or the first sample exactly on
 * a boundary: no step, h = 0): the ending period, if one is active, gets the first part of
 * the step and is finished into c->out; the new one starts at s with the rest. Returns 1
 * when a period was completed. */
static AFM_CLONES_NOINLINE int step_boundary(afm_cycle *c, const afm_sample *s, double frac,
                                             bool has_step) {
    afm_cycle_metrics *m = &c->cur, *o = &c->out;
    const afm_sample *p = &c->prev;
    bool finishing = c->active && has_step;
    double h = has_step ? s->t_s - p->t_s : 0.0;
    /* minima of the Hermite cubic inside the step, before and after the boundary */
    double xmin_b = HUGE_VAL, xmin_a = HUGE_VAL, h3 = h * (1.0 / 3.0);
    double b1 = fma(h3, p->v_m_s, p->x_m), b2 = fma(-h3, s->v_m_s, s->x_m);
    if (has_step && !hermite_monotone(p->x_m, b1, b2, s->x_m)) {
        xmin_b = hermite_min(p, s, h, 0.0, frac, xmin_b);
        xmin_a = hermite_min(p, s, h, frac, 1.0, xmin_a);
    }
    /* contact part of the step [ca, cb] and the inward crossing r_in */
    double xc = c->x_contact_m, ca = 0.0, cb = 0.0, r_in = -1.0, v_in = 0.0;
    bool in0 = has_step && p->x_m < xc, in1 = s->x_m < xc;
    if (has_step && in1) cb = 1.0;
    /* the integrator's crossing where it saw just the one the samples show */
    const afm_step_events *ev = has_step ? c->ev : NULL;
    bool evc = ev && ev->n_in + ev->n_out == (in0 != in1) && ev_sides_agree(ev, in0, in1);
    if (has_step && in0 != in1) {
        if (in1) {
            if (evc) {
                r_in = ev->in_frac;
                v_in = ev->v_in_m_s;
            } else {
                crossing(p, s, h, xc, &r_in, &v_in);
            }
            ca = r_in;
        } else if (evc) {
            cb = ev->out_frac;
        } else {
            double v_out;
            crossing(p, s, h, xc, &cb, &v_out);
        }
    }
    /* the integrals' parts (afm_split_weights) */
    double wb0 = frac - 0.5 * frac * frac, wb1 = 0.5 * frac * frac;
    double wa0 = 0.5 * (1.0 - frac) * (1.0 - frac), wa1 = 0.5 * (1.0 - frac * frac);
    double e0 = -p->f_n * p->v_m_s, e1 = -s->f_n * s->v_m_s;
    double q0 = -p->theta_rad, q1 = -s->theta_rad; /* the squeeze film's (with split) */
    double qb = h * (wb0 * q0 + wb1 * q1), qa = h * (wa0 * q0 + wa1 * q1);
    /* the energy of the step's parts: the linear interpolant's, or for a contact step with
     * the force law the continuous path's (path_work) */
    double eb = h * (wb0 * e0 + wb1 * e1), ea = h * (wa0 * e0 + wa1 * e1);
    if (has_step && c->forces && (p->x_m < c->x_near_m || s->x_m < c->x_near_m)) {
        double fr = r_in >= 0.0 ? r_in : (in0 != in1 ? cb : -1.0);
        const cycle_law law = law_of(c);
        eb = -path_work(&law, p, s, 0.0, frac, fr);
        ea = -path_work(&law, p, s, frac, 1.0, fr);
        if (ev && isfinite(ev->work_ts_j)) { /* the integrator's total, split as the path's */
            double dw = ev->work_ts_j + (eb + ea);
            eb -= frac * dw;
            ea -= (1.0 - frac) * dw;
        }
    }
    if (finishing) {
        /* the last sample's own (backward) weight, then the sums in a fixed order */
        int l = (int)(c->k & 3);
        double w = p->t_s - c->t_before;
        c->sum_fv[l] = fma(w, p->f_n * p->v_m_s, c->sum_fv[l]);
        c->sum_x[l] = fma(w, p->x_m, c->sum_x[l]);
        c->sum_sq[l] = fma(w, p->theta_rad, c->sum_sq[l]);
        double rfv = (c->sum_fv[0] + c->sum_fv[1]) + (c->sum_fv[2] + c->sum_fv[3]);
        double rsq = (c->sum_sq[0] + c->sum_sq[1]) + (c->sum_sq[2] + c->sum_sq[3]);
        double rx = (c->sum_x[0] + c->sum_x[1]) + (c->sum_x[2] + c->sum_x[3]);
        double peak = m->peak_force_n;
        if (c->n_prev >= 2) { /* the parabola, but at a local maximum in contact */
            if (c->forces && p->x_m < xc && p->f_n >= c->prev2.f_n && p->f_n >= s->f_n) {
                peak_add(c, &c->prev2, p, s, &c->e_corr, &peak);
            } else {
                double pk = afm_parabola_peak(c->prev2.f_n, p->f_n, s->f_n);
                if (pk > peak) peak = pk;
            }
        }
        double xmin = m->min_deflection_m < c->smin ? m->min_deflection_m : c->smin;
        if (xmin_b < xmin) xmin = xmin_b;
        int nc = m->n_contacts;
        double vpre = m->pre_contact_velocity_m_s;
        if (r_in >= 0.0 && r_in < frac) {
            if (nc == 0) vpre = v_in;
            nc++;
        }
        if (frac >= 1.0) { /* s ends this period */
            if (s->x_m < xmin) xmin = s->x_m;
            if (s->f_n > peak) peak = s->f_n;
        }
        if (c->forces && xmin < xc) { /* the contact's peak between the samples */
            if (c->defer) {
                def_new(c, AFM_CYCLE_DEF_TIP, &c->e_corr, &peak)->p[0].x_m = xmin;
            } else {
                double fk = afm_force_tip(c->forces, c->z_m, xmin, 0.0, NULL, NULL);
                if (fk > peak) peak = fk;
            }
        }
        double dur = (m->duration_s + (p->t_s - c->t_first)) + h * frac;
        double xint = (c->x_int + 0.5 * rx) + h * (wb0 * p->x_m + wb1 * s->x_m);
        double ct = m->contact_time_s + (in0 ? p->t_s - c->t_in : 0.0);
        o->period = m->period;
        o->t_start_s = m->t_start_s;
        o->duration_s = dur;
        o->peak_force_n = peak;
        o->min_deflection_m = xmin;
        o->indentation_m = xmin < xc ? c->cos_alpha * (xc - xmin) : 0.0;
        o->contact_time_s = ct + h * overlap(ca, cb, 0.0, frac);
        o->n_contacts = nc;
        o->pre_contact_velocity_m_s = vpre;
        const double e_part = (m->dissipated_energy_j + -0.5 * rfv) + eb;
        o->dissipated_energy_j = c->pend.n_energy > 0 ? NAN : e_part - c->e_corr;
        o->mean_deflection_m = dur > 0 ? xint / dur : xmin;
        o->squeeze_dissipated_energy_j =
            c->split ? (m->squeeze_dissipated_energy_j + -0.5 * rsq) + qb : 0.0;
        c->periods++;
        if (c->defer) { /* the pending entries go with the record (afm_cycle_finish) */
            c->pend.e_part = e_part;
            c->pend.e_corr = c->e_corr;
            afm_cycle_deferred *d = c->out_def_to ? c->out_def_to : &c->out_def;
            memcpy(d, &c->pend, offsetof(afm_cycle_deferred, law_id));
            if (c->pend.n > 0) {
                if (d->law_id != c->law_id) { /* d (a chain's record) may hold it already */
                    d->f = c->fsnap;
                    d->law_id = c->law_id;
                }
                copy_steps(d->st, c->pend.st, c->pend.n);
            }
            c->out_def_at = c->out_def_to; /* NULL: out_def (c stays copyable) */
            c->pend.n = c->pend.n_energy = 0;
        }
    }
    /* the new period: the rest of the step */
    m->period = c->periods;
    m->t_start_s = p->t_s + frac * h;
    if (!has_step) m->t_start_s = s->t_s;
    m->duration_s = h * (1.0 - frac);
    m->peak_force_n = s->f_n;
    m->min_deflection_m = xmin_a < s->x_m ? xmin_a : s->x_m;
    m->indentation_m = 0.0;
    m->contact_time_s = h * overlap(ca, cb, frac, 1.0);
    m->n_contacts = 0;
    m->pre_contact_velocity_m_s = NAN;
    if (r_in >= frac) {
        m->pre_contact_velocity_m_s = v_in;
        m->n_contacts = 1;
    }
    m->dissipated_energy_j = ea;
    m->squeeze_dissipated_energy_j = qa;
    c->e_corr = 0.0;
    m->mean_deflection_m = 0.0;
    c->x_int = h * (wa0 * p->x_m + wa1 * s->x_m);
    AFM_V4_ST(c->sum_fv, AFM_V4_SET1(0.0));
    AFM_V4_ST(c->sum_x, AFM_V4_SET1(0.0));
    AFM_V4_ST(c->sum_sq, AFM_V4_SET1(0.0));
    c->smin = s->x_m;
    c->k = 0;
    c->t_before = c->t_first = c->t_in = s->t_s;
    c->active = true;
    copy_sample(&c->prev2, p);
    copy_sample(&c->prev, s);
    if (c->n_prev < 2) c->n_prev++;
    return finishing;
}

/* A step with no period boundary in it: accumulated into the open period (plain) or only
 * remembered as the previous sample. */
static inline void step_inside(afm_cycle *c, const afm_sample *s, bool plain) {
    if (plain) {
        step_plain(c, s);
    } else {
        copy_sample(&c->prev2, &c->prev);
        copy_sample(&c->prev, s);
    }
    if (c->n_prev < 2) c->n_prev++;
}

/* The step from c->prev to s by the exact clock's event ev (frac for a boundary). */
static int step_general(afm_cycle *c, const afm_sample *s, bool had_prev, int ev, double frac) {
    if (ev == AFM_CLOCK_CROSS && had_prev) return step_boundary(c, s, frac, true);
    if (ev == AFM_CLOCK_START && !had_prev) return step_boundary(c, s, 1.0, false);
    step_inside(c, s, had_prev && c->active);
    return 0;
}

/* The sample by the exact clock (checked: the sample itself is valid). */
static int push_slow(afm_cycle *c, const afm_sample *s, double theta_rad) {
    double frac = 1.0;
    bool had_prev = c->trk.started;
    int ev = afm_track_step(&c->trk, theta_rad, &frac);
    if (ev == AFM_CLOCK_BAD) return -1;
    return step_general(c, s, had_prev, ev, frac);
}

int afm_cycle_push(afm_cycle *c, const afm_sample *s, double theta_rad) {
    if (!s || !isfinite(s->t_s) || !isfinite(s->x_m) || !isfinite(s->v_m_s) || !isfinite(s->f_n) ||
        (c->n_prev > 0 && !(s->t_s > c->prev.t_s)))
        return -1;
    afm_sample sp;
    if (c->split) {
        split_sample(c, s, &sp);
        s = &sp;
    }
    if (!afm_track_fast(&c->trk, theta_rad)) return push_slow(c, s, theta_rad);
    step_inside(c, s, c->active); /* no boundary in the step */
    return 0;
}

int afm_cycle_push_ev(afm_cycle *c, const afm_sample *s, double theta_rad,
                      const afm_step_events *ev) {
    c->ev = ev;
    int rc = afm_cycle_push(c, s, theta_rad);
    c->ev = NULL;
    return rc;
}

/* ---- runs: afm_cycle_push_n's fast path ----
 *
 * A run is a stretch of samples that all take the tracker's fast path (no period boundary),
 * with the period active and the history full: step_plain for each, 4 steps at a time
 * (afm_v4 lanes; run is multiversioned, AFM_CLONES). The sums and minima by index mod 4 are 4
 * vector lanes (rotated to the run's first sample), the flags (local maximum of f, contact
 * crossing, Bernstein control point below both ends of the step) are recorded per block of 4 steps
 * and handled after the sums, in order, with step_plain's arithmetic: the state after a run is the
 * state after its samples' afm_cycle_push, bit for bit. A run stops before a sample whose theta is
 * off the tracker's line or whose step is not positive; a run with a value that is not finite (its
 * sums are not) is undone and pushed sample by sample (afm_cycle_push rejects it). */

enum {
    RUN_MAX = 512,  /* samples per run (the event records below are on the stack) */
    RUN_MIN = 4,    /* shorter stretches go through afm_cycle_push */
    SPLIT_MAX = 256 /* with split: samples per run, and per block split_here splits */
};

/* Index of the lowest set bit of m != 0. */
static inline int lowest_bit(unsigned m) {
#if defined(__GNUC__)
    return __builtin_ctz(m);
#else
    int l = 0;
    while (!(m >> l & 1))
        l++;
    return l;
#endif
}

typedef struct {
    const afm_sample *s; /* the run's samples; sample -1 is *p0 */
    const double *fs;    /* with the split given apart (afm_cycle_push_n_split): the
                            tip-sample force and squeeze power of s[k] (NULL: s[k]'s own f_n,
                            theta_rad: without a film) */
    const double *qs;
    afm_cycle *c;
    const afm_sample *p0; /* the sample before the run (c->prev) */
    const afm_sample *m2; /* the sample before p0 (c->prev2) */
    double f_m2;          /* its f */
    double t_m2;          /* time of the sample before p0 */
    double xc;            /* contact line */
    double ct;            /* the period's contact time so far, s */
    double t_in;          /* while in contact: the contact's whole steps start here */
    double v_in;          /* velocity at the run's first inward crossing */
    double pk;            /* peak force so far */
    double xmin;          /* Hermite minimum so far */
    double ec;            /* the period's contact-step work corrections so far (e_corr) */
    int nc;               /* inward crossings in the run */
} run_state;

/* The flagged blocks of a run. */
typedef struct {
    int n_ev;                     /* flagged blocks */
    unsigned ev[RUN_MAX / 4 + 1]; /* first step << 16 | ct << 12 | mn << 8 | cr << 4 | lm */
} run_flags;

/* Sample k >= 0 of the run as afm_cycle_push sees it (split): s[k], or with the split
 * given apart (r->fs) a copy in *buf with its f_n and theta_rad from there. */
static inline const afm_sample *run_at(const run_state *r, int k, afm_sample *buf) {
    if (!r->fs) return r->s + k;
    AFM_V4_ST(&buf->t_s, AFM_V4_LD(&r->s[k].t_s)); /* t, x, v, f; base_m: none reads it */
    buf->f_n = r->fs[k];
    buf->theta_rad = r->qs[k];
    return buf;
}

/* *d = sample k >= 0 of the run as afm_cycle_push keeps it (every field). */
static inline void run_keep(const run_state *r, int k, afm_sample *d) {
    copy_sample(d, r->s + k);
    if (r->fs) {
        d->f_n = r->fs[k];
        d->theta_rad = r->qs[k];
    }
}

/* *d = the point (t, x, v, f as afm_cycle_push has it) of sample k >= -2 of the run (-1: *p0,
 * -2: *m2): one load, the split force put in (no copy of the sample first; issue 12). */
static inline void run_pt(const run_state *r, int k, afm_cycle_pt *d) {
    const afm_sample *q = k >= 0 ? r->s + k : k == -1 ? r->p0 : r->m2;
    afm_v4 v = AFM_V4_LD(&q->t_s);
    if (k >= 0 && r->fs) v[3] = r->fs[k];
    AFM_V4_ST(&d->t_s, v);
}

/* f of sample k >= -2 of the run as afm_cycle_push has it (-1: *p0, -2: *m2). */
static inline double run_f(const run_state *r, int k) {
    return k >= 0 ? (r->fs ? r->fs[k] : r->s[k].f_n) : k == -1 ? r->p0->f_n : r->m2->f_n;
}

/* The flagged steps, in order: step k joins sample k - 1 (p) to sample k (q); in block
 * record e, bit l of lm / cr / mn flags step k0 + l. lm: f has a local maximum at p (>= both
 * neighbours): the parabola; cr: p and q lie on opposite sides of the contact line; mn: a
 * Bernstein control point below both p and q: step_min. As step_plain. (cross_step and
 * step_min read t, x and v alone: the samples as they are.) */
static AFM_CLONES_NOINLINE void run_events(run_state *r, const run_flags *fl) {
    const afm_sample *s = r->s;
    afm_cycle *c = r->c;
    /* deferred entries (peak_add, work_add with defer: no record of the step in a run) are
     * written from the samples and the split forces; the figures computed at once need the
     * samples as afm_cycle_push has them (run_at) */
    const bool dfr = c->defer && !c->ev;
    afm_sample b0, b1, b2;
    for (int e = 0; e < fl->n_ev; e++) {
        unsigned ev = fl->ev[e];
        int k0 = (int)(ev >> 16);
        for (unsigned lm = ev & 15u; lm; lm &= lm - 1) {
            int k = k0 + lowest_bit(lm);
            const bool in = c->forces && (k ? s[k - 1].x_m : r->p0->x_m) < c->x_contact_m;
            if (!in) { /* local_peak's parabola, at once (no copies, no call) */
                double v = afm_parabola_peak(run_f(r, k - 2), run_f(r, k - 1), run_f(r, k));
                if (v > r->pk) r->pk = v;
                continue;
            }
            if (dfr) {
                afm_cycle_step *st = def_new(c, AFM_CYCLE_DEF_PEAK, &r->ec, &r->pk);
                run_pt(r, k - 2, &st->p[0]);
                run_pt(r, k - 1, &st->p[1]);
                run_pt(r, k, &st->p[2]);
                continue;
            }
            const afm_sample *sm = k >= 2 ? run_at(r, k - 2, &b0) : k ? r->p0 : r->m2;
            const afm_sample *s0 = k >= 1 ? run_at(r, k - 1, &b1) : r->p0;
            peak_add(r->c, sm, s0, run_at(r, k, &b2), &r->ec, &r->pk);
        }
        for (unsigned cr = ev >> 4 & 15u; cr; cr &= cr - 1) {
            int k = k0 + lowest_bit(cr);
            const afm_sample *p = k ? s + k - 1 : r->p0, *q = s + k;
            cross_step(p, q, q->t_s - p->t_s, r->xc, &r->ct, &r->t_in, &r->nc, &r->v_in);
        }
        for (unsigned mn = ev >> 8 & 15u; mn; mn &= mn - 1) {
            int k = k0 + lowest_bit(mn);
            r->xmin = step_min(k ? s + k - 1 : r->p0, s + k, r->xmin);
        }
        for (unsigned ct = ev >> 12 & 15u; ct; ct &= ct - 1) {
            int k = k0 + lowest_bit(ct);
            if (dfr) {
                afm_cycle_step *st = def_new(c, AFM_CYCLE_DEF_WORK, &r->ec, &r->pk);
                run_pt(r, k - 1, &st->p[0]);
                run_pt(r, k, &st->p[1]);
                continue;
            }
            work_add(r->c, k ? run_at(r, k - 1, &b0) : r->p0, run_at(r, k, &b1), &r->ec, &r->pk);
        }
    }
}

/* Lanes delayed across blocks: LAG2(a, b) = (a2, a3, b0, b1), LAG1(LAG2(a, b), b) =
 * (a3, b0, b1, b2), a the previous block. */
#define LAG2(a, b) __builtin_shufflevector((a), (b), 2, 3, 4, 5)
#define LAG1(l2, b) __builtin_shufflevector((l2), (b), 1, 4, 3, 6)
/* Lane masks (0 or -1 per lane). Any lane set: two shuffles and ors, then lane 0 (moving
 * every lane to an integer register took ~16 instructions; issue 12). */
#define ANY4(m)                                                                                    \
    __extension__({                                                                                \
        afm_v4i o_ = (m) | __builtin_shufflevector((m), (m), 2, 3, 0, 1);                          \
        o_ = o_ | __builtin_shufflevector(o_, o_, 1, 0, 3, 2);                                     \
        o_[0] != 0;                                                                                \
    })
/* The block's lane masks as one word: lane l of lm, cr, mn, ct, bad at bits l, 4 + l, 8 + l,
 * 12 + l, 16 + l (each mask and-ed with its lanes' bits, then or-ed across the lanes by two
 * shuffles: ~13 instructions where the four masks lane by lane to integer registers took
 * ~60; issue 12). */
static inline unsigned flag_bits(afm_v4i lm, afm_v4i cr, afm_v4i mn, afm_v4i ct, afm_v4i bad) {
    const afm_v4i b0 = {1, 2, 4, 8};
    afm_v4i o = ((lm & b0) | (cr & (b0 << 4))) | ((mn & (b0 << 8)) | (ct & (b0 << 12)));
    o = o | (bad & (b0 << 16));
    o = o | __builtin_shufflevector(o, o, 2, 3, 0, 1);
    o = o | __builtin_shufflevector(o, o, 1, 0, 3, 2);
    return (unsigned)o[0];
}
/* a ? x : y lane by lane; min as vminpd (a < b ? a : b, so b where either is NaN). */
#define SEL4(m, x, y) ((afm_v4)(((m) & (afm_v4i)(x)) | (~(m) & (afm_v4i)(y))))
#define MIN4(a, b) SEL4((afm_v4i)((a) < (b)), (a), (b))

typedef struct {
    afm_v4 t, x, v, f, q;  /* the previous block (t, x, v, f, theta: F_sq v with split) */
    afm_v4 nn;             /* minus the tracker steps of the block's lanes (the fma
                              err = th - ref - n dphi without a negation per block) */
    afm_v4 fv, xs, xm, sq; /* sums of w f v, w x of the previous samples, minima of x, sums
                              of w F_sq v */
} run_vec;

/* min over the lanes, in vminpd's order (lanes 0, 2 and 1, 3, then the two) */
static inline double hmin4(const afm_v4 *a) {
    double s0 = (*a)[0] < (*a)[2] ? (*a)[0] : (*a)[2], s1 = (*a)[1] < (*a)[3] ? (*a)[1] : (*a)[3];
    return s0 < s1 ? s0 : s1;
}

typedef struct {
    afm_v4 ref, dphi, tol, xc, third, xn, z0;
    afm_v4i ctm; /* all ones when the force law is set (contact steps are flagged), else 0 */
} run_consts;

/* One block of 4 samples a[0..3] (steps k0 .. k0 + 3, theta th4); lanes >= nv repeat the
 * last valid one (they add nothing: weights and flags masked, x not in the minima; the last
 * valid sample's own weight waits for its next step, as in step_plain). f4, q4: the 4
 * samples' split force and squeeze power (NULL: the samples' f_n and theta_rad). Returns 4
 * when taken, else the first lane off the fast path (theta off the tracker's line, a step not
 * positive): nothing added. */
static CYCLE_INLINE int run_block(run_vec *w, unsigned *ev, int *n_ev, const run_consts *k,
                                  const afm_sample *const a[4], const double *th4, int k0, int nv,
                                  const double *f4, const double *q4) {
    /* (t, x) and (v, f) of samples 0, 2 and 1, 3 side by side, then transposed */
#define TX(i, fld) (*(const cycle_v2 *)(const void *)&a[i]->fld)
    afm_v4 u0 = __builtin_shufflevector(TX(0, t_s), TX(2, t_s), 0, 1, 2, 3);
    afm_v4 u1 = __builtin_shufflevector(TX(1, t_s), TX(3, t_s), 0, 1, 2, 3);
    afm_v4 u2 = __builtin_shufflevector(TX(0, v_m_s), TX(2, v_m_s), 0, 1, 2, 3);
    afm_v4 u3 = __builtin_shufflevector(TX(1, v_m_s), TX(3, v_m_s), 0, 1, 2, 3);
    afm_v4 T = __builtin_shufflevector(u0, u1, 0, 4, 2, 6),
           X = __builtin_shufflevector(u0, u1, 1, 5, 3, 7);
    afm_v4 V = __builtin_shufflevector(u2, u3, 0, 4, 2, 6), F, Q;
    if (f4) {
        F = AFM_V4_LD(f4);
        Q = AFM_V4_LD(q4);
    } else {
        afm_v4 u4 = __builtin_shufflevector(TX(0, theta_rad), TX(2, theta_rad), 0, 1, 2, 3);
        afm_v4 u5 = __builtin_shufflevector(TX(1, theta_rad), TX(3, theta_rad), 0, 1, 2, 3);
        F = __builtin_shufflevector(u2, u3, 1, 5, 3, 7);
        Q = __builtin_shufflevector(u4, u5, 0, 4, 2, 6);
    }
#undef TX
    /* the fast path: theta on the tracker's line, a positive step */
    afm_v4 Tpp = LAG2(w->t, T), H = T - LAG1(Tpp, T);
    afm_v4 err = AFM_V4_FMA(w->nn, k->dphi, AFM_V4_LD(th4) - k->ref);
    /* |err| <= tol (the sign bit cleared): err <= tol and err >= -tol, NaN neither */
    afm_v4 aerr = (afm_v4)((afm_v4i)err & ~(afm_v4i)AFM_V4_SET1(-0.0));
    afm_v4i bad = ~(afm_v4i)(aerr <= k->tol) | ~(afm_v4i)(H > 0.0);
    afm_v4 Xq = X, W = T - Tpp; /* w of the previous samples (Xp, Fp Vp) */
    if (nv < 4) {               /* the repeated lanes, and the last valid sample's own weight */
        afm_v4i keep = (afm_v4i)((afm_v4){0.0, 1.0, 2.0, 3.0} < (double)nv);
        Xq = SEL4(keep, X, AFM_V4_SET1(HUGE_VAL));
        W = (afm_v4)((afm_v4i)W & keep);
    }
    /* flags: contact crossing, local maximum of f at the previous sample, a Bernstein
     * control point below the minimum of x of the lane */
    afm_v4 Xp = LAG1(LAG2(w->x, X), X), Vp = LAG1(LAG2(w->v, V), V);
    afm_v4i cr = (afm_v4i)(X < k->xc) ^ (afm_v4i)(Xp < k->xc);
    afm_v4 Fpp = LAG2(w->f, F), Fp = LAG1(Fpp, F);
    /* the sums at once, while Xp, Vp, Fp are in registers (put in w only when the block is
     * taken): later, gcc rebuilt Xp lane by lane from spilled halves of the loads (issue 12) */
    const afm_v4 fv = AFM_V4_FMA(W, Fp * Vp, w->fv), xs = AFM_V4_FMA(W, Xp, w->xs);
    const afm_v4 sq = AFM_V4_FMA(W, LAG1(LAG2(w->q, Q), Q), w->sq);
    afm_v4i lm = (afm_v4i)(Fp >= Fpp) & (afm_v4i)(Fp >= F);
    afm_v4 H3 = H * k->third, XM = MIN4(w->xm, Xq);
    /* + z0 (+0.0, not known to the compiler): vector values, so that the fmas below are
     * vfmadds and not 8 scalar ones on the samples' loads (issue 12); it changes at most the
     * sign of a zero, which the comparisons below do not see */
    afm_v4 b1 = AFM_V4_FMA(H3, Vp + k->z0, Xp + k->z0), b2 = AFM_V4_FNMA(H3, V + k->z0, X + k->z0);
    afm_v4 bmin = MIN4(b1, b2), xpm = MIN4(Xp, X);
    afm_v4i mn = (afm_v4i)(bmin < xpm);
    afm_v4i ct = ((afm_v4i)(X < k->xn) | (afm_v4i)(Xp < k->xn)) & k->ctm;
    afm_v4i any = ((bad | mn) | (cr | lm)) | ct;
    unsigned fb = 0; /* the flags, bad lanes at bits 16..19 (flag_bits) */
    if (nv < 4)
        fb = flag_bits(lm, cr, mn, ct, bad) & ((1u << nv) - 1u) * 0x11111u;
    else if (ANY4(any))
        fb = flag_bits(lm, cr, mn, ct, bad);
    if (fb) {
        if (fb >> 16) return lowest_bit(fb >> 16);
        ev[(*n_ev)++] = (unsigned)k0 << 16 | fb;
    }
    w->fv = fv;
    w->xs = xs;
    w->sq = sq;
    w->xm = XM;
    w->t = T;
    w->x = X;
    w->v = V;
    w->f = F;
    w->q = Q;
    w->nn = w->nn - 4.0;
    return 4;
}

/* (a[o & 3], a[(o + 1) & 3], a[(o + 2) & 3], a[(o + 3) & 3]) as lanes 0..3, and back
 * (o = 0 mod 4 after a boundary: a plain load). */
static inline void lanes_from(const double *a, long o, afm_v4 *v) {
    const afm_v4 x = AFM_V4_LD(a); /* one load and a rotation (issue 12) */
    switch (o & 3) {
    case 0:
        *v = x;
        break;
    case 1:
        *v = __builtin_shufflevector(x, x, 1, 2, 3, 0);
        break;
    case 2:
        *v = __builtin_shufflevector(x, x, 2, 3, 0, 1);
        break;
    default:
        *v = __builtin_shufflevector(x, x, 3, 0, 1, 2);
        break;
    }
}
static inline void lanes_to(double *a, long o, const afm_v4 *v) {
    const afm_v4 x = *v;
    switch (o & 3) {
    case 0:
        AFM_V4_ST(a, x);
        break;
    case 1:
        AFM_V4_ST(a, __builtin_shufflevector(x, x, 3, 0, 1, 2));
        break;
    case 2:
        AFM_V4_ST(a, __builtin_shufflevector(x, x, 2, 3, 0, 1));
        break;
    default:
        AFM_V4_ST(a, __builtin_shufflevector(x, x, 1, 2, 3, 0));
        break;
    }
}

/* The sums over the first samples of s[0 .. m-1] that pass the fast-path test (theta on
 * the tracker's line, a positive step): returns how many; the lanes in w. fs, qs: the split
 * given apart (r->fs, r->qs; NULL: the samples' own), a parameter so that each case inlines
 * on its own. */
static CYCLE_INLINE int run_sums_of(const run_state *r, const afm_cycle *c, const afm_sample *s,
                                    const double *th, int m, run_vec *wo, run_flags *out,
                                    const double *fs, const double *qs) {
#define RUN_F(i) (fs ? fs[i] : s[i].f_n)
#define RUN_Q(i) (fs ? qs[i] : s[i].theta_rad)
    const afm_sample *p0 = r->p0;
    const afm_phase_track *tk = &c->trk;
    double n0 = tk->n;
    run_consts k;
    k.ref = AFM_V4_SET1(tk->th_ref);
    k.dphi = AFM_V4_SET1(tk->dphi);
    k.tol = AFM_V4_SET1(tk->tol);
    k.xc = AFM_V4_SET1(r->xc);
    k.third = AFM_V4_SET1(1.0 / 3.0);
    k.xn = AFM_V4_SET1(c->x_near_m);
    k.z0 = AFM_V4_SET1(0.0 * c->cos_alpha); /* +0.0: cos_alpha is in (0, 1] */
    k.ctm = (afm_v4i)AFM_V4_SET1(0.0) - (c->forces ? 1 : 0);
    run_vec w;
    w.t = (afm_v4){0.0, 0.0, r->t_m2, p0->t_s};
    w.x = AFM_V4_SET1(p0->x_m);
    w.v = AFM_V4_SET1(p0->v_m_s);
    w.f = (afm_v4){0.0, 0.0, r->f_m2, p0->f_n};
    w.q = AFM_V4_SET1(p0->theta_rad);
    w.nn = -(afm_v4){n0 + 1.0, n0 + 2.0, n0 + 3.0, n0 + 4.0};
    lanes_from(c->sum_fv, c->k, &w.fv); /* lane l: the sample k + l (p0 is lane 0) */
    lanes_from(c->sum_x, c->k, &w.xs);
    lanes_from(c->sum_sq, c->k, &w.sq);
    w.xm = AFM_V4_SET1(c->smin); /* lane l: the samples k + 1 + l mod 4 and before */
    int n_ev = 0, j = 0, l = 4;
    for (; j + 8 <= m; j += 8) { /* two blocks a step (no register moves) */
        const afm_sample *a[4] = {s + j, s + j + 1, s + j + 2, s + j + 3};
        l = run_block(&w, out->ev, &n_ev, &k, a, th + j, j, 4, fs ? fs + j : NULL,
                      fs ? qs + j : NULL);
        if (l < 4) break;
        const afm_sample *b[4] = {s + j + 4, s + j + 5, s + j + 6, s + j + 7};
        l = run_block(&w, out->ev, &n_ev, &k, b, th + j + 4, j + 4, 4, fs ? fs + j + 4 : NULL,
                      fs ? qs + j + 4 : NULL);
        if (l < 4) {
            j += 4;
            break;
        }
    }
    for (; l == 4 && j + 4 <= m; j += 4) {
        const afm_sample *a[4] = {s + j, s + j + 1, s + j + 2, s + j + 3};
        l = run_block(&w, out->ev, &n_ev, &k, a, th + j, j, 4, fs ? fs + j : NULL,
                      fs ? qs + j : NULL);
        if (l < 4) break;
    }
    if (l < 4) { /* w as before the block, from the samples (not kept in registers) */
        m = j + l;
        const afm_sample *q1 = j > 0 ? s + j - 1 : p0;
        double t2 = j > 1 ? s[j - 2].t_s : j > 0 ? p0->t_s : r->t_m2;
        w.t = (afm_v4){0.0, 0.0, t2, q1->t_s};
        w.x = AFM_V4_SET1(q1->x_m);
        w.v = AFM_V4_SET1(q1->v_m_s);
        w.f = (afm_v4){0.0, 0.0,
                       j > 1   ? RUN_F(j - 2)
                       : j > 0 ? p0->f_n
                               : r->f_m2,
                       j > 0 ? RUN_F(j - 1) : p0->f_n};
        w.q = AFM_V4_SET1(j > 0 ? RUN_Q(j - 1) : p0->theta_rad);
        w.nn = -(afm_v4){n0 + j + 1.0, n0 + j + 2.0, n0 + j + 3.0, n0 + j + 4.0};
    }
    while (j < m) { /* the last 1-3 samples, the last one repeated */
        int v = m - j, l1 = v > 1 ? j + 1 : m - 1, l2 = v > 2 ? j + 2 : m - 1;
        const afm_sample *a[4] = {s + j, s + l1, s + l2, s + m - 1};
        double t4[4] = {th[j], th[l1], th[l2], th[m - 1]};
        double f4[4], q4[4];
        if (fs) {
            f4[0] = fs[j], f4[1] = fs[l1], f4[2] = fs[l2], f4[3] = fs[m - 1];
            q4[0] = qs[j], q4[1] = qs[l1], q4[2] = qs[l2], q4[3] = qs[m - 1];
        }
        l = run_block(&w, out->ev, &n_ev, &k, a, t4, j, v, fs ? f4 : NULL, fs ? q4 : NULL);
        if (l == 4) break;
        m = j + l;
    }
    out->n_ev = n_ev;
    *wo = w;
    return m;
#undef RUN_F
#undef RUN_Q
}

/* A run over s[0 .. m-1] (m <= RUN_MAX, fast-path room for m samples, period active, full
 * history), without split (fs NULL) or with its split in fs[0 .. m-1], qs[0 .. m-1] (force and
 * squeeze power, afm_cycle_split_forces). Returns the samples taken (0: none, the caller
 * pushes the next one), or -k: the first k samples hold a value that is not finite; nothing
 * changed (the caller pushes them one at a time). */
AFM_CLONES static int run(afm_cycle *c, const afm_sample *s, const double *th, int m,
                          const double *fs, const double *qs) {
    const afm_sample *p0 = &c->prev;
    afm_cycle_metrics *cm = &c->cur;
    run_state r = {.s = s,
                   .fs = fs,
                   .qs = qs,
                   .c = c,
                   .p0 = p0,
                   .m2 = &c->prev2,
                   .f_m2 = c->prev2.f_n,
                   .t_m2 = c->t_before,
                   .xc = c->x_contact_m,
                   .ct = cm->contact_time_s,
                   .t_in = c->t_in,
                   .v_in = NAN,
                   .pk = cm->peak_force_n,
                   .xmin = cm->min_deflection_m,
                   .ec = c->e_corr,
                   .nc = 0};
    run_flags fl;
    run_vec w;
    m = fs ? run_sums_of(&r, c, s, th, m, &w, &fl, fs, qs)
           : run_sums_of(&r, c, s, th, m, &w, &fl, NULL, NULL);
    if (m == 0) return 0;
    /* a value that is not finite makes the sums not finite */
    afm_v4 z = (w.fv + w.xs) * 0.0;
    if (ANY4((afm_v4i)(z != z))) return -m;
    if (fl.n_ev) run_events(&r, &fl);
    lanes_to(c->sum_fv, c->k, &w.fv);
    lanes_to(c->sum_x, c->k, &w.xs);
    lanes_to(c->sum_sq, c->k, &w.sq);
    c->smin = hmin4(&w.xm);
    const afm_sample *q = s + m - 1;
    cm->contact_time_s = r.ct;
    if (r.nc > 0) {
        if (cm->n_contacts == 0) cm->pre_contact_velocity_m_s = r.v_in;
        cm->n_contacts += r.nc;
    }
    cm->min_deflection_m = r.xmin;
    c->e_corr = r.ec;
    const double qf = fs ? fs[m - 1] : q->f_n;
    cm->peak_force_n = qf > r.pk ? qf : r.pk;
    c->t_in = r.t_in;
    c->t_before = m >= 2 ? s[m - 2].t_s : p0->t_s;
    if (m >= 2) {
        run_keep(&r, m - 2, &c->prev2);
    } else {
        copy_sample(&c->prev2, p0);
    }
    c->k += m;
    run_keep(&r, m - 1, &c->prev);
    c->trk.n += m;
    c->trk.th_prev = th[m - 1];
    return m;
}

/* afm_cycle_push for a sample known to be off the tracker's fast path (afm_track_fast
 * would fail): its checks, then the exact clock. f, qs (with split; NULL without): its split
 * force and squeeze power given apart (afm_cycle_split_forces, as the runs read them). */
static CYCLE_INLINE int push_exact(afm_cycle *c, const afm_sample *q, double th, const double *f,
                                   const double *qs) {
    /* all finite: the products with 0 are all +-0 (NaN otherwise) */
    double z = (q->t_s * 0.0 + q->x_m * 0.0) + (q->v_m_s * 0.0 + q->f_n * 0.0);
    if (!(z == 0.0 && !(c->n_prev > 0 && !(q->t_s > c->prev.t_s)))) return -1;
    afm_sample sp;
    if (f) {
        copy_sample(&sp, q);
        sp.f_n = *f;
        sp.theta_rad = *qs;
        q = &sp;
    }
    return push_slow(c, q, th);
}

/* afm_cycle_push_n_split's work, with split given apart (f_ts, p_sq; not read without
 * split): one path for the chain's split and the one split_here takes. */
static CYCLE_INLINE int push_n_core(afm_cycle *c, const afm_sample *s, const double *th,
                                    const double *f_ts, const double *p_sq, int n, int *done,
                                    long long *rejects) {
    *done = 0;
    int i = 0, one_by_one = 0;
    while (i < n) {
        bool off = false; /* the next sample is off the fast path (a boundary, mostly) */
        if (one_by_one == 0 && c->active && c->n_prev >= 2) {
            double room = c->trk.n_end - c->trk.n;
            off = !(room >= 1.0);
            int m = n - i < RUN_MAX ? n - i : RUN_MAX;
            if (c->split && m > SPLIT_MAX) m = SPLIT_MAX;
            if (room < m) m = room > 0 ? (int)room : 0;
            if (m >= RUN_MIN) {
                int k = c->split ? run(c, s + i, th + i, m, f_ts + i, p_sq + i)
                                 : run(c, s + i, th + i, m, NULL, NULL);
                if (k > 0) {
                    i += k;
                    /* a run that took the whole room: the next sample is off the fast path */
                    if (!(room == (double)k && i < n)) continue;
                    off = true;
                } else {
                    one_by_one = -k;
                }
            }
        }
        int rc = !off       ? afm_cycle_push(c, &s[i], th[i])
                 : c->split ? push_exact(c, &s[i], th[i], f_ts + i, p_sq + i)
                            : push_exact(c, &s[i], th[i], NULL, NULL);
        i++;
        if (one_by_one > 0) one_by_one--;
        if (rc < 0) (*rejects)++;
        if (rc == 1) {
            *done = 1;
            break;
        }
    }
    return i;
}

/* afm_cycle_push_n_split with split and no split given: the split taken here
 * (afm_cycle_split_forces) SPLIT_MAX samples at a time (the same bits however the stream is
 * cut), out of the hot function's way. */
static AFM_CLONES_NOINLINE int split_here(afm_cycle *c, const afm_sample *s, const double *th,
                                          int n, int *done, long long *rejects) {
    double f[SPLIT_MAX], q[SPLIT_MAX];
    int i = 0;
    *done = 0;
    while (i < n && !*done) {
        int m = n - i < SPLIT_MAX ? n - i : SPLIT_MAX;
        afm_cycle_split_forces(c, s + i, m, f, q);
        i += afm_cycle_push_n_split(c, s + i, th + i, f, q, m, done, rejects);
    }
    return i;
}

int afm_cycle_push_n(afm_cycle *c, const afm_sample *s, const double *th, int n, int *done,
                     long long *rejects) {
    return afm_cycle_push_n_split(c, s, th, NULL, NULL, n, done, rejects);
}

AFM_CLONES int afm_cycle_push_n_split(afm_cycle *c, const afm_sample *s, const double *th,
                                      const double *f_ts, const double *p_sq, int n, int *done,
                                      long long *rejects) {
    if (c->split && !f_ts) return split_here(c, s, th, n, done, rejects);
    return push_n_core(c, s, th, f_ts, p_sq, n, done, rejects);
}
