/* SPDX-License-Identifier: MIT */
/* afm_harm.c -- streaming per-period harmonics (contract in afm_harm.h). */
#include "estimators/afm_harm.h"

#include "config/afm_clones.h"

#include <stdio.h>
#include <string.h>

#define RE(j) (((j) >> 2) * 8 + ((j)&3)) /* lane j in a grouped complex array */
#define IM(j) (RE(j) + 4)

#if defined(__GNUC__)
#define ALWAYS_INLINE __attribute__((always_inline))
#else
#define ALWAYS_INLINE
#endif

/* Empty state for the harmonic list already in h (nk, nl, ks). */
static void clear_state(afm_harm *h) {
    afm_track_init(&h->trk, true);
    h->active = false;
    h->x_prev = h->f_prev = 0.0;
    for (int j = 0; j < 2 * AFM_HARM_LANES; j++)
        h->b[j] = h->cx[j] = h->cf[j] = h->sx[j] = h->sf[j] = 0.0;
    for (int j = 0; j < h->nl; j++) {
        h->b[RE(j)] = 1.0;
        h->tab[RE(j)] = 1.0; /* entry 0: e^0; the rest is built when the tracker locks */
        h->tab[IM(j)] = 0.0;
    }
    h->nbase = 0.0;
    h->wsum = h->nsteps = 0.0;
    h->imp_ref = 0.0;
    h->n_sync = HUGE_VAL; /* the first sample is computed exactly */
    h->periods = 0;
    memset(&h->out, 0, sizeof h->out);
    h->out.n_harmonics = h->nk;
    for (int j = 0; j < h->nk; j++)
        h->out.h[j].k = h->ks[j];
    h->out_at = NULL;
}

int afm_harm_init(afm_harm *h, const int *ks, int nk, char *err, size_t errlen) {
    if (!h || !ks || nk < 1 || nk > AFM_MAX_HARMONICS) {
        if (err && errlen)
            snprintf(err, errlen, "harmonics: need 1..%d harmonic numbers", AFM_MAX_HARMONICS);
        return -1;
    }
    for (int j = 0; j < nk; j++)
        if (ks[j] < 1 || ks[j] > AFM_HARM_MAX_K) {
            if (err && errlen)
                snprintf(err, errlen, "harmonics: harmonic number %d not in 1..%d", ks[j],
                         AFM_HARM_MAX_K);
            return -1;
        }
    memset(h, 0, sizeof *h);
    h->nk = nk;
    memcpy(h->ks, ks, (size_t)nk * sizeof *ks);
    h->lane1 = -1;
    for (int j = 0; j < nk && h->lane1 < 0; j++)
        if (ks[j] == 1) h->lane1 = j;
    int used = nk;
    if (h->lane1 < 0) {
        h->lane1 = nk;
        h->ks[used++] = 1;
    }
    h->nl = (used + 3) / 4 * 4;
    for (int j = 0; j < AFM_HARM_LANES; j++)
        h->kd[j] = (double)h->ks[j];
    clear_state(h);
    return 0;
}

void afm_harm_reset(afm_harm *h) {
    clear_state(h);
}

/* e^{-i k phi} from c + i s = e^{-i phi} by binary powering (k = 0: 1). */
static void rot_pow(double c, double s, int k, double *re, double *im) {
    double rr = 1.0, ri = 0.0;
    while (k) {
        if (k & 1) {
            double t = rr * c - ri * s;
            ri = rr * s + ri * c;
            rr = t;
        }
        k >>= 1;
        if (k) {
            double t = c * c - s * s;
            s = 2.0 * c * s;
            c = t;
        }
    }
    *re = rr;
    *im = ri;
}

/* e^{-ik phi} on every lane into p (grouped), exactly from phi. */
AFM_EST_COLD static void phasors_exact(const afm_harm *h, double phi, double *p) {
    double c1 = cos(phi), s1 = -sin(phi);
    for (int j = 0; j < h->nl; j++)
        rot_pow(c1, s1, h->ks[j], &p[RE(j)], &p[IM(j)]);
}

/* The table for the tracker's (new) dphi: T[0] = 1, T[m] = T[m - 1] e^{-ik dphi}.
 * Multiversioned (one vfmadd per AFM_V4_FMA lane in the x86-64-v3 copy, not a libm call: the
 * same bits at a fraction of the cost; under FM it runs once per NCO step). */
