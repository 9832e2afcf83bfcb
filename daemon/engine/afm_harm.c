/* SPDX-License-Identifier: MIT */
/* afm_harm.c -- streaming per-period harmonics (contract in afm_harm.h). */
#include "afm_harm.h"

#include <stdio.h>
#include <string.h>

/* Empty state for the harmonic list already in h (nk, nl, ks). */
static void clear_state(afm_harm *h) {
    afm_track_init(&h->trk, true);
    h->active = false;
    h->x_prev = h->f_prev = 0.0;
    for (int j = 0; j < AFM_HARM_LANES; j++) {
        h->er[j] = h->rr[j] = 1.0;
        h->ei[j] = h->ri[j] = 0.0;
        h->xr[j] = h->xi[j] = h->fr[j] = h->fi[j] = 0.0;
    }
    h->wsum = 0.0;
    h->imp_ref = 0.0;
    h->n_sync = HUGE_VAL; /* the first sample is computed exactly */
    h->periods = 0;
    memset(&h->out, 0, sizeof h->out);
    h->out.n_harmonics = h->nk;
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
    h->nl = (nk + 1 + 3) / 4 * 4;
    h->ks[0] = 1;
    memcpy(h->ks + 1, ks, (size_t)nk * sizeof *ks);
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

#if defined(__AVX__) && defined(__FMA__)
#include <immintrin.h>
/* atan2 of 4 lanes, within 2 ulp of libm's (checked on 1.6e7 random pairs over 12 decades
 * of |y| / |x|): the octant reduction to t = min(|x|, |y|) / max(|x|, |y|) in [0, 1], t > 0.66
 * mapped to (t - 1) / (t + 1) around pi / 4, then Cephes's atan rational P(t^2)/Q(t^2)
 * (S. Moshier, Cephes Math Library atan.c: P degree 4, Q degree 5, about 1e-16 relative),
 * then pi / 2 - r, pi - r (with the low parts of pi / 2, pi) and the sign of y. Lanes with
 * max(|x|, |y|) = 0 or not finite are not handled here (t is NaN): the caller checks. */
static inline __m256d atan2_v4(__m256d y, __m256d x) {
    const __m256d sgn = _mm256_set1_pd(-0.0);
    __m256d ax = _mm256_andnot_pd(sgn, x), ay = _mm256_andnot_pd(sgn, y);
    __m256d mx = _mm256_max_pd(ax, ay), mn = _mm256_min_pd(ax, ay);
    __m256d t = _mm256_div_pd(mn, mx);
    __m256d big = _mm256_cmp_pd(t, _mm256_set1_pd(0.66), _CMP_GT_OQ);
    __m256d one = _mm256_set1_pd(1.0);
    __m256d tr =
        _mm256_blendv_pd(t, _mm256_div_pd(_mm256_sub_pd(t, one), _mm256_add_pd(t, one)), big);
    __m256d z = _mm256_mul_pd(tr, tr);
    __m256d p = _mm256_set1_pd(-8.750608600031904122785E-1);
    p = _mm256_fmadd_pd(p, z, _mm256_set1_pd(-1.615753718733365076637E1));
    p = _mm256_fmadd_pd(p, z, _mm256_set1_pd(-7.500855792314704667340E1));
    p = _mm256_fmadd_pd(p, z, _mm256_set1_pd(-1.228866684490136173410E2));
    p = _mm256_fmadd_pd(p, z, _mm256_set1_pd(-6.485021904942025371773E1));
    __m256d q = _mm256_add_pd(z, _mm256_set1_pd(2.485846490142306297962E1));
    q = _mm256_fmadd_pd(q, z, _mm256_set1_pd(1.650270098316988542046E2));
    q = _mm256_fmadd_pd(q, z, _mm256_set1_pd(4.328810604912902668951E2));
    q = _mm256_fmadd_pd(q, z, _mm256_set1_pd(4.853903996359136964868E2));
    q = _mm256_fmadd_pd(q, z, _mm256_set1_pd(1.945506571482613964425E2));
    __m256d r = _mm256_fmadd_pd(tr, _mm256_div_pd(_mm256_mul_pd(z, p), q), tr);
    /* + pi/4 (with its low part) in the upper range */
    r = _mm256_add_pd(r, _mm256_and_pd(big, _mm256_set1_pd(3.061616997868382943065E-17)));
    r = _mm256_add_pd(r, _mm256_and_pd(big, _mm256_set1_pd(7.85398163397448278999E-1)));
    /* |y| > |x|: pi/2 - r */
    __m256d steep = _mm256_cmp_pd(ay, ax, _CMP_GT_OQ);
    __m256d r2 = _mm256_add_pd(_mm256_sub_pd(_mm256_set1_pd(1.57079632679489655800), r),
                               _mm256_set1_pd(6.123233995736765886130E-17));
    r = _mm256_blendv_pd(r, r2, steep);
    /* x < 0: pi - r */
    __m256d r3 = _mm256_add_pd(_mm256_sub_pd(_mm256_set1_pd(3.14159265358979311600), r),
                               _mm256_set1_pd(1.2246467991473531772E-16));
    r = _mm256_blendv_pd(r, r3, x);
    return _mm256_or_pd(r, _mm256_and_pd(sgn, y));
}

#endif

/* Phases atan2(im[j], re[j]) of lanes 0..n-1 (n a multiple of 4) and magnitudes
 * |re[j] + i im[j]| (afm_est_hypot's value). */
static void polar(const double *re, const double *im, int n, double *ph, double *mag) {
    for (int j = 0; j < n; j += 4) {
#if defined(__AVX__) && defined(__FMA__)
        __m256d x = _mm256_loadu_pd(re + j), y = _mm256_loadu_pd(im + j);
        __m256d q = _mm256_add_pd(_mm256_mul_pd(x, x), _mm256_mul_pd(y, y)); /* as afm_est_hypot */
        __m256d sgn = _mm256_set1_pd(-0.0);
        __m256d mx = _mm256_max_pd(_mm256_andnot_pd(sgn, x), _mm256_andnot_pd(sgn, y));
        __m256d ok =
            _mm256_and_pd(_mm256_and_pd(_mm256_cmp_pd(mx, _mm256_setzero_pd(), _CMP_GT_OQ),
                                        _mm256_cmp_pd(mx, _mm256_set1_pd(HUGE_VAL), _CMP_LT_OQ)),
                          _mm256_and_pd(_mm256_cmp_pd(q, _mm256_set1_pd(1e-290), _CMP_GT_OQ),
                                        _mm256_cmp_pd(q, _mm256_set1_pd(1e290), _CMP_LT_OQ)));
        if (_mm256_movemask_pd(ok) == 15) {
            _mm256_storeu_pd(ph + j, atan2_v4(y, x));
            _mm256_storeu_pd(mag + j, _mm256_sqrt_pd(q));
            continue;
        }
#endif
        for (int l = j; l < j + 4; l++) {
            ph[l] = atan2(im[l], re[l]);
            mag[l] = afm_est_hypot(re[l], im[l]);
        }
    }
}

static void finish_period(afm_harm *h) {
    double scale = 2.0 / h->wsum;
    double px[AFM_HARM_LANES], ax[AFM_HARM_LANES], pf[AFM_HARM_LANES], af[AFM_HARM_LANES];
    polar(h->xr, h->xi, h->nl, px, ax);
    polar(h->fr, h->fi, h->nl, pf, af);
    double phi1 = px[0];
    h->out.period = h->periods;
    h->out.samples = h->wsum;
    h->out.n_harmonics = h->nk;
    for (int j = 1; j <= h->nk; j++) {
        afm_orbit_harmonic *o = &h->out.h[j - 1];
        o->k = h->ks[j];
        o->x_amp_m = scale * ax[j];
        o->x_phase_deg = px[j] * AFM_EST_RAD2DEG;
        o->f_amp_n = scale * af[j];
        o->f_phase_deg = pf[j] * AFM_EST_RAD2DEG;
        o->phase_diff_deg = afm_phase_diff_deg(o->k, phi1, px[j]);
    }
    h->periods++;
}

/* The sample by the exact clock: theta mod 2 pi, sincos, O(log k) products per harmonic;
 * boundaries, fractional ends, resynchronisation of the phasors. */
AFM_EST_COLD static int push_slow(afm_harm *h, double x, double f, double theta_rad) {
    double phi; /* phase since the last boundary; at a boundary e^{-ik phi} is the same for
                 * both periods since k is an integer */
    if (afm_track_check(&h->trk, theta_rad, &phi) != AFM_CLOCK_NONE) return -1;
    bool had_prev = h->trk.started, rate_changed;
    double frac = 1.0;
    /* On the tracker's prediction (only the boundary ended the fast path): the phasors
     * rotate one more step and then stand for imp, which must be within tol of theta. */
    const afm_phase_track *t = &h->trk;
    double n1 = t->n + 1.0, imp = h->imp_ref + n1 * t->dphi, tol = t->tol;
    bool rotate = t->locked && h->n_sync + n1 <= AFM_TRACK_WINDOW_CLOCK &&
                  fabs((theta_rad - t->th_ref) - n1 * t->dphi) <= tol &&
                  fabs(theta_rad - imp) <= tol;
    int ev = afm_track_advance(&h->trk, theta_rad, phi, &frac, &rate_changed);
    int n = h->nl, done = 0;
    double er[AFM_HARM_LANES], ei[AFM_HARM_LANES];
    if (rotate && h->trk.locked) {
        /* one step as the fast path, then e^{-ik e} ~ 1 - i k e for the residual
         * e = theta - imp (|k e| < 1e-6: the dropped terms are below 1e-12 of it) */
        double e = theta_rad - imp;
        for (int j = 0; j < n; j++) {
            double a = fma(h->er[j], h->rr[j], -h->ei[j] * h->ri[j]);
            double b = fma(h->er[j], h->ri[j], h->ei[j] * h->rr[j]);
            double ke = (double)h->ks[j] * e;
            er[j] = fma(ke, b, a);
            ei[j] = fma(-ke, a, b);
        }
        h->n_sync += n1;
        h->imp_ref = theta_rad;
    } else {
        double c1 = cos(phi), s1 = -sin(phi);
        for (int j = 0; j < n; j++)
            rot_pow(c1, s1, h->ks[j], &er[j], &ei[j]);
        h->n_sync = 0.0;
        h->imp_ref = theta_rad;
    }
    if (h->trk.locked && rate_changed) {
        double cd = cos(h->trk.dphi), sd = -sin(h->trk.dphi);
        for (int j = 0; j < n; j++)
            rot_pow(cd, sd, h->ks[j], &h->rr[j], &h->ri[j]);
    }

    if (had_prev && h->active) {
        if (ev == AFM_CLOCK_CROSS) {
            /* the previous sample already has weight 1 (0.5 from each side); the step's
             * part before the boundary is wb[0] g_prev + wb[1] g_cur */
            double wb[2], wa[2];
            afm_split_weights(frac, wb, wa);
            double w0 = wb[0] - 0.5;
            for (int j = 0; j < n; j++) {
                h->xr[j] += w0 * h->x_prev * h->er[j] + wb[1] * x * er[j];
                h->xi[j] += w0 * h->x_prev * h->ei[j] + wb[1] * x * ei[j];
                h->fr[j] += w0 * h->f_prev * h->er[j] + wb[1] * f * er[j];
                h->fi[j] += w0 * h->f_prev * h->ei[j] + wb[1] * f * ei[j];
            }
            h->wsum += frac;
            finish_period(h);
            done = 1;
        } else {
            for (int j = 0; j < n; j++) {
                h->xr[j] += x * er[j];
                h->xi[j] += x * ei[j];
                h->fr[j] += f * er[j];
                h->fi[j] += f * ei[j];
            }
            h->wsum += 1.0;
        }
    }
    if (ev == AFM_CLOCK_START || (ev == AFM_CLOCK_CROSS && had_prev)) {
        /* a new period starts: at this sample, or inside the step just taken; this sample
         * gets the after-boundary weight plus 0.5 from the next step */
        double wb[2], wa[2] = {0.0, 0.0};
        if (ev == AFM_CLOCK_CROSS) afm_split_weights(frac, wb, wa);
        double w1 = wa[1] + 0.5;
        for (int j = 0; j < n; j++) {
            h->xr[j] = wa[0] * h->x_prev * h->er[j] + w1 * x * er[j];
            h->xi[j] = wa[0] * h->x_prev * h->ei[j] + w1 * x * ei[j];
            h->fr[j] = wa[0] * h->f_prev * h->er[j] + w1 * f * er[j];
            h->fi[j] = wa[0] * h->f_prev * h->ei[j] + w1 * f * ei[j];
        }
        h->wsum = ev == AFM_CLOCK_CROSS ? 1.0 - frac : 0.0;
        h->active = true;
    }
    h->x_prev = x;
    h->f_prev = f;
    memcpy(h->er, er, (size_t)n * sizeof er[0]);
    memcpy(h->ei, ei, (size_t)n * sizeof ei[0]);
    return done;
}

int afm_harm_push(afm_harm *h, double x, double f, double theta_rad) {
    if (!isfinite(x) || !isfinite(f)) return -1;
    if (!afm_track_fast(&h->trk, theta_rad)) return push_slow(h, x, f, theta_rad);
    /* fast path: no boundary in the step; rotate every harmonic's phasor by one step and
     * add the sample with weight 1 (4 lanes at a time: the compiler vectorises these) */
    int n = h->nl;
    if (h->active) {
        for (int j = 0; j < n; j += 4)
            for (int l = j; l < j + 4; l++) {
                double a = fma(h->er[l], h->rr[l], -h->ei[l] * h->ri[l]);
                double b = fma(h->er[l], h->ri[l], h->ei[l] * h->rr[l]);
                h->er[l] = a;
                h->ei[l] = b;
                h->xr[l] = fma(x, a, h->xr[l]);
                h->xi[l] = fma(x, b, h->xi[l]);
                h->fr[l] = fma(f, a, h->fr[l]);
                h->fi[l] = fma(f, b, h->fi[l]);
            }
        h->wsum += 1.0;
    } else {
        for (int j = 0; j < n; j += 4)
            for (int l = j; l < j + 4; l++) {
                double a = fma(h->er[l], h->rr[l], -h->ei[l] * h->ri[l]);
                double b = fma(h->er[l], h->ri[l], h->ei[l] * h->rr[l]);
                h->er[l] = a;
                h->ei[l] = b;
            }
    }
    h->x_prev = x;
    h->f_prev = f;
    return 0;
}

/* Fast-path samples in a row from x, f, theta (at most n): finite data, theta on the
 * tracker's prediction (afm_track_fast's test). */
static int fast_run(const afm_harm *h, const double *x, const double *f, const double *th, int n) {
    const afm_phase_track *t = &h->trk;
    double nn = t->n;
    int L = 0;
    for (; L < n; L++) {
        nn += 1.0;
        if (!(nn <= t->n_end && fabs((th[L] - t->th_ref) - nn * t->dphi) <= t->tol) ||
            !isfinite(x[L]) || !isfinite(f[L]))
            break;
    }
    return L;
}

#if defined(__AVX__) && defined(__FMA__)
#include <immintrin.h>
/* L fast-path samples: per 4-lane group, phasors and sums in registers over the run (the
 * same operations as afm_harm_push's fast path, so the same roundings). */
static void fast_block(afm_harm *h, const double *x, const double *f, const double *th, int L) {
    (void)th;
    for (int j = 0; j < h->nl; j += 4) {
        __m256d er = _mm256_loadu_pd(h->er + j), ei = _mm256_loadu_pd(h->ei + j);
        __m256d rr = _mm256_loadu_pd(h->rr + j), ri = _mm256_loadu_pd(h->ri + j);
        if (h->active) {
            __m256d xr = _mm256_loadu_pd(h->xr + j), xi = _mm256_loadu_pd(h->xi + j);
            __m256d fr = _mm256_loadu_pd(h->fr + j), fi = _mm256_loadu_pd(h->fi + j);
            for (int i = 0; i < L; i++) {
                __m256d a = _mm256_fmadd_pd(er, rr, -(ei * ri));
                __m256d b = _mm256_fmadd_pd(er, ri, ei * rr);
                er = a;
                ei = b;
                __m256d xv = _mm256_set1_pd(x[i]), fv = _mm256_set1_pd(f[i]);
                xr = _mm256_fmadd_pd(xv, a, xr);
                xi = _mm256_fmadd_pd(xv, b, xi);
                fr = _mm256_fmadd_pd(fv, a, fr);
                fi = _mm256_fmadd_pd(fv, b, fi);
            }
            _mm256_storeu_pd(h->xr + j, xr);
            _mm256_storeu_pd(h->xi + j, xi);
            _mm256_storeu_pd(h->fr + j, fr);
            _mm256_storeu_pd(h->fi + j, fi);
        } else {
            for (int i = 0; i < L; i++) {
                __m256d a = _mm256_fmadd_pd(er, rr, -(ei * ri));
                __m256d b = _mm256_fmadd_pd(er, ri, ei * rr);
                er = a;
                ei = b;
            }
        }
        _mm256_storeu_pd(h->er + j, er);
        _mm256_storeu_pd(h->ei + j, ei);
    }
    if (h->active)
        for (int i = 0; i < L; i++)
            h->wsum += 1.0;
    h->trk.n += (double)L; /* integer-valued: exact */
}
#else
static void fast_block(afm_harm *h, const double *x, const double *f, const double *th, int L) {
    for (int i = 0; i < L; i++)
        afm_harm_push(h, x[i], f[i], th[i]); /* all take the fast path */
}
#endif

int afm_harm_push_n(afm_harm *h, const double *x, const double *f, const double *th, int n,
                    int *done, long long *rejects) {
    *done = 0;
    int i = 0;
    while (i < n) {
        int L = fast_run(h, x + i, f + i, th + i, n - i);
        if (L > 0) {
            fast_block(h, x + i, f + i, th + i, L);
            i += L;
            h->trk.th_prev = th[i - 1];
            h->x_prev = x[i - 1];
            h->f_prev = f[i - 1];
            continue;
        }
        int rc = afm_harm_push(h, x[i], f[i], th[i]);
        i++;
        if (rc < 0) (*rejects)++;
        if (rc == 1) {
            *done = 1;
            break;
        }
    }
    return i;
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
