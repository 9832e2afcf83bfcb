/* SPDX-License-Identifier: MIT */
/* afm_lockin.c -- lock-in at tone 0 with cascaded first-order filters (contract in
 * afm_lockin.h). */
#include "estimators/afm_lockin.h"

#include "config/afm_clones.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#if defined(__GNUC__)
#define ALWAYS_INLINE __attribute__((always_inline))
#else
#define ALWAYS_INLINE
#endif

int afm_lockin_init(afm_lockin *l, const afm_cfg_lockin *cfg, double dt_s, char *err,
                    size_t errlen) {
    if (!l || !cfg || !(cfg->time_constant_s > 0) || !isfinite(cfg->time_constant_s) ||
        cfg->order < 1 || cfg->order > AFM_LOCKIN_MAX_ORDER || !(dt_s > 0) || !isfinite(dt_s)) {
        if (err && errlen)
            snprintf(err, errlen,
                     "lock-in: need time constant > 0 (got %g s), order 1..%d (got %d), sample "
                     "interval > 0 (got %g s)",
                     cfg ? cfg->time_constant_s : NAN, AFM_LOCKIN_MAX_ORDER, cfg ? cfg->order : 0,
                     dt_s);
        return -1;
    }
    memset(l, 0, sizeof *l);
    l->order = cfg->order;
    l->tau_s = cfg->time_constant_s;
    l->dt_s = dt_s;
    l->alpha = -expm1(-dt_s / cfg->time_constant_s);
    /* first column of A^L: the stages started at z = e_0, run with no input */
    double y[AFM_LOCKIN_MAX_ORDER] = {1.0};
    for (int L = 0; L <= AFM_LOCKIN_TAB; L++) {
        for (int i = 0; i < AFM_LOCKIN_MAX_ORDER; i++)
            l->ap[L][i] = i < l->order ? y[i] : 0.0;
        double in = 0.0;
        for (int i = 0; i < l->order; i++) {
            y[i] = fma(l->alpha, in - y[i], y[i]);
            in = y[i];
        }
    }
    for (int L = 0; L <= AFM_LOCKIN_TAB; L++) /* a(L) reversed onto the stages, per channel */
        for (int i = 0; i < l->order; i++)
            l->apl[L][2 * i] = l->apl[L][2 * i + 1] = l->ap[L][l->order - 1 - i];
    l->pr[0][0] = 1.0; /* e^{i 0 dphi}: the rest is built when the tracker locks */
    /* |A^m| |A^-m| ~ ((1 + alpha) / (1 - alpha))^m <= 2 */
    double lim = log(2.0) / (2.0 * l->alpha);
    l->m_max = lim >= AFM_LOCKIN_TAB ? AFM_LOCKIN_TAB : lim >= 4.0 ? (int)lim : 0;
    /* g_j = A^{-(j+1)} b (b: the stages' response to a unit input; A^{-1} g = (g_i - alpha
     * g_{i-1}) / (1 - alpha) stage by stage, from the last one down): independent of dphi */
    double gg[AFM_LOCKIN_MAX_ORDER] = {0.0}, gin = 1.0, a = l->alpha;
    for (int i = 0; i < l->order; i++) {
        gg[i] = fma(a, gin - gg[i], gg[i]);
        gin = gg[i];
    }
    for (int j = 0; j < l->m_max; j++) {
        for (int i = l->order - 1; i >= 0; i--)
            gg[i] = (gg[i] - (i > 0 ? a * gg[i - 1] : 0.0)) / (1.0 - a);
        for (int i = 0; i < AFM_LOCKIN_MAX_ORDER; i++)
            l->g[j][i] = i < l->order ? gg[i] : 0.0;
    }
    afm_lockin_reset(l);
    return 0;
}

void afm_lockin_reset(afm_lockin *l) {
    memset(l->xy, 0, sizeof l->xy);
    memset(l->acc, 0, sizeof l->acc);
    l->n = 0;
    l->m = 0;
    afm_track_init(&l->trk, false);
    l->c = l->rc = 1.0;
    l->s = l->rs = 0.0;
}

/* The block tables for the tracker's (new) dphi, (rc, rs) = e^{i dphi} already set, built
 * as the samples need them (extend_tables): a rate change costs O(1) here, and each entry
 * one complex product and 2 order products when first used (under FM, an NCO step every 64
 * samples uses 64 of the AFM_LOCKIN_TAB). */
static void build_tables(afm_lockin *l) {
    l->pr[0][0] = 1.0;
    l->pr[0][1] = 0.0;
    l->built = 0;
}