AFM_CLONES_NOINLINE static void build_table(afm_harm *h) {
    const int st = 2 * h->nl;
    double r[2 * AFM_HARM_LANES];
    double cd = cos(h->trk.dphi), sd = -sin(h->trk.dphi);
    for (int j = 0; j < h->nl; j++) {
        rot_pow(cd, sd, h->ks[j], &r[RE(j)], &r[IM(j)]);
        h->tab[RE(j)] = 1.0;
        h->tab[IM(j)] = 0.0;
    }
    for (int m = 1; m <= AFM_HARM_TAB; m++) {
        const double *a = h->tab + (size_t)(m - 1) * st;
        double *o = h->tab + (size_t)m * st;
        for (int g = 0; g < st; g += 8) {
            afm_v4 re, im;
            AFM_V4_CMUL(AFM_V4_LD(a + g), AFM_V4_LD(a + g + 4), AFM_V4_LD(r + g),
                        AFM_V4_LD(r + g + 4), re, im);
            AFM_V4_ST(o + g, re);
            AFM_V4_ST(o + g + 4, im);
        }
    }
}

/* s += p c over the lanes (complex, grouped): the chunk sums c rotated by the base phasor p. */
static inline void cmadd(double *s, const double *p, const double *c, int st) {
    for (int g = 0; g < st; g += 8) {
        afm_v4 pr = AFM_V4_LD(p + g), pi = AFM_V4_LD(p + g + 4);
        afm_v4 cr = AFM_V4_LD(c + g), ci = AFM_V4_LD(c + g + 4);
        AFM_V4_ST(s + g, AFM_V4_FMA(pr, cr, AFM_V4_FNMA(pi, ci, AFM_V4_LD(s + g))));
        AFM_V4_ST(s + g + 4, AFM_V4_FMA(pr, ci, AFM_V4_FMA(pi, cr, AFM_V4_LD(s + g + 4))));
    }
}

/* The chunk into the period sums (s += b c for x and f), the base phasor b moved on by the
 * table row `row` (the chunk's end), the chunk sums cleared: a full chunk of the fast path,
 * or the part chunk a rebase closes. */
static inline void fold_chunk(afm_harm *h, const double *row, int st) {
    cmadd(h->sx, h->b, h->cx, st);
    cmadd(h->sf, h->b, h->cf, st);
    for (int g = 0; g < st; g += 8) {
        afm_v4 re, im;
        AFM_V4_CMUL(AFM_V4_LD(h->b + g), AFM_V4_LD(h->b + g + 4), AFM_V4_LD(row + g),
                    AFM_V4_LD(row + g + 4), re, im);
        AFM_V4_ST(h->b + g, re);
        AFM_V4_ST(h->b + g + 4, im);
    }
    memset(h->cx, 0, (size_t)st * sizeof h->cx[0]);
    memset(h->cf, 0, (size_t)st * sizeof h->cf[0]);
}

/* Lane selection (SEL4: m ? x : y per lane, m a lane mask), the sign bit. */
#define SEL4(m, x, y) ((afm_v4)(((m) & (afm_v4i)(x)) | (~(m) & (afm_v4i)(y))))
#define SIGN4 ((afm_v4i)AFM_V4_SET1(-0.0))

/* atan2 of 4 lanes (*out = atan2(*y, *x)), within 2 ulp of libm's (checked on 1.6e7 random
 * pairs over 12 decades of |y| / |x|): the octant reduction to t = min(|x|, |y|) / max(|x|,
 * |y|) in [0, 1], t > 0.66 mapped to (t - 1) / (t + 1) around pi / 4, then Cephes's atan
 * rational P(t^2)/Q(t^2) (S. Moshier, Cephes Math Library atan.c: P degree 4, Q degree 5,
 * about 1e-16 relative), then pi / 2 - r, pi - r (with the low parts of pi / 2, pi) and the
 * sign of y. Lanes with max(|x|, |y|) = 0 or not finite are not handled here (t is NaN): the
 * caller checks. Every build computes the same bits (afm_v4: one rounding per operation). */
static inline AFM_EST_INLINE void atan2_v4(const afm_v4 *py, const afm_v4 *px, afm_v4 *out) {
    const afm_v4 y = *py, x = *px, one = AFM_V4_SET1(1.0);
    afm_v4 ax = (afm_v4)((afm_v4i)x & ~SIGN4), ay = (afm_v4)((afm_v4i)y & ~SIGN4);
    afm_v4 mx = SEL4((afm_v4i)(ax > ay), ax, ay), mn = SEL4((afm_v4i)(ax < ay), ax, ay);
    afm_v4 t = mn / mx;
    afm_v4i big = (afm_v4i)(t > 0.66);
    afm_v4 tr = SEL4(big, (t - one) / (t + one), t);
    afm_v4 z = tr * tr;
    afm_v4 p = AFM_V4_SET1(-8.750608600031904122785E-1);
    p = AFM_V4_FMA(p, z, AFM_V4_SET1(-1.615753718733365076637E1));
    p = AFM_V4_FMA(p, z, AFM_V4_SET1(-7.500855792314704667340E1));
    p = AFM_V4_FMA(p, z, AFM_V4_SET1(-1.228866684490136173410E2));
    p = AFM_V4_FMA(p, z, AFM_V4_SET1(-6.485021904942025371773E1));
    afm_v4 q = z + 2.485846490142306297962E1;
    q = AFM_V4_FMA(q, z, AFM_V4_SET1(1.650270098316988542046E2));
    q = AFM_V4_FMA(q, z, AFM_V4_SET1(4.328810604912902668951E2));
    q = AFM_V4_FMA(q, z, AFM_V4_SET1(4.853903996359136964868E2));
    q = AFM_V4_FMA(q, z, AFM_V4_SET1(1.945506571482613964425E2));
    afm_v4 r = AFM_V4_FMA(tr, (z * p) / q, tr);
    /* + pi/4 (with its low part) in the upper range */
    r = r + (afm_v4)(big & (afm_v4i)AFM_V4_SET1(3.061616997868382943065E-17));
    r = r + (afm_v4)(big & (afm_v4i)AFM_V4_SET1(7.85398163397448278999E-1));
    /* |y| > |x|: pi/2 - r */
    afm_v4 r2 = (1.57079632679489655800 - r) + 6.123233995736765886130E-17;
    r = SEL4((afm_v4i)(ay > ax), r2, r);
    /* x < 0 (its sign bit): pi - r */
    afm_v4 r3 = (3.14159265358979311600 - r) + 1.2246467991473531772E-16;
    r = SEL4((afm_v4i)x >> 63, r3, r);
    *out = (afm_v4)((afm_v4i)r | ((afm_v4i)y & SIGN4));
}

/* polar4's lanes it does not take: zero, tiny, huge or not finite */
AFM_EST_COLD static void polar_scalar(const double *z, double *ph, double *mag) {
    for (int l = 0; l < 4; l++) {
        ph[l] = atan2(z[4 + l], z[l]);
        mag[l] = afm_est_hypot(z[l], z[4 + l]);
    }
}

/* afm_phase_diff_deg(k, phi1, ph) on 4 lanes: v = k (pi - phi1) + ph (a = pi - phi1),
 * reduced mod 2 pi as afm_clock_wrap (|v| < 2^52), in degrees, 360 read as 0. */
static inline AFM_EST_INLINE void phase_diff4(const double *kd, double a, const double *ph,
                                              afm_v4 *pd) {
    const afm_v4 two_pi = AFM_V4_SET1(AFM_EST_TWO_PI), one = AFM_V4_SET1(1.0);
    afm_v4 vv = AFM_V4_LD(kd) * a + AFM_V4_LD(ph);
    afm_v4 m = vv * (1.0 / AFM_EST_TWO_PI);
    for (int l = 0; l < 4; l++)
        m[l] = __builtin_floor(m[l]);
    afm_v4 w = AFM_V4_FNMA(m, two_pi, vv);
    afm_v4i lo = (afm_v4i)(w < 0.0), hi = (afm_v4i)(w >= two_pi);
    m = (m + (afm_v4)(hi & (afm_v4i)one)) - (afm_v4)(lo & (afm_v4i)one);
    afm_v4 deg = AFM_V4_FNMA(m, two_pi, vv) * AFM_EST_RAD2DEG;
    *pd = (afm_v4)(~(afm_v4i)(deg >= 360.0) & (afm_v4i)deg);
}

/* Phases atan2(y, x) (rad) and magnitudes |x + i y| (afm_est_hypot's value) of 4 lanes: x
 * in z[0..4), y in z[4..8). */