/* Entries up to L = upto (<= m_max) of the block tables: e^{i L dphi} by rotation (no sin
 * and cos per entry, within ~L ulp) and V_{L-1} = g_{L-1} e^{i L dphi} (the stages past
 * order stay 0). Multiversioned: one vfmadd per fma in the x86-64-v3 copy, the same bits. */
AFM_CLONES_NOINLINE static void extend_tables(afm_lockin *l, int upto) {
    const double rc = l->rc, rs = l->rs;
    for (int L = l->built + 1; L <= upto; L++) {
        double c = l->pr[L - 1][0], s = l->pr[L - 1][1];
        l->pr[L][0] = fma(c, rc, -(s * rs));
        l->pr[L][1] = fma(s, rc, c * rs);
        for (int i = 0; i < l->order; i++) {
            l->v[L - 1][2 * i] = l->g[L - 1][i] * l->pr[L][0];
            l->v[L - 1][2 * i + 1] = l->g[L - 1][i] * l->pr[L][1];
        }
    }
    if (upto > l->built) l->built = upto;
}

/* w = z_b + 2 e^{i theta_b} S over the stages (S = the four sums), NV vectors of 2 stages
 * as (X, Y) pairs: (X, Y) = (imaginary, real) part, = 2 c (im S, re S) + 2 s (re S, -im S). */
static inline ALWAYS_INLINE void stages_w(const afm_lockin *l, afm_v4 *w, const int NV) {
    const afm_v4 c2 = AFM_V4_SET1(2.0 * l->c);
    const afm_v4 s2 = (afm_v4){2.0 * l->s, -2.0 * l->s, 2.0 * l->s, -2.0 * l->s};
#pragma GCC unroll 4
    for (int v = 0; v < NV; v++) {
        afm_v4 sum =
            AFM_V4_ADD(AFM_V4_ADD(AFM_V4_LD(l->acc[0] + 4 * v), AFM_V4_LD(l->acc[1] + 4 * v)),
                       AFM_V4_ADD(AFM_V4_LD(l->acc[2] + 4 * v), AFM_V4_LD(l->acc[3] + 4 * v)));
        afm_v4 sw = __builtin_shufflevector(sum, sum, 1, 0, 3, 2); /* (im, re) pairs */
        w[v] = AFM_V4_ADD(AFM_V4_LD(&l->xy[2 * v][0]), AFM_V4_FMA(c2, sw, AFM_V4_MUL(s2, sum)));
    }
}

/* The last stage now: z = sum_d a_d(m) w_{last - d} (A^m is Toeplitz), as the lanes of w
 * times a(m) reversed onto the stages (apl), summed by channel. The fmas a loop over the lanes
 * in memory: gcc makes it vfmadds in the x86-64-v3 copy (AFM_V4_FMA here stayed scalar
 * vfmadds and shuffles; issue 12), the same bits. */
static inline ALWAYS_INLINE void current_nv(const afm_lockin *l, double *x, double *y,
                                            const int NV) {
    afm_v4 w[4];
    stages_w(l, w, NV);
    const double *ap = l->apl[l->m];
    double q[4] __attribute__((aligned(32))), wv[16] __attribute__((aligned(32)));
    for (int v = 0; v < NV; v++)
        AFM_V4_ST(wv + 4 * v, w[v]);
    for (int k = 0; k < 4; k++)
        q[k] = wv[k] * ap[k];
    for (int v = 1; v < NV; v++)
        for (int k = 0; k < 4; k++)
            q[k] = fma(wv[4 * v + k], ap[4 * v + k], q[k]);
    *x = q[0] + q[2];
    *y = q[1] + q[3];
}

/* Multiversioned: its afm_v4 fmas are vfmadds in the x86-64-v3 copy, not 12 calls of libm's
 * fma (the chain takes X, Y once a period: 235 -> ~50 instructions, issue 12). */
AFM_CLONES_NOINLINE static void current(const afm_lockin *l, double *x, double *y) {
    switch ((l->order + 1) / 2) {
    case 1:
        current_nv(l, x, y, 1);
        break;
    case 2:
        current_nv(l, x, y, 2);
        break;
    case 3:
        current_nv(l, x, y, 3);
        break;
    default:
        current_nv(l, x, y, 4);
        break;
    }
}

/* Move the base to the last sample: z_b = z (every stage: sum_d a_d w_{i - d}), theta_b +=
 * m dphi, sums 0. The fmas a loop over the lanes in memory, as in current_nv. */