static inline AFM_EST_INLINE void polar4v(const double *z, double *ph, double *mag) {
    afm_v4 x = AFM_V4_LD(z), y = AFM_V4_LD(z + 4);
    afm_v4 q = x * x + y * y; /* as afm_est_hypot */
    /* q in (1e-290, 1e290): afm_est_hypot's sqrt, and max(|x|, |y|) > 0 and finite */
    afm_v4i ok = (afm_v4i)(q > 1e-290) & (afm_v4i)(q < 1e290);
    if ((ok[0] & ok[1]) & (ok[2] & ok[3])) {
        afm_v4 at;
        atan2_v4(&y, &x, &at);
        AFM_V4_ST(ph, at);
        for (int l = 0; l < 4; l++)
            mag[l] = __builtin_sqrt(q[l]);
        return;
    }
    polar_scalar(z, ph, mag);
}

void afm_harm_set_deferred(afm_harm *h, bool deferred) {
    h->deferred = deferred;
}

/* The polar form of a completed period's sums: the phases (rad) and magnitudes of x on every
 * lane (pxs, axs) and of f on the configured ones (pfs, afs) by polar4v, then eq.
 * E.12-E.13 and the records, 4 lanes at a time. */
AFM_CLONES void afm_harm_polar(const afm_harm *h, afm_harm_result *r) {
    double pxs[AFM_HARM_LANES], axs[AFM_HARM_LANES], pfs[AFM_HARM_LANES], afs[AFM_HARM_LANES];
    for (int l = 0; l < h->nl; l += 4) {
        const double *z = r->raw + 4 * l;
        polar4v(z, pxs + l, axs + l);
        if (l < h->nk) polar4v(z + 8, pfs + l, afs + l);
    }
    const double scale = 2.0 / r->samples;
    const double a = AFM_EST_PI - pxs[h->lane1]; /* pi - phi_1 */
    r->n_harmonics = h->nk;
    for (int j = 0; j < h->nk; j++)
        r->h[j].k = h->ks[j];
    for (int j = 0; j < h->nk; j += 4) {
        afm_v4 pd;
        phase_diff4(h->kd + j, a, pxs + j, &pd);
        afm_v4 ax = AFM_V4_LD(axs + j) * scale, af = AFM_V4_LD(afs + j) * scale;
        afm_v4 px = AFM_V4_LD(pxs + j) * AFM_EST_RAD2DEG, pf = AFM_V4_LD(pfs + j) * AFM_EST_RAD2DEG;
        afm_orbit_harmonic *o = r->h + j;
        int n = h->nk - j < 4 ? h->nk - j : 4;
        for (int l = 0; l < n; l++) {
            o[l].x_amp_m = ax[l];
            o[l].x_phase_deg = px[l];
            o[l].f_amp_n = af[l];
            o[l].f_phase_deg = pf[l];
            o[l].phase_diff_deg = pd[l];
        }
    }
}

/* What one sample off the fast path does, worked out by harm_slow_clock and
 * harm_slow_weights before harm_slow_lanes applies it to every lane. */
typedef struct {
    bool had_prev, active; /* a sample before this one; a period running before it */
    bool exact;            /* this sample's phasors computed exactly (pex), not rotated */
    bool rate_changed;     /* the clock's step dphi changed: rebuild the table afterwards */
    bool cross;            /* this step ends a period: its sums go out (h->out) */
    bool start;            /* a period starts at this sample or inside the step just taken */
    int ev;                /* AFM_CLOCK_NONE, _START or _CROSS */
    double frac;           /* fraction of the step before the boundary (CROSS), else 1 */
    double e_rad;          /* residual theta - imp of the rotated phasors (rad) */
    const double *tm;      /* the table row of the previous sample */
    double wb[2], wa[2];   /* weights (previous, this sample) before / after the boundary */
    double wx, wf;         /* this sample into the new chunk: weight x x (m), weight x f (N) */
    double samples;        /* the ending period's length in samples (fractional ends) */
} harm_slow_step;

/* The exact clock for theta (rad): theta mod 2 pi (phi, the phase since the last boundary;
 * at a boundary e^{-ik phi} is the same for both periods since k is an integer), the
 * tracker advanced, and whether the phasors rotate one more step (standing then for imp,
 * within tol of theta) or are computed exactly into pex. -1 (rejected, nothing changed) or
 * 0. */
static inline ALWAYS_INLINE int harm_slow_clock(afm_harm *h, double theta_rad, harm_slow_step *s,
                                                double *pex) {
    double phi;
    const afm_phase_track *t = &h->trk;
    const double n1 = t->n + 1.0, imp = h->imp_ref + n1 * t->dphi, tol = t->tol;
    /* On the tracker's prediction (only the boundary or the window ended the fast path):
     * theta - theta_prev is dphi within 2 tol (theta_prev was on it too), and a locked clock
     * has dphi in (4 tol, pi - 4 tol), so the step passes afm_track_check (theta mod 2 pi is
     * exact, the step rounds by less than tol): only theta mod 2 pi is needed. */
    const bool on_pred = t->locked && fabs((theta_rad - t->th_ref) - n1 * t->dphi) <= tol;
    if (on_pred)
        phi = afm_clock_wrap(theta_rad);
    else if (afm_track_check(&h->trk, theta_rad, &phi) != AFM_CLOCK_NONE)
        return -1;
    s->had_prev = h->trk.started;
    s->active = h->active;
    const bool rotate =
        on_pred && h->n_sync + n1 <= AFM_TRACK_WINDOW_CLOCK && fabs(theta_rad - imp) <= tol;
    s->tm = h->tab + (size_t)(int)(t->n - h->nbase) * (2 * h->nl); /* previous sample */
    s->frac = 1.0;
    s->ev = afm_track_advance(&h->trk, theta_rad, phi, &s->frac, &s->rate_changed);
    s->exact = !(rotate && h->trk.locked);
    if (s->exact) {
        phasors_exact(h, phi, pex);
        h->n_sync = 0.0;
    } else {
        h->n_sync += n1;
    }
    h->imp_ref = theta_rad;
    s->e_rad = theta_rad - imp;
    return 0;
}

/* The weights of the clock's event. cross: this step ends the period (the previous sample
 * already has weight 1, 0.5 from each side; the step's part before the boundary is wb[0]
 * g_prev + wb[1] g_cur); start: a period starts at this sample or inside the step just
 * taken: this sample gets the after-boundary weight plus 0.5 from the next step, the
 * previous one wa[0]. Also the new chunk's weights of x (m) and f (N): 1, nothing before
 * the first boundary. */
static inline ALWAYS_INLINE void harm_slow_weights(afm_harm *h, double x, double f,
                                                   harm_slow_step *s) {
    s->cross = s->had_prev && s->active && s->ev == AFM_CLOCK_CROSS;
    s->start = s->ev == AFM_CLOCK_START || (s->ev == AFM_CLOCK_CROSS && s->had_prev);
    s->wb[0] = s->wb[1] = s->wa[0] = s->wa[1] = 0.0;
    if (s->ev == AFM_CLOCK_CROSS) afm_split_weights(s->frac, s->wb, s->wa);
    if (s->had_prev && s->active && !s->cross) h->nsteps += 1.0;
    s->samples = (h->wsum + h->nsteps) + s->frac;
    s->wx = s->active ? x : 0.0;
    s->wf = s->active ? f : 0.0;
    if (s->start) {
        s->wx = (s->wa[1] + 0.5) * x;
        s->wf = (s->wa[1] + 0.5) * f;
        h->wsum = s->ev == AFM_CLOCK_CROSS ? 1.0 - s->frac : 0.0;
        h->nsteps = 0.0;
        h->active = true;
    }
}

/* One pass over the lanes: the previous sample's phasor ep = b T[m]; the phasor p for this
 * sample on the rotation, b T[m + 1] times e^{-ik e} ~ 1 - i k e for the residual e = theta
 * - imp (|k e| < 1e-6: the dropped terms are below 1e-12 of it), or exact (pex); the chunk
 * into the period sums (s += b c); the ends of a completed period (into out.raw, or out_to's); the
 * new period's sums; the new chunk (c = w x: the phasor of the new chunk base is its own). */