static inline ALWAYS_INLINE void flush_nv(afm_lockin *l, const int NV) {
    afm_v4 w[4];
    stages_w(l, w, NV);
    double zp[32]; /* 2 NV - 1 zero stages, then w */
#pragma GCC unroll 4
    for (int v = 0; v < NV; v++)
        AFM_V4_ST(zp + 4 * v, AFM_V4_SET1(0.0));
#pragma GCC unroll 4
    for (int v = 0; v < NV; v++)
        AFM_V4_ST(zp + 4 * NV - 2 + 4 * v, w[v]);
    const double *a = l->ap[l->m];
#pragma GCC unroll 4
    for (int v = 0; v < NV; v++) {
        const double *zv = zp + 4 * NV - 2 + 4 * v; /* w[v] */
        double z[4] __attribute__((aligned(32)));
        for (int k = 0; k < 4; k++)
            z[k] = a[0] * zv[k];
#pragma GCC unroll 8
        for (int d = 1; d < 2 * NV; d++)
            for (int k = 0; k < 4; k++)
                z[k] = fma(a[d], zv[k - 2 * d], z[k]);
        AFM_V4_ST(&l->xy[2 * v][0], AFM_V4_LD(z));
    }
    if (l->order & 1) l->xy[l->order][0] = l->xy[l->order][1] = 0.0; /* the pad stage */
    double pc = l->pr[l->m][0], ps = l->pr[l->m][1];
    double c = fma(l->c, pc, -(l->s * ps));
    l->s = fma(l->s, pc, l->c * ps);
    l->c = c;
    for (int q = 0; q < 4; q++)
#pragma GCC unroll 4
        for (int v = 0; v < NV; v++)
            AFM_V4_ST(l->acc[q] + 4 * v, AFM_V4_SET1(0.0));
    l->m = 0;
}

static void flush(afm_lockin *l) {
    switch ((l->order + 1) / 2) {
    case 1:
        flush_nv(l, 1);
        break;
    case 2:
        flush_nv(l, 2);
        break;
    case 3:
        flush_nv(l, 3);
        break;
    default:
        flush_nv(l, 4);
        break;
    }
}

void afm_lockin_retune(afm_lockin *l) {
    if (l->m > 0) flush(l); /* the base onto the last sample, on the old rate's tables */
    afm_track_init(&l->trk, false);
}

bool afm_lockin_rebase(afm_lockin *l, double theta_rad, double dphi) {
    afm_phase_track t = l->trk;
    if (!t.locked || !afm_track_rebase(&t, theta_rad, dphi)) return false;
    if (l->m > 0) flush(l); /* the base onto the last sample, on the old rate's tables */
    l->trk = t;
    l->rc = cos(dphi);
    l->rs = sin(dphi);
    build_tables(l);
    return true;
}

/* One sample by the recursion (after moving the base to the previous sample): theta on
 * the tracker's prediction rotates the phasor by e^{i dphi}, else sin and cos come from
 * theta itself and the tracker resynchronises. -1 (nothing changed) if rejected. */
static int push_one(afm_lockin *l, double u_m, double theta_rad) {
    if (!isfinite(u_m)) return -1;
    afm_phase_track t = l->trk;
    bool fast = afm_track_fast(&t, theta_rad);
    double p;
    if (!fast && afm_track_check(&l->trk, theta_rad, &p) != AFM_CLOCK_NONE) return -1;
    if (l->m > 0) flush(l);
    if (fast) {
        l->trk = t;
        double c = fma(l->c, l->rc, -l->s * l->rs);
        l->s = fma(l->s, l->rc, l->c * l->rs);
        l->c = c;
    } else {
        double frac;
        bool rate_changed;
        afm_track_advance(&l->trk, theta_rad, p, &frac, &rate_changed);
        l->c = cos(theta_rad);
        l->s = sin(theta_rad);
        if (l->trk.locked && rate_changed) {
            l->rc = cos(l->trk.dphi);
            l->rs = sin(l->trk.dphi);
            build_tables(l);
        }
    }
    /* y += alpha (in - y) per stage, both channels side by side */
    double in[2] = {2.0 * u_m * l->s, 2.0 * u_m * l->c}, a = l->alpha;
    for (int i = 0; i < l->order; i++)
        for (int k = 0; k < 2; k++) {
            l->xy[i][k] = fma(a, in[k] - l->xy[i][k], l->xy[i][k]);
            in[k] = l->xy[i][k];
        }
    l->n++;
    return 0;
}