AFM_CLONES static void harm_slow_lanes(afm_harm *h, double x, double f, const harm_slow_step *s,
                                       const double *pex) {
    const int st = 2 * h->nl;
    const double *tm = s->tm;
    const bool exact = s->exact, active = s->active, cross = s->cross, start = s->start;
    const afm_v4 e = AFM_V4_SET1(s->e_rad), zero = AFM_V4_SET1(0.0);
    const afm_v4 kxp = AFM_V4_SET1((s->wb[0] - 0.5) * h->x_prev), kxc = AFM_V4_SET1(s->wb[1] * x);
    const afm_v4 kfp = AFM_V4_SET1((s->wb[0] - 0.5) * h->f_prev), kfc = AFM_V4_SET1(s->wb[1] * f);
    const afm_v4 nxp = AFM_V4_SET1(s->wa[0] * h->x_prev), nfp = AFM_V4_SET1(s->wa[0] * h->f_prev);
    const afm_v4 wxv = AFM_V4_SET1(s->wx), wfv = AFM_V4_SET1(s->wf);
    double *const out_raw = (h->out_to ? h->out_to : &h->out)->raw;
    for (int g = 0; g < st; g += 8) {
        const afm_v4 br = AFM_V4_LD(h->b + g), bi = AFM_V4_LD(h->b + g + 4);
        afm_v4 er, ei, pr, pi;
        AFM_V4_CMUL(br, bi, AFM_V4_LD(tm + g), AFM_V4_LD(tm + g + 4), er, ei);
        if (exact) {
            pr = AFM_V4_LD(pex + g);
            pi = AFM_V4_LD(pex + g + 4);
        } else {
            afm_v4 re, im;
            AFM_V4_CMUL(br, bi, AFM_V4_LD(tm + st + g), AFM_V4_LD(tm + st + g + 4), re, im);
            afm_v4 ke = AFM_V4_MUL(AFM_V4_LD(h->kd + g / 2), e);
            pr = AFM_V4_FMA(ke, im, re);
            pi = AFM_V4_FNMA(ke, re, im);
        }
        afm_v4 sxr = AFM_V4_LD(h->sx + g), sxi = AFM_V4_LD(h->sx + g + 4);
        afm_v4 sfr = AFM_V4_LD(h->sf + g), sfi = AFM_V4_LD(h->sf + g + 4);
        if (active) {
            afm_v4 cr = AFM_V4_LD(h->cx + g), ci = AFM_V4_LD(h->cx + g + 4);
            sxr = AFM_V4_FMA(br, cr, AFM_V4_FNMA(bi, ci, sxr));
            sxi = AFM_V4_FMA(br, ci, AFM_V4_FMA(bi, cr, sxi));
            cr = AFM_V4_LD(h->cf + g);
            ci = AFM_V4_LD(h->cf + g + 4);
            sfr = AFM_V4_FMA(br, cr, AFM_V4_FNMA(bi, ci, sfr));
            sfi = AFM_V4_FMA(br, ci, AFM_V4_FMA(bi, cr, sfi));
        }
        if (cross) {
            sxr = AFM_V4_FMA(kxc, pr, AFM_V4_FMA(kxp, er, sxr));
            sxi = AFM_V4_FMA(kxc, pi, AFM_V4_FMA(kxp, ei, sxi));
            sfr = AFM_V4_FMA(kfc, pr, AFM_V4_FMA(kfp, er, sfr));
            sfi = AFM_V4_FMA(kfc, pi, AFM_V4_FMA(kfp, ei, sfi));
            double *z = out_raw + 2 * g;
            AFM_V4_ST(z, sxr);
            AFM_V4_ST(z + 4, sxi);
            AFM_V4_ST(z + 8, sfr);
            AFM_V4_ST(z + 12, sfi);
        }
        if (start) {
            sxr = AFM_V4_MUL(nxp, er);
            sxi = AFM_V4_MUL(nxp, ei);
            sfr = AFM_V4_MUL(nfp, er);
            sfi = AFM_V4_MUL(nfp, ei);
        }
        AFM_V4_ST(h->sx + g, sxr);
        AFM_V4_ST(h->sx + g + 4, sxi);
        AFM_V4_ST(h->sf + g, sfr);
        AFM_V4_ST(h->sf + g + 4, sfi);
        AFM_V4_ST(h->cx + g, wxv);
        AFM_V4_ST(h->cx + g + 4, zero);
        AFM_V4_ST(h->cf + g, wfv);
        AFM_V4_ST(h->cf + g + 4, zero);
        AFM_V4_ST(h->b + g, pr);
        AFM_V4_ST(h->b + g + 4, pi);
    }
}

/* A sample off the fast path, by the exact clock: theta mod 2 pi; boundaries, fractional
 * ends, resynchronisation of the phasors. Returns -1 (rejected, nothing changed), 0, or 1 (a
 * period completed). */
AFM_CLONES static int harm_push_slow(afm_harm *h, double x, double f, double theta_rad) {
    if (!isfinite(x) || !isfinite(f)) return -1;
    harm_slow_step s;
    double pex[2 * AFM_HARM_LANES];
    if (harm_slow_clock(h, theta_rad, &s, pex)) return -1;
    harm_slow_weights(h, x, f, &s);
    harm_slow_lanes(h, x, f, &s, pex);
    if (s.cross) {
        afm_harm_result *o = h->out_to ? h->out_to : &h->out;
        o->period = h->periods;
        o->samples = s.samples;
        o->n_harmonics = h->nk;
        if (!h->deferred) afm_harm_polar(h, o);
        h->out_at = h->out_to; /* no pointer into h itself: h stays copyable */
        h->periods++;
    }
    if (h->trk.locked && s.rate_changed) build_table(h); /* after the pass: tm points into it */
    h->nbase = 0.0;
    h->x_prev = x;
    h->f_prev = f;
    return s.cross ? 1 : 0;
}

AFM_CLONES bool afm_harm_rebase(afm_harm *h, double theta_rad, double dphi) {
    afm_phase_track t = h->trk;
    if (!t.locked || !afm_track_rebase(&t, theta_rad, dphi)) return false;
    const int st = 2 * h->nl;
    const double *tm = h->tab + (size_t)(int)(h->trk.n - h->nbase) * st; /* the last sample */
    /* what the phasors stand for, less the theta supplied, carried into the new frame */
    const double resid = h->trk.th_prev - (h->imp_ref + h->trk.n * h->trk.dphi);
    fold_chunk(h, tm, st);
    h->n_sync += h->trk.n;
    h->nbase = 0.0;
    h->imp_ref = theta_rad - resid;
    h->trk = t;
    build_table(h);
    return true;
}

_Static_assert(AFM_HARM_LANES <= 20, "chunk_sig keeps at most 5 groups of lanes in registers");

/* c[0..2 nl) += sum_i v[i] T[m0 + i] over n samples, NG groups of 4 lanes (nl = 4 NG): the
 * sums in registers, each table entry read once (one pass per signal, so that every load
 * folds into its multiply-add); samples in order, so any split of a run into calls gives the
 * same sums. */
static inline ALWAYS_INLINE void chunk_sig(double *c, const double *tab, const double *v, int n,
                                           const int NG) {
    afm_v4 acc[10];
#pragma GCC unroll 10
    for (int g = 0; g < 2 * NG; g++)
        acc[g] = AFM_V4_LD(c + 4 * g);
    const double *tp = tab;
    int i = 0;
    for (; i + 8 <= n; i += 8, tp += 8 * 8 * NG) {
#pragma GCC unroll 8
        for (int u = 0; u < 8; u++) {
            afm_v4 vu = AFM_V4_SET1(v[i + u]);
#pragma GCC unroll 10
            for (int g = 0; g < 2 * NG; g++)
                acc[g] = AFM_V4_FMA(vu, AFM_V4_LD(tp + 8 * NG * u + 4 * g), acc[g]);
        }
    }
    for (; i + 4 <= n; i += 4, tp += 4 * 8 * NG) {
        afm_v4 v0 = AFM_V4_SET1(v[i]), v1 = AFM_V4_SET1(v[i + 1]);
        afm_v4 v2 = AFM_V4_SET1(v[i + 2]), v3 = AFM_V4_SET1(v[i + 3]);
#pragma GCC unroll 10
        for (int g = 0; g < 2 * NG; g++)
            acc[g] = AFM_V4_FMA(v0, AFM_V4_LD(tp + 4 * g), acc[g]);
#pragma GCC unroll 10
        for (int g = 0; g < 2 * NG; g++)
            acc[g] = AFM_V4_FMA(v1, AFM_V4_LD(tp + 8 * NG + 4 * g), acc[g]);
#pragma GCC unroll 10
        for (int g = 0; g < 2 * NG; g++)
            acc[g] = AFM_V4_FMA(v2, AFM_V4_LD(tp + 16 * NG + 4 * g), acc[g]);
#pragma GCC unroll 10
        for (int g = 0; g < 2 * NG; g++)
            acc[g] = AFM_V4_FMA(v3, AFM_V4_LD(tp + 24 * NG + 4 * g), acc[g]);
    }
    for (; i < n; i++, tp += 8 * NG) {
        afm_v4 v0 = AFM_V4_SET1(v[i]);
#pragma GCC unroll 10
        for (int g = 0; g < 2 * NG; g++)
            acc[g] = AFM_V4_FMA(v0, AFM_V4_LD(tp + 4 * g), acc[g]);
    }
#pragma GCC unroll 10
    for (int g = 0; g < 2 * NG; g++)
        AFM_V4_ST(c + 4 * g, acc[g]);
}

/* Samples x[0..n), f[0..n) at table entries m0, m0 + 1, ... (m0 + n - 1 <= AFM_HARM_TAB)
 * into the chunk sums. */