/* Samples u[0..k) on the prediction, the m-th to the (m + k - 1)-th since the base
 * (m + k <= m_max): acc[j mod 4] += u V_j, NV = (order + 1) / 2 vectors of 2 stages. The
 * four sums are held in registers rotated by m mod 4, so that u[i] goes to r[i mod 4]. */
static inline ALWAYS_INLINE void block_add(afm_lockin *l, const double *u, int k, const int NV) {
    const int p = l->m & 3, st = 2 * AFM_LOCKIN_MAX_ORDER;
    double *s0 = l->acc[p], *s1 = l->acc[(p + 1) & 3], *s2 = l->acc[(p + 2) & 3],
           *s3 = l->acc[(p + 3) & 3];
    afm_v4 r0[4], r1[4], r2[4], r3[4];
#pragma GCC unroll 4
    for (int v = 0; v < NV; v++) {
        r0[v] = AFM_V4_LD(s0 + 4 * v);
        r1[v] = AFM_V4_LD(s1 + 4 * v);
        r2[v] = AFM_V4_LD(s2 + 4 * v);
        r3[v] = AFM_V4_LD(s3 + 4 * v);
    }
    const double *w = l->v[l->m];
    int i = 0;
    for (; i + 4 <= k; i += 4, w += 4 * st) {
        afm_v4 u0 = AFM_V4_SET1(u[i]), u1 = AFM_V4_SET1(u[i + 1]);
        afm_v4 u2 = AFM_V4_SET1(u[i + 2]), u3 = AFM_V4_SET1(u[i + 3]);
#pragma GCC unroll 4
        for (int v = 0; v < NV; v++) {
            r0[v] = AFM_V4_FMA(u0, AFM_V4_LD(w + 4 * v), r0[v]);
            r1[v] = AFM_V4_FMA(u1, AFM_V4_LD(w + st + 4 * v), r1[v]);
            r2[v] = AFM_V4_FMA(u2, AFM_V4_LD(w + 2 * st + 4 * v), r2[v]);
            r3[v] = AFM_V4_FMA(u3, AFM_V4_LD(w + 3 * st + 4 * v), r3[v]);
        }
    }
    if (i < k) { /* 1..3 more */
        afm_v4 u0 = AFM_V4_SET1(u[i]);
#pragma GCC unroll 4
        for (int v = 0; v < NV; v++)
            r0[v] = AFM_V4_FMA(u0, AFM_V4_LD(w + 4 * v), r0[v]);
        if (i + 1 < k) {
            afm_v4 u1 = AFM_V4_SET1(u[i + 1]);
#pragma GCC unroll 4
            for (int v = 0; v < NV; v++)
                r1[v] = AFM_V4_FMA(u1, AFM_V4_LD(w + st + 4 * v), r1[v]);
        }
        if (i + 2 < k) {
            afm_v4 u2 = AFM_V4_SET1(u[i + 2]);
#pragma GCC unroll 4
            for (int v = 0; v < NV; v++)
                r2[v] = AFM_V4_FMA(u2, AFM_V4_LD(w + 2 * st + 4 * v), r2[v]);
        }
    }
#pragma GCC unroll 4
    for (int v = 0; v < NV; v++) {
        AFM_V4_ST(s0 + 4 * v, r0[v]);
        AFM_V4_ST(s1 + 4 * v, r1[v]);
        AFM_V4_ST(s2 + 4 * v, r2[v]);
        AFM_V4_ST(s3 + 4 * v, r3[v]);
    }
    l->m += k;
}

/* The marks at sample count i (NV vectors of 2 stages): X and Y read as afm_lockin_xy would,
 * the rejects since the last one. Returns the next mark's end (n after the last). */
static inline ALWAYS_INLINE int marks_at(const afm_lockin *l, afm_lockin_mark *mk, int nm, int *j,
                                         int i, int n, int *rej, const int NV) {
    for (; *j < nm && mk[*j].end <= i; (*j)++) {
        if (mk[*j].x_m) current_nv(l, mk[*j].x_m, mk[*j].y_m, NV);
        mk[*j].rejects = *rej;
        *rej = 0;
    }
    return *j < nm && mk[*j].end < n ? mk[*j].end : n;
}

/* afm_lockin_push_marks for NV = (order + 1) / 2 (no marks: afm_lockin_push_n). The tracker's
 * runs go over all that is left, the blocks stop at the marks: the fast path's test of a
 * sample does not depend on where the runs start, so the state is the same as with a call
 * per mark. */