static inline ALWAYS_INLINE void chunk_xf(afm_harm *h, const double *tp, const double *x,
                                          const double *f, int n, const int NG) {
    chunk_sig(h->cx, tp, x, n, NG);
    chunk_sig(h->cf, tp, f, n, NG);
}

AFM_CLONES static void chunk_add(afm_harm *h, const double *x, const double *f, int n, int m0) {
    const double *tp = h->tab + (size_t)m0 * 2 * h->nl;
    switch (h->nl / 4) { /* the group count as a constant: chunk_sig keeps its sums in registers */
    case 1:
        chunk_xf(h, tp, x, f, n, 1);
        break;
    case 2:
        chunk_xf(h, tp, x, f, n, 2);
        break;
    case 3:
        chunk_xf(h, tp, x, f, n, 3);
        break;
    case 4:
        chunk_xf(h, tp, x, f, n, 4);
        break;
    default:
        chunk_xf(h, tp, x, f, n, 5);
        break;
    }
}

/* n fast-path samples (afm_track_run): weight 1 each into the chunk sums; a full chunk
 * (entry AFM_HARM_TAB) goes into the period sums and the base phasor moves to its end. */
AFM_CLONES static void fast_block(afm_harm *h, const double *x, const double *f, int n) {
    const int st = 2 * h->nl;
    int m = (int)(h->trk.n - h->nbase) + 1; /* table entry of x[0] */
    h->trk.n += (double)n;                  /* integer-valued: exact */
    h->nsteps += (double)n;
    while (n > 0) {
        int k = AFM_HARM_TAB + 1 - m < n ? AFM_HARM_TAB + 1 - m : n;
        chunk_add(h, x, f, k, m);
        x += k;
        f += k;
        n -= k;
        m += k;
        if (m > AFM_HARM_TAB) {
            fold_chunk(h, h->tab + (size_t)AFM_HARM_TAB * st, st);
            h->nbase += AFM_HARM_TAB;
            m = 1;
        }
    }
}

AFM_CLONES int afm_harm_push_n(afm_harm *h, const double *x, const double *f, const double *th,
                               int n, int *done, long long *rejects) {
    *done = 0;
    int i = 0;
    while (i < n) {
        int k = afm_track_run(&h->trk, th + i, x + i, f + i, n - i);
        if (k > 0) {
            fast_block(h, x + i, f + i, k);
            i += k;
            h->trk.th_prev = th[i - 1];
            h->x_prev = x[i - 1];
            h->f_prev = f[i - 1];
            if (i == n) break;
        }
        int rc = harm_push_slow(h, x[i], f[i], th[i]);
        i++;
        if (rc < 0) (*rejects)++;
        if (rc == 1) {
            *done = 1;
            break;
        }
    }
    return i;
}

int afm_harm_push(afm_harm *h, double x, double f, double theta_rad) {
    int done;
    long long rej = 0;
    afm_harm_push_n(h, &x, &f, &theta_rad, 1, &done, &rej);
    return rej ? -1 : done;
}

void afm_harm_phasor1(const afm_harm *h, double *re, double *im) {
    int m = (int)(h->trk.n - h->nbase), j = h->lane1;
    const double *t = h->tab + (size_t)m * 2 * h->nl;
    double br = h->b[RE(j)], bi = h->b[IM(j)], tr = t[RE(j)], ti = t[IM(j)];
    *re = fma(br, tr, -(bi * ti));
    *im = fma(br, ti, bi * tr);
}

int afm_harm_default_list(const afm_modal *m, double fe_hz, int *ks) {
    if (!(fe_hz > 0) || !ks) return 0;
    int cand[5] = {1, 2, 3, 0, 0}, nc = 3;
    for (int i = 1; m && i <= 2 && i < m->n; i++) {
        double r = m->omega_rad_s[i] / (AFM_EST_TWO_PI * fe_hz);
        if (r >= 0.5 && r < (double)AFM_HARM_MAX_K) cand[nc++] = (int)floor(r + 0.5);
    }
    /* insertion sort, then drop repeats */
    for (int i = 1; i < nc; i++)
        for (int j = i; j > 0 && cand[j - 1] > cand[j]; j--) {
            int t = cand[j];
            cand[j] = cand[j - 1];
            cand[j - 1] = t;
        }
    int n = 0;
    for (int i = 0; i < nc; i++)
        if (n == 0 || cand[i] != ks[n - 1]) ks[n++] = cand[i];
    return n;
}