static inline ALWAYS_INLINE int push_n(afm_lockin *l, const double *u, const double *th, int n,
                                       afm_lockin_mark *mk, int nm, const int NV) {
    int rej = 0, total = 0, i = 0, j = 0;
    int stop = marks_at(l, mk, nm, &j, 0, n, &rej, NV);
    while (i < n) {
        int k = afm_track_run(&l->trk, th + i, u + i, NULL, n - i);
        l->trk.n += (double)k; /* integer-valued: exact */
        l->n += k;
        for (int e = i + k; i < e;) { /* in blocks of at most m_max, up to the next mark */
            int b = l->m_max - l->m < e - i ? l->m_max - l->m : e - i;
            if (stop - i < b) b = stop - i;
            if (l->m + b > l->built) extend_tables(l, l->m + b);
            block_add(l, u + i, b, NV);
            i += b;
            l->trk.th_prev = th[i - 1];
            if (l->m == l->m_max) flush_nv(l, NV);
            if (i == stop) stop = marks_at(l, mk, nm, &j, i, n, &rej, NV);
        }
        if (i == n) break;
        if (push_one(l, u[i], th[i])) { /* off the prediction, or rejected */
            rej++;
            total++;
        }
        i++;
        if (i == stop) stop = marks_at(l, mk, nm, &j, i, n, &rej, NV);
    }
    marks_at(l, mk, nm, &j, n, n + 1, &rej, NV); /* those at n */
    return total;
}

/* The per-sample recursion (m_max 0), with the marks. */
static int push_each(afm_lockin *l, const double *u, const double *th, int n, afm_lockin_mark *mk,
                     int nm) {
    int rej = 0, total = 0, j = 0;
    for (int i = 0; i <= n; i++) {
        for (; j < nm && mk[j].end <= i; j++) {
            if (mk[j].x_m) afm_lockin_xy(l, mk[j].x_m, mk[j].y_m);
            mk[j].rejects = rej;
            rej = 0;
        }
        if (i < n && push_one(l, u[i], th[i])) {
            rej++;
            total++;
        }
    }
    return total;
}

AFM_CLONES int afm_lockin_push_marks(afm_lockin *l, const double *u, const double *th, int n,
                                     afm_lockin_mark *marks, int n_marks) {
    if (l->m_max == 0) return push_each(l, u, th, n, marks, n_marks);
    switch ((l->order + 1) / 2) {
    case 1:
        return push_n(l, u, th, n, marks, n_marks, 1);
    case 2:
        return push_n(l, u, th, n, marks, n_marks, 2);
    case 3:
        return push_n(l, u, th, n, marks, n_marks, 3);
    default:
        return push_n(l, u, th, n, marks, n_marks, 4);
    }
}

int afm_lockin_push_n(afm_lockin *l, const double *u, const double *th, int n) {
    return afm_lockin_push_marks(l, u, th, n, NULL, 0);
}

int afm_lockin_push(afm_lockin *l, double u_m, double theta_rad) {
    return afm_lockin_push_n(l, &u_m, &theta_rad, 1) ? -1 : 0;
}

double afm_lockin_x(const afm_lockin *l) {
    double x, y;
    current(l, &x, &y);
    return x;
}

double afm_lockin_y(const afm_lockin *l) {
    double x, y;
    current(l, &x, &y);
    return y;
}

double afm_lockin_amplitude(const afm_lockin *l) {
    double x, y;
    current(l, &x, &y);
    return hypot(x, y);
}

double afm_lockin_phase_deg(const afm_lockin *l) {
    double x, y;
    current(l, &x, &y);
    return atan2(-y, x) * 57.295779513082320876798154814105;
}

void afm_lockin_polar_of(double x_m, double y_m, double *amplitude_m, double *phase_deg) {
    *amplitude_m = hypot(x_m, y_m);
    *phase_deg = atan2(-y_m, x_m) * 57.295779513082320876798154814105;
}

void afm_lockin_polar(const afm_lockin *l, double *amplitude_m, double *phase_deg) {
    double x, y;
    current(l, &x, &y);
    afm_lockin_polar_of(x, y, amplitude_m, phase_deg);
}

void afm_lockin_xy(const afm_lockin *l, double *x_m, double *y_m) {
    current(l, x_m, y_m);
}

void afm_lockin_phasor(const afm_lockin *l, double *c, double *s) {
    double pc = l->pr[l->m][0], ps = l->pr[l->m][1];
    *c = fma(l->c, pc, -(l->s * ps));
    *s = fma(l->s, pc, l->c * ps);
}
