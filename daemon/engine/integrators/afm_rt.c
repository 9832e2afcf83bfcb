/* SPDX-License-Identifier: MIT */
/* afm_rt.c -- the real-time fixed-step integrator backend (afm_rt_backend).
 *
 * Scheme (docs/numerics.md has the reasons and the measurements):
 *  - Every mode's linear part and the sinusoidal base drive are integrated exactly
 *    (afm_rt_coef.h): the state is the homogeneous part qh = q - sum_j Im(c_j e^{i theta_j})
 *    (c_j the steady-state response to tone j), which the drive does not enter; the phasors
 *    e^{i theta_j} are rotated by a precomputed unit complex per step and resynchronised
 *    from afm_drive every RT_RESYNC steps and on every change. A change reloads qh from the
 *    full q, so tone changes are phase-continuous and q never jumps.
 *  - Thermal noise (afm_sim_set_thermal): each piece adds the exact Gaussian increment of
 *    the Langevin force to (qh, qh') (afm_rt_coef_thermal), drawn before the force solve so
 *    that the implicit force sees it. A redone piece is drawn given the increment already
 *    drawn for its interval (Brownian bridge: rt_noise, rt_bridge_draw), so that redoing a
 *    sample does not depend on the noise it discards.
 *  - The tip force enters through one channel. It is taken as linear over each step
 *    (exponential trapezoidal rule) and solved implicitly: the end force F1 satisfies
 *    F1 = f(x* + gx F1, v* + gv F1). Out of contact that is one linearly implicit step (one
 *    force evaluation at x* + gx F0 and one chord correction with the slope of the step
 *    before); a convergence estimate that is checked off the critical path sends the rare
 *    step that needs more to a safeguarded chord/Newton iteration of at most RT_NEWTON_MAX
 *    evaluations, which in contact takes 2-4.
 *  - Latency: x*, v* of the next full step are affine in this step's F1 (x*_next = A + hx
 *    F1, with A from the modal update before F1 is known), so the chain from one force to
 *    the next is one multiply-add, the force and the chord update. The modal update runs
 *    beside it.
 *  - Out of contact: one step per output sample. When the gap is below a0 at the start or
 *    the end of the sample, or on the cubic Hermite path between, the sample is redone in
 *    m = cfg.rt_substeps_contact substeps, and a substep in which the contact starts or
 *    ends is split at the crossing, located on its cubic Hermite path and rounded to a
 *    grid of RT_GRID cells per substep (every step length used is precomputed). A bound on
 *    the Hermite path (it stays above min(x0, x1) - 4/27 dt (|v0| + |v1|)) skips the
 *    crossing search on samples well clear of the sample.
 *  - Forces: the formulas of afm_force_inline.h, inlined. Starr's squeeze film (a pow per
 *    evaluation) is replaced near the rest gap h0 = Z + kappa l cos(alpha) by a quartic
 *    interpolant of c(h) on h0 (1 +- AFM_RT_STARR_WINDOW), rebuilt whenever Z changes; outside
 *    it the exact formula is used (afm_rt_coef.h).
 *  - Output: afm_sim_run calls rt_run (the backend's batch hook), one loop over the block
 *    of samples writing x, v, F, theta and the base displacement from the step; the full
 *    q is rebuilt for struct afm_sim once per call (rt_publish).
 * Cost per sample is bounded: at most 1 + 3m implicit pieces (a trial full step, then per
 * substep a trial and two split pieces), each of at most RT_NEWTON_MAX force evaluations.
 * No allocation after init. */
#include "forces/afm_force_inline.h"
#include "forces/afm_rng.h"
#include "config/afm_clones.h"
#include "integrators/afm_rt_coef.h"
#include "integrators/afm_sim_impl.h"

/* A portable x86-64 build compiles this file twice (Makefile, AFM_RT_COPY): for the
 * baseline (afm_rt_backend_base) and for x86-64-v3 (afm_rt_backend_v3, the same code as an
 * x86-64-v3 build's, so the same bits), and afm_sim picks the copy the CPU runs. Inside a
 * copy nothing is cloned. */
#if defined(AFM_RT_COPY)
#undef AFM_CLONES
#undef AFM_CLONES_NOINLINE
#define AFM_CLONES
#define AFM_CLONES_NOINLINE __attribute__((noinline))
#if AFM_RT_COPY == 2
#define AFM_RT_BACKEND afm_rt_backend_v3
#else
#define AFM_RT_BACKEND afm_rt_backend_base
#endif
#else
#define AFM_RT_BACKEND afm_rt_backend
#endif

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__FMA__) && defined(__AVX__)
#include <immintrin.h>
#endif

#define RT_GRID 8                  /* table cells per contact substep: crossing resolution */
#define RT_DEFAULT_SUBSTEPS 4      /* substeps per sample in contact (measured, numerics.md) */
#define RT_ACC_DEFAULT_SUBSTEPS 16 /* the accurate scheme's (docs/numerics.md, issue 28) */
/* The accurate scheme redoes a sample in substeps when its path comes within this many
 * travels ((|v0| + |v1|) dt) of the contact line (docs/numerics.md: 0 leaves 0.013 deg and
 * 1.3e-4 of amplitude on probe-q300, 0.5 and more 0.001 deg and 2e-5) */
#define RT_ACC_NEAR_TRAVELS 1.0
#define RT_MAX_SUBSTEPS AFM_MAX_RT_SUBSTEPS
#define RT_RESYNC 4096 /* steps between phasor resynchronisations */
#define RT_NEWTON_MAX 12
#define RT_KB_J_K 1.380649e-23 /* Boltzmann constant (exact, SI 2019) */

/* The tip at the end of a piece and what a full step from there needs of it. The free step
 * carries it in registers from sample to sample (rt_run_t), so that the chain from one force
 * to the next does not go through a store and a load; rt_snap holds the same struct. */
typedef struct {
    double x_m, v_m_s, f_n; /* tip displacement (m), velocity (m/s), tip-sample force (N) */
    /* x*, v*: the tip at the end of a full step from here without the response to that
     * step's end force (m, m/s) */
    double x_free_m, v_free_m_s;
    /* 1 / max(1 - fx gx - fv gv, 1/4) (dimensionless) at the last force evaluation, for a
     * piece of rt_snap.slope_cells cells; in a free-standing rt_tip, for a full step */
    double inv_slope;
    /* x, v and the gap d = x cos(alpha) + Z at the full step's first guess, its end force
     * held at f_n: x_free_m + gx f_n, ... (m, m/s, m) */
    double x_guess_m, v_guess_m_s, gap_guess_m;
} rt_tip;

/* The state a step reads and writes; two of them so a trial step can be dropped. */
typedef struct {
    double q[AFM_MAX_MODES], v[AFM_MAX_MODES];       /* homogeneous part qh (m), qh' (m/s) */
    double z_re[AFM_MAX_TONES], z_im[AFM_MAX_TONES]; /* e^{i theta_j} */
    rt_tip tip;
    double dfdx_n_m, dfdv_n_s_m; /* df/dx (N/m), df/dv (N s/m) at the last force evaluation */
    int slope_cells;             /* the piece length tip.inv_slope is for, in cells (0: none) */
    double df_per_cell_n;        /* force change per cell over the piece that ended here (N) */
    double fdot_n_s;             /* dF/dt here (N/s): the accurate scheme's Hermite end slope */
} rt_snap;

/* The step tables of one scheme: contact substeps m, ncell = m RT_GRID cells, the
 * coefficients of a piece of k cells at prop[k - 1] (in block), and, once thermal noise was
 * set, its Cholesky factors and bridge gains (rt_state.lth, .bridge). */
typedef struct {
    int m, ncell;
    afm_rt_prop *prop;
    double *block, *lth, *bridge;
} rt_tables;

typedef struct {
    int n, np, m, ncell, ntones; /* np: n rounded up to a multiple of 4 */
    double tip[AFM_MAX_MODES];   /* tip_i, zero past n */
    double rot[AFM_MAX_MODES];   /* rot_i (tip rotation per unit q_i), zero past n */
    afm_rt_prop *prop;           /* prop[k - 1]: step of k cells, tau = k dt / ncell */
    double *block;
    rt_snap buf[2];
    int cur;
    double wd[AFM_MAX_TONES];
    double cq_re[AFM_MAX_TONES][AFM_MAX_MODES], cq_im[AFM_MAX_TONES][AFM_MAX_MODES];
    double th_re[AFM_MAX_TONES], th_im[AFM_MAX_TONES]; /* theta = rot . qh + Im(th z) */
    double amp_m[AFM_MAX_TONES]; /* base amplitude of each tone (m); zero past ntones */
    double xc;                   /* tip x at which the gap is a0 */
    double cos_alpha, z_m;       /* d = x cos(alpha) + Z (copies of s->f's and s's) */
    /* A full step's first guess per unit end force of the step before (rt_tip's x_guess_m,
     * v_guess_m_s, gap_guess_m): gx + hx (m/N), gv + hv (m/s/N), (gx + hx) cos(alpha) (m/N) */
    double guess_x_per_n, guess_v_per_n, guess_gap_per_n;
    bool kinked; /* the force has a kink at d = a0 (contact, capillary, electrostatic) */
    double ftol; /* Newton tolerance on F (N) */
    double inv_cells[RT_MAX_SUBSTEPS * RT_GRID + 1]; /* 1 / k */
    double clear_k; /* 4/27 dt: the Hermite path's largest dip per unit end speed */
    afm_rt_starr starr;
    long since_sync;
    bool noise;   /* thermal force on */
    double *lth;  /* thermal Cholesky factors: step of k cells at lth + 3 np (k - 1) */
    afm_rng *rng; /* its generator (allocated by the first afm_sim_set_thermal) */
    /* Brownian-bridge gains (afm_rt_coef_bridge), 4 np each: a substep's first kc cells
     * (kc = 1 .. RT_GRID - 1), then a substep of the rest of a sample of j substeps
     * (j = 2 .. m); see rt_bridge_gain */
    double *bridge;
    struct rt_noise *nz; /* the increments being split (mutable scratch) */
    /* The accurate scheme (cfg.rt_scheme; rt_run_acc): the force cubic Hermite in time.
     * m, ncell, prop, block, lth and bridge above are tab[acc]'s (rt_use). */
    bool acc;
    rt_tables tab[2]; /* [0] the fast scheme's, [1] the accurate one's */
    /* the tip acceleration: sum_i aq_i qh_i + av_i qh'_i + tip2 F + Im(ax_j z_j) with
     * aq = -tip w^2, av = -2 tip xi w (1/s^2, 1/s; zero past n), tip2 = sum tip^2 (1/kg),
     * ax_j = -wd_j^2 cx_j (m/s^2; zero past ntones) */
    double aq[AFM_MAX_MODES], av[AFM_MAX_MODES], tip2;
    double ax_re[AFM_MAX_TONES], ax_im[AFM_MAX_TONES];
} rt_state;

/* A redone piece takes the noise already drawn for its interval (issue 11): the increment
 * the next piece must take, the last piece's, and what of a sample's increment its
 * substeps have not taken yet (per mode, on (qh, qh')). */
typedef struct rt_noise {
    double gq[AFM_MAX_MODES], gv[AFM_MAX_MODES]; /* given to the next piece of given_cells */
    int given_cells;                             /* 0: the next piece draws afresh */
    double lq[AFM_MAX_MODES], lv[AFM_MAX_MODES]; /* the last piece's (last_cells) */
    int last_cells;
    double rq[AFM_MAX_MODES], rv[AFM_MAX_MODES]; /* the sample's rest, rem_cells */
    int rem_cells;
    double sq[AFM_MAX_MODES], sv[AFM_MAX_MODES]; /* a substep's rest after its crossing */
} rt_noise;

/* ---- forces ---- */

/* Starr squeeze film from the interpolant; *kx, *kv its partials (afm_force_squeeze_term
 * outside the window). */
static inline double rt_squeeze(const afm_sim *s, const rt_state *r, double x, double v, double *kx,
                                double *kv) {
    const afm_force_params *p = &s->f;
    double dcdh, c = afm_rt_starr_eval(&r->starr, afm_force_starr_h(p, s->z_m, x), &dcdh);
    if (c >= 0.0) {
        *kv = -c;
        *kx = -dcdh * p->cos_alpha * v;
        return -c * v;
    }
    return afm_force_squeeze_term(p, s->z_m, x, v, kx, kv);
}

/* Total tip force at (x, v) and its partials: afm_force_tip, inlined. */
AFM_CLONES static inline double rt_force(const afm_sim *s, const rt_state *r, double x, double v,
                                         double *fx, double *fv) {
    const afm_force_params *p = &s->f;
    double fc, fvi, kx, kv;
    double f = afm_force_near_terms(p, fma(x, p->cos_alpha, s->z_m), v, &fc, &fvi, &kx, &kv);
    if (p->squeeze == AFM_SQUEEZE_LINEAR) { /* afm_force_squeeze_term's linear film */
        double c = fma(p->p1, s->z_m + x, p->p2);
        if (c > 0.0) {
            f = fma(-c, v, f);
            kv -= c;
            kx = fma(-p->p1, v, kx);
        }
    } else if (p->squeeze == AFM_SQUEEZE_STARR) {
        double sx, sv;
        f += rt_squeeze(s, r, x, v, &sx, &sv);
        kx += sx;
        kv += sv;
    }
    *fx = kx;
    *fv = kv;
    return f;
}

/* ---- one implicit piece ---- */

/* Solve F = f(xs + gx F, vs + gv F) from the guess F. Each iteration corrects with the
 * newest reciprocal slope rj = 1 / g'(F) known before it (a chord step: out of contact g'
 * is 1 to 1e-5, so this is Newton there), which keeps the division off the critical path;
 * a bracket turns a step that leaves it into bisection. Leaves f's partials and rj in o. */
static inline __attribute__((always_inline)) double rt_solve_in(const afm_sim *s, const rt_state *r,
                                                                double xs, double vs, double gx,
                                                                double gv, double F, double rj,
                                                                rt_snap *o) {
    double fx, fv;
    double f = rt_force(s, r, fma(gx, F, xs), fma(gv, F, vs), &fx, &fv);
    double res = F - f, fn = fma(-res, rj, F);
    /* g'(F) = 1 - fx gx - fv gv is >= 1 in contact (fx, fv <= 0); the floor guards the
     * attractive branch, where it stays near 1 for any real cantilever. */
    double jac = 1.0 - fx * gx - fv * gv;
    jac = jac > 0.25 ? jac : 0.25;
    /* What the next chord step would still change: |fn - F| |1 - jac rj| (the quadratic
     * Newton term is below that by orders of magnitude for any step taken here). Out of
     * contact this is ~1e-8 of the force change per step: the test never fails there, and
     * nothing on the path to the next force waits for it. */
    double est = fabs(fn - F) * fabs(1.0 - jac * rj);
    rj = 1.0 / jac;
    if (__builtin_expect(est > r->ftol, 0)) {
        double lo = res > 0 ? -HUGE_VAL : F, hi = res > 0 ? F : HUGE_VAL;
        F = fn;
        for (int it = 1; it < RT_NEWTON_MAX; it++) {
            f = rt_force(s, r, fma(gx, F, xs), fma(gv, F, vs), &fx, &fv);
            res = F - f;
            if (res > 0)
                hi = F;
            else
                lo = F;
            fn = F - res * rj;
            jac = 1.0 - fx * gx - fv * gv;
            jac = jac > 0.25 ? jac : 0.25;
            est = fabs(fn - F) * fabs(1.0 - jac * rj);
            rj = 1.0 / jac;
            if (!(fn > lo && fn < hi) && lo > -HUGE_VAL && hi < HUGE_VAL) {
                fn = 0.5 * (lo + hi);
                est = hi - lo;
            }
            if (!(est > r->ftol)) break;
            F = fn;
        }
    }
    o->dfdx_n_m = fx;
    o->dfdv_n_s_m = fv;
    o->tip.inv_slope = rj;
    return fn;
}

/* rt_solve_in out of line: the rare fallback of the free step (rt_solve_fast). The
 * contact pieces inline rt_solve_in. */
static AFM_CLONES_NOINLINE double rt_solve(const afm_sim *s, const rt_state *r, double xs,
                                           double vs, double gx, double gv, double F, double rj,
                                           rt_snap *o) {
    return rt_solve_in(s, r, xs, vs, gx, gv, F, rj, o);
}

/* Out of contact, d = x cos(alpha) + Z >= a0: the force terms valid there, inlined. */
static inline __attribute__((always_inline)) double rt_force_out(const afm_sim *s,
                                                                 const rt_state *r, double x,
                                                                 double v, double d, double *fx,
                                                                 double *fv) {
    const afm_force_params *p = &s->f;
    double f = afm_force_out_terms(p, d, fx);
    *fv = 0.0;
    if (p->squeeze == AFM_SQUEEZE_LINEAR) {
        double c = fma(p->p1, s->z_m + x, p->p2);
        if (c > 0.0) {
            f = fma(-c, v, f);
            *fv = -c;
            *fx = fma(-p->p1, v, *fx);
        }
    } else if (p->squeeze == AFM_SQUEEZE_STARR) {
        double sx, sv;
        f += rt_squeeze(s, r, x, v, &sx, &sv);
        *fx += sx;
        *fv = sv;
    }
    return f;
}

/* rt_solve for a step that starts out of contact: one force evaluation at the guess F and
 * one chord correction with the reciprocal slope rj of the step before (a linearly
 * implicit step). Its convergence estimate is checked off the critical path; a step that
 * fails it, or whose guess is in contact, goes to rt_solve. x, v and d = x cos(alpha) + Z
 * at the guess (xs + gx F, vs + gv F) are the caller's (rt_tip: one multiply-add from the
 * last force). */
static inline __attribute__((always_inline)) double
rt_solve_fast(const afm_sim *s, const rt_state *r, double xs, double vs, double gx, double gv,
              double F, double rj, double x, double v, double d, rt_snap *o) {
    const afm_force_params *p = &s->f;
    if (__builtin_expect(!(d >= p->a0_m), 0)) return rt_solve(s, r, xs, vs, gx, gv, F, rj, o);
    double fx, fv;
    double f = rt_force_out(s, r, x, v, d, &fx, &fv);
    double fn = fma(f - F, rj, F);
    double jac = 1.0 - fx * gx - fv * gv;
    jac = jac > 0.25 ? jac : 0.25;
    double est = fabs(fn - F) * fabs(1.0 - jac * rj);
    if (__builtin_expect(est > r->ftol, 0)) return rt_solve(s, r, xs, vs, gx, gv, F, rj, o);
    o->dfdx_n_m = fx;
    o->dfdv_n_s_m = fv;
    o->tip.inv_slope = 1.0 / jac;
    return fn;
}

/* Four modes at a time. GCC/Clang vector extension (plain C would leave it to the
 * auto-vectoriser, which at -O2 turned these loops into memcpy calls and scalar code);
 * aligned(8) and may_alias make loads from any double array legal. */
typedef double rt_v4 __attribute__((vector_size(32), aligned(8), may_alias));
#if !defined(__AVX__) && defined(__GNUC__) && !defined(__clang__)
/* Without AVX, gcc warns that passing rt_v4 by value has another ABI; every such function
 * here is static, so no other object file sees that ABI. */
#pragma GCC diagnostic ignored "-Wpsabi"
#endif
#if !defined(__AVX__) && defined(__clang__) /* the same warning from clang (portable builds) */
#pragma clang diagnostic ignored "-Wpsabi"
#endif
#define RT_V4(p) (*(const rt_v4 *)(const void *)(p))
#define RT_V4W(p) (*(rt_v4 *)(void *)(p))

/* a b + c, rounded once per lane in every build (-std=c11 keeps gcc from contracting
 * anything else): one vfmadd in an x86-64-v3 build; elsewhere lane by lane with
 * __builtin_fma, which gcc and clang fold into one vfmadd in the x86-64-v3 clone of a
 * portable build (AFM_CLONES) and into fmla on arm64, so every copy gives the same bits (the
 * baseline x86-64 copy calls libm's fma: slow, exact). As AFM_V4_FMA of the estimators. */
static inline __attribute__((always_inline)) rt_v4 rt_fma4(rt_v4 a, rt_v4 b, rt_v4 c) {
#if defined(__FMA__) && defined(__AVX__)
    return (rt_v4)_mm256_fmadd_pd((__m256d)a, (__m256d)b, (__m256d)c);
#else
    return (rt_v4){__builtin_fma(a[0], b[0], c[0]), __builtin_fma(a[1], b[1], c[1]),
                   __builtin_fma(a[2], b[2], c[2]), __builtin_fma(a[3], b[3], c[3])};
#endif
}

static inline rt_v4 rt_splat(double x) {
    return (rt_v4){x, x, x, x};
}

static inline double rt_hsum(rt_v4 a) {
    return (a[0] + a[1]) + (a[2] + a[3]);
}

/* rt_hsum of a and b at once (one horizontal add), same rounding. */
static inline void rt_hsum2(rt_v4 a, rt_v4 b, double *sa, double *sb) {
#if defined(__AVX__)
    __m256d t = _mm256_hadd_pd((__m256d)a, (__m256d)b); /* a0+a1, b0+b1, a2+a3, b2+b3 */
    __m128d u = _mm_add_pd(_mm256_castpd256_pd128(t), _mm256_extractf128_pd(t, 1));
    *sa = u[0];
    *sb = u[1];
#else
    *sa = rt_hsum(a);
    *sb = rt_hsum(b);
#endif
}

/* d = x cos(alpha) + Z. */
static inline double rt_gap(const rt_state *r, double x) {
    return fma(x, r->cos_alpha, r->z_m);
}

/* The drive's tones. nt is a constant in every hot copy: 1 (scalar), or RT_TONES_V4 when
 * several tones run: then all AFM_MAX_TONES phasors are rotated and summed as one vector,
 * whatever their number (every per-tone array is zero past ntones: rt_changed,
 * afm_rt_coef_drive, rt_sync_phasors), so four tones cost what one does (a scalar loop over
 * four tones cost +14 ns/sample, the soak's worst state, issue 12). */
#define RT_TONES_V4 AFM_MAX_TONES
_Static_assert(AFM_MAX_TONES == 4, "the tone vector is one rt_v4");

/* The nt of r's tones: 0, 1 or RT_TONES_V4. */
static inline int rt_tones_kind(const rt_state *r) {
    return r->ntones > 1 ? RT_TONES_V4 : r->ntones;
}

/* sum_j Im(c_j z_j) = c_re z_im + c_im z_re over nt tones. */
static inline double rt_tones_im(const double *c_re, const double *c_im, const double *z_re,
                                 const double *z_im, int nt) {
    if (nt == RT_TONES_V4)
        return rt_hsum(rt_fma4(RT_V4(c_re), RT_V4(z_im), RT_V4(c_im) * RT_V4(z_re)));
    double t = 0.0;
    for (int j = 0; j < nt; j++)
        t += c_re[j] * z_im[j] + c_im[j] * z_re[j];
    return t;
}

/* o = z rot per tone (complex); o may not be z. */
static inline void rt_tones_rotate(const double *z_re, const double *z_im, const double *rot_re,
                                   const double *rot_im, double *o_re, double *o_im, int nt) {
    if (nt == RT_TONES_V4) {
        rt_v4 zr = RT_V4(z_re), zi = RT_V4(z_im), rr = RT_V4(rot_re), ri = RT_V4(rot_im);
        RT_V4W(o_re) = zr * rr - zi * ri;
        RT_V4W(o_im) = zr * ri + zi * rr;
        return;
    }
    for (int j = 0; j < nt; j++) {
        o_re[j] = z_re[j] * rot_re[j] - z_im[j] * rot_im[j];
        o_im[j] = z_re[j] * rot_im[j] + z_im[j] * rot_re[j];
    }
}

/* x*, v* of a full step from st (the tip at the step's end without its F1 response), and
 * x, v, d at its first guess. */
static void rt_predict(const rt_state *r, rt_snap *st) {
    const afm_rt_prop *P = &r->prop[r->ncell - 1];
    const int np = r->np;
    const double *c = P->c;
    rt_v4 xs4 = rt_splat(0.0), vs4 = rt_splat(0.0);
    for (int i = 0; i < np; i += 4) {
        rt_v4 q = RT_V4(st->q + i), v = RT_V4(st->v + i);
        xs4 = rt_fma4(RT_V4(c + 8 * np + i), q, rt_fma4(RT_V4(c + 9 * np + i), v, xs4));
        vs4 = rt_fma4(RT_V4(c + 10 * np + i), q, rt_fma4(RT_V4(c + 11 * np + i), v, vs4));
    }
    double xs = P->gx0 * st->tip.f_n + rt_hsum(xs4), vs = P->gv0 * st->tip.f_n + rt_hsum(vs4);
    for (int j = 0; j < r->ntones; j++) {
        xs += P->dx_re[j] * st->z_im[j] + P->dx_im[j] * st->z_re[j];
        vs += P->dv_re[j] * st->z_im[j] + P->dv_im[j] * st->z_re[j];
    }
    st->tip.x_free_m = xs;
    st->tip.v_free_m_s = vs;
    st->tip.x_guess_m = fma(P->gx, st->tip.f_n, xs);
    st->tip.v_guess_m_s = fma(P->gv, st->tip.f_n, vs);
    st->tip.gap_guess_m = rt_gap(r, st->tip.x_guess_m);
}

/* The thermal increment of a piece of k cells: (nq, nv) per mode (zero past n) and its tip
 * sums (*xq, *xv). The increment given for it (a redone piece: rt_noise) if there is one,
 * else a fresh draw; kept as the last piece's. */
static inline void rt_thermal_draw(const rt_state *r, int k, double *nq, double *nv, double *xq,
                                   double *xv) {
    const int np = r->np;
    const double *l = r->lth + 3 * (size_t)np * (size_t)(k - 1);
    rt_noise *z = r->nz;
    bool given = z->given_cells == k;
    z->given_cells = 0;
    double sx = 0.0, sv = 0.0;
    for (int i = 0; i < np; i++) {
        if (given) {
            nq[i] = z->gq[i];
            nv[i] = z->gv[i];
        } else {
            double n1 = 0.0, n2 = 0.0;
            if (i < r->n) {
                n1 = afm_rng_normal(r->rng);
                n2 = afm_rng_normal(r->rng);
            }
            nq[i] = l[i] * n1;
            nv[i] = fma(l[np + i], n1, l[2 * np + i] * n2);
        }
        z->lq[i] = nq[i];
        z->lv[i] = nv[i];
        sx = fma(r->tip[i], nq[i], sx);
        sv = fma(r->tip[i], nv[i], sv);
    }
    z->last_cells = k;
    *xq = sx;
    *xv = sv;
}

/* The bridge gain of the first k1 cells of an interval of len cells (rt_state.bridge). */
static const double *rt_bridge_gain(const rt_state *r, int k1, int len) {
    size_t at = len == RT_GRID ? (size_t)(k1 - 1) : (size_t)(RT_GRID - 1 + len / RT_GRID - 2);
    return r->bridge + 4 * (size_t)r->np * at;
}

/* The increment of the first k1 cells of an interval of len cells whose increment (rq, rv)
 * is drawn, distributed as it is given that one (Matheron's rule with fresh draws of both
 * parts: afm_rt_coef_bridge), into r->nz's given; (rq, rv) becomes the rest's increment. */
static void rt_bridge_draw(const rt_state *r, int k1, int len, double *rq, double *rv) {
    const size_t np = (size_t)r->np;
    const double *kg = rt_bridge_gain(r, k1, len);
    const double *l1 = r->lth + 3 * np * (size_t)(k1 - 1);
    const double *l2 = r->lth + 3 * np * (size_t)(len - k1 - 1);
    const double *p2 = r->prop[len - k1 - 1].c; /* Phi of the rest */
    rt_noise *z = r->nz;
    for (size_t i = 0; i < np; i++) {
        z->gq[i] = z->gv[i] = 0.0;
        if (i >= (size_t)r->n) continue;
        double a1 = afm_rng_normal(r->rng), a2 = afm_rng_normal(r->rng);
        double b1 = afm_rng_normal(r->rng), b2 = afm_rng_normal(r->rng);
        double xq = l1[i] * a1, xv = fma(l1[np + i], a1, l1[2 * np + i] * a2);
        double yq = l2[i] * b1, yv = fma(l2[np + i], b1, l2[2 * np + i] * b2);
        double p11 = p2[i], p12 = p2[np + i], p21 = p2[2 * np + i], p22 = p2[3 * np + i];
        double eq = rq[i] - (p11 * xq + p12 * xv + yq), ev = rv[i] - (p21 * xq + p22 * xv + yv);
        double gq = xq + kg[i] * eq + kg[np + i] * ev;
        double gv = xv + kg[2 * np + i] * eq + kg[3 * np + i] * ev;
        z->gq[i] = gq;
        z->gv[i] = gv;
        rq[i] -= p11 * gq + p12 * gv;
        rv[i] -= p21 * gq + p22 * gv;
    }
    z->given_cells = k1;
}

/* The reciprocal slope of a piece with coefficients P that starts where the force's partials
 * are fx, fv: 1 / max(1 - fx gx - fv gv, 1/4). */
static inline double rt_slope(const afm_rt_prop *P, double fx, double fv) {
    double jj = 1.0 - fx * P->gx - fv * P->gv; /* fmax(jj, 0.25), inlined */
    return 1.0 / (jj > 0.25 ? jj : 0.25);
}

/* rt_tip of st for a following full step. */
static inline rt_tip rt_tip_of(const rt_state *r, const rt_snap *st) {
    double rj = st->slope_cells == r->ncell
                    ? st->tip.inv_slope
                    : rt_slope(&r->prop[r->ncell - 1], st->dfdx_n_m, st->dfdv_n_s_m);
    rt_tip t = st->tip;
    t.inv_slope = rj;
    return t;
}

/* Which piece rt_piece_t advances. Every call passes constants, so that each kind becomes
 * its own straight-line code (rt_piece_t is always inlined). */
typedef struct {
    int np;         /* mode stride: n rounded up to 4 (coefficients are zero past n) */
    int ntones;     /* drive tones */
    bool free_step; /* the free step (k = ncell, predict): in's tip comes from *ti and o's
                     * goes to *to as well; one linearly implicit solve (rt_solve_fast) */
    bool thermal;   /* add the thermal increment (afm_sim_set_thermal) */
    bool predict;   /* leave the predictor of a following full step in o (the free step
                     * does; contact pieces leave it to one rt_predict after the sample) */
} rt_piece_kind;

/* Advance in by k cells (tau = k dt / ncell) into o; o may be in. A full step
 * (k = ncell) takes x*, v* from in's predictor; a shorter piece from its own tip-weighted
 * rows. */
static inline __attribute__((always_inline)) void rt_piece_t(const afm_sim *s, const rt_state *r,
                                                             const rt_snap *in, rt_snap *o, int k,
                                                             const rt_piece_kind kind,
                                                             const rt_tip *ti, rt_tip *to) {
    const int np = kind.np, nt = kind.ntones;
    const afm_rt_prop *P = &r->prop[k - 1], *PF = &r->prop[r->ncell - 1];
    const double *c = P->c, *cf = PF->c;
    const double F0 = kind.free_step ? ti->f_n : in->tip.f_n;
    double xs, vs, rj;
    double nq[AFM_MAX_MODES] __attribute__((aligned(32)));
    double nv[AFM_MAX_MODES] __attribute__((aligned(32)));
    if (kind.free_step) {
        xs = ti->x_free_m;
        vs = ti->v_free_m_s;
    } else if (k == r->ncell) {
        xs = in->tip.x_free_m;
        vs = in->tip.v_free_m_s;
    } else {
        rt_v4 xs4 = rt_splat(0.0), vs4 = rt_splat(0.0);
        for (int i = 0; i < np; i += 4) {
            rt_v4 q = RT_V4(in->q + i), v = RT_V4(in->v + i);
            xs4 = rt_fma4(RT_V4(c + 8 * np + i), q, rt_fma4(RT_V4(c + 9 * np + i), v, xs4));
            vs4 = rt_fma4(RT_V4(c + 10 * np + i), q, rt_fma4(RT_V4(c + 11 * np + i), v, vs4));
        }
        rt_hsum2(xs4, vs4, &xs, &vs);
        xs = fma(P->gx0, F0, xs);
        vs = fma(P->gv0, F0, vs);
        xs += rt_tones_im(P->dx_re, P->dx_im, in->z_re, in->z_im, nt);
        vs += rt_tones_im(P->dv_re, P->dv_im, in->z_re, in->z_im, nt);
    }
    if (kind.thermal) {
        double xq, xv;
        rt_thermal_draw(r, k, nq, nv, &xq, &xv);
        xs += xq;
        vs += xv;
    }
    if (kind.free_step) {
        rj = ti->inv_slope;
    } else {
        rj = in->slope_cells == k ? in->tip.inv_slope : rt_slope(P, in->dfdx_n_m, in->dfdv_n_s_m);
    }
    /* The force first (the critical path); the modal update below does not wait for it
     * until its last multiply-add. */
    /* In contact the force changes fast: the iteration starts from the force extrapolated
     * along the last piece's slope (about one force evaluation fewer per piece). */
    double F1 = kind.free_step ? rt_solve_fast(s, r, xs, vs, P->gx, P->gv, F0, rj, ti->x_guess_m,
                                               ti->v_guess_m_s, ti->gap_guess_m, o)
                               : rt_solve_in(s, r, xs, vs, P->gx, P->gv,
                                             fma(in->df_per_cell_n, (double)k, F0), rj, o);
    const double dfc = (F1 - F0) * r->inv_cells[k];
    double zr1[AFM_MAX_TONES], zi1[AFM_MAX_TONES];
    double xn = 0.0, vn = 0.0;
    rt_tones_rotate(in->z_re, in->z_im, P->rot_re, P->rot_im, zr1, zi1, nt);
    if (kind.predict) {
        xn = rt_tones_im(PF->dx_re, PF->dx_im, zr1, zi1, nt);
        vn = rt_tones_im(PF->dv_re, PF->dv_im, zr1, zi1, nt);
    }
    const rt_v4 f0 = rt_splat(F0), f1 = rt_splat(F1);
    rt_v4 xn4 = rt_splat(0.0), vn4 = rt_splat(0.0);
    for (int i = 0; i < np; i += 4) {
        rt_v4 q = RT_V4(in->q + i), v = RT_V4(in->v + i);
        rt_v4 a =
            rt_fma4(RT_V4(c + i), q, rt_fma4(RT_V4(c + np + i), v, RT_V4(c + 4 * np + i) * f0));
        rt_v4 w = rt_fma4(RT_V4(c + 2 * np + i), q,
                          rt_fma4(RT_V4(c + 3 * np + i), v, RT_V4(c + 5 * np + i) * f0));
        if (kind.thermal) {
            a += RT_V4(nq + i);
            w += RT_V4(nv + i);
        }
        /* next full step's x*, v* without this F1 (its F1 part is P->hx F1, P->hv F1) */
        if (kind.predict) {
            xn4 = rt_fma4(RT_V4(cf + 8 * np + i), a, rt_fma4(RT_V4(cf + 9 * np + i), w, xn4));
            vn4 = rt_fma4(RT_V4(cf + 10 * np + i), a, rt_fma4(RT_V4(cf + 11 * np + i), w, vn4));
        }
        RT_V4W(o->q + i) = rt_fma4(RT_V4(c + 6 * np + i), f1, a);
        RT_V4W(o->v + i) = rt_fma4(RT_V4(c + 7 * np + i), f1, w);
    }
    if (nt == RT_TONES_V4) { /* after the loop: in == o is allowed */
        RT_V4W(o->z_re) = RT_V4(zr1);
        RT_V4W(o->z_im) = RT_V4(zi1);
    } else {
        for (int j = 0; j < nt; j++) {
            o->z_re[j] = zr1[j];
            o->z_im[j] = zi1[j];
        }
    }
    o->slope_cells = k;
    o->df_per_cell_n = dfc;
    const double x1 = fma(P->gx, F1, xs), v1 = fma(P->gv, F1, vs);
    if (kind.predict) {
        double xh, vh;
        rt_hsum2(xn4, vn4, &xh, &vh);
        const double xr = xn + xh, vr = vn + vh;
        /* The next guess straight from F1 (one multiply-add each, not two: the force chain
         * from one step to the next is shorter; the same point up to rounding). */
        const rt_tip t = {.x_m = x1,
                          .v_m_s = v1,
                          .f_n = F1,
                          .x_free_m = fma(P->hx, F1, xr),
                          .v_free_m_s = fma(P->hv, F1, vr),
                          .inv_slope = o->tip.inv_slope, /* the solve's */
                          .x_guess_m = fma(r->guess_x_per_n, F1, xr),
                          .v_guess_m_s = fma(r->guess_v_per_n, F1, vr),
                          .gap_guess_m = fma(r->guess_gap_per_n, F1, rt_gap(r, xr))};
        o->tip = t;
        if (kind.free_step) *to = t;
    } else {
        o->tip.x_m = x1;
        o->tip.v_m_s = v1;
        o->tip.f_n = F1;
    }
}

/* rt_piece_t for the pieces of contact samples (iterated solve), without the predictor of
 * a following full step: rt_contact computes it once, after the sample's last piece. */
static AFM_CLONES_NOINLINE void rt_piece(const afm_sim *s, const rt_state *r, const rt_snap *in,
                                         rt_snap *o, int k) {
    if (r->noise)
        rt_piece_t(s, r, in, o, k,
                   (rt_piece_kind){.np = r->np, .ntones = rt_tones_kind(r), .thermal = true}, NULL,
                   NULL);
    else if (r->ntones == 1 && r->np == 4)
        rt_piece_t(s, r, in, o, k, (rt_piece_kind){.np = 4, .ntones = 1}, NULL, NULL);
    else if (r->ntones == 1 && r->np == 8)
        rt_piece_t(s, r, in, o, k, (rt_piece_kind){.np = 8, .ntones = 1}, NULL, NULL);
    else if (r->ntones > 1 && r->np == 4)
        rt_piece_t(s, r, in, o, k, (rt_piece_kind){.np = 4, .ntones = RT_TONES_V4}, NULL, NULL);
    else if (r->ntones > 1 && r->np == 8)
        rt_piece_t(s, r, in, o, k, (rt_piece_kind){.np = 8, .ntones = RT_TONES_V4}, NULL, NULL);
    else
        rt_piece_t(s, r, in, o, k, (rt_piece_kind){.np = r->np, .ntones = rt_tones_kind(r)}, NULL,
                   NULL);
}

/* ---- contact location on the cubic Hermite path x(sigma), sigma in [0, 1] ---- */

typedef struct {
    double a, b, c, d; /* x(sigma) = ((a sigma + b) sigma + c) sigma + d */
} rt_cubic;

static double rt_cubic_at(const rt_cubic *p, double sg) {
    return ((p->a * sg + p->b) * sg + p->c) * sg + p->d;
}

/* Root of x(sigma) = xc in (lo, hi), where x - xc changes sign (bisection-safe Newton). */
static double rt_cubic_root(const rt_cubic *p, double xc, double lo, double hi) {
    bool neg_lo = rt_cubic_at(p, lo) < xc;
    double sg = 0.5 * (lo + hi);
    for (int it = 0; it < 40; it++) {
        double g = rt_cubic_at(p, sg) - xc;
        if ((g < 0) == neg_lo)
            lo = sg;
        else
            hi = sg;
        double dg = (3.0 * p->a * sg + 2.0 * p->b) * sg + p->c;
        double nx = dg != 0.0 ? sg - g / dg : 0.5 * (lo + hi);
        if (!(nx > lo && nx < hi)) nx = 0.5 * (lo + hi);
        if (fabs(nx - sg) < 1e-7) return nx;
        sg = nx;
    }
    return sg;
}

/* Where the path from a to b (a piece of length tau) first crosses xc, rounded to the
 * piece's grid of RT_GRID cells: the crossing cell kc in 0..RT_GRID (lround(sigma RT_GRID)
 * of the crossing sigma in (0, 1)), or -1 if the path does not cross. locate = false only
 * asks whether it crosses (any value >= 0 then means yes). When the ends are on opposite
 * sides, lround(sigma RT_GRID) is the first cell midpoint (k + 1/2) / RT_GRID already on the
 * far side (for one crossing in the piece), so RT_GRID cubic evaluations replace a root
 * search; a dip between two ends out of contact is found by its stationary point first. */
static int rt_crossing_cell(const rt_state *r, const rt_snap *a, const rt_snap *b, double tau,
                            bool locate) {
    double x0 = a->tip.x_m, v0 = a->tip.v_m_s, x1 = b->tip.x_m, v1 = b->tip.v_m_s, xc = r->xc;
    bool in0 = x0 < xc, in1 = x1 < xc;
    bool dip = !in0 && !in1 && v0 < 0 && v1 > 0;
    if (in0 == in1 && !dip) return -1;
    if (in0 != in1 && !locate) return 0;
    rt_cubic p = {2.0 * (x0 - x1) + tau * (v0 + v1), 3.0 * (x1 - x0) - tau * (2.0 * v0 + v1),
                  tau * v0, x0};
    if (in0 != in1) {
        for (int k = 0; k < RT_GRID; k++)
            if ((rt_cubic_at(&p, (k + 0.5) * (1.0 / RT_GRID)) < xc) != in0) return k;
        return RT_GRID;
    }
    /* Both ends out of contact, turning inside: does the path dip below xc? Bisect x' = 0. */
    double lo = 0.0, hi = 1.0;
    for (int it = 0; it < 16; it++) {
        double sg = 0.5 * (lo + hi);
        if ((3.0 * p.a * sg + 2.0 * p.b) * sg + p.c < 0)
            lo = sg;
        else
            hi = sg;
    }
    double sm = 0.5 * (lo + hi);
    if (!(rt_cubic_at(&p, sm) < xc)) return -1;
    return (int)lround(rt_cubic_root(&p, xc, 0.0, sm) * RT_GRID);
}

/* One contact substep of RT_GRID cells from a into b, split at a located crossing. */
static void rt_substep(const afm_sim *s, const rt_state *r, const rt_snap *a, rt_snap *b,
                       double tau) {
    rt_piece(s, r, a, b, RT_GRID);
    int kc = rt_crossing_cell(r, a, b, tau, true);
    if (kc <= 0 || kc >= RT_GRID) return;
    rt_noise *z = r->nz;
    if (r->noise) { /* both parts from the substep's increment, drawn above */
        memcpy(z->sq, z->lq, sizeof z->sq);
        memcpy(z->sv, z->lv, sizeof z->sv);
        rt_bridge_draw(r, kc, RT_GRID, z->sq, z->sv);
    }
    rt_piece(s, r, a, b, kc);
    if (r->noise) {
        memcpy(z->gq, z->sq, sizeof z->gq);
        memcpy(z->gv, z->sv, sizeof z->gv);
        z->given_cells = RT_GRID - kc;
    }
    rt_piece(s, r, b, b, RT_GRID - kc);
}

/* ---- backend ---- */

/* Phasors exactly from afm_drive at s->t_s. */
static void rt_sync_phasors(const afm_sim *s, rt_state *r, rt_snap *st) {
    for (int j = 0; j < AFM_MAX_TONES; j++)
        st->z_re[j] = st->z_im[j] = 0.0; /* zero past ntones (RT_TONES_V4) */
    for (int j = 0; j < r->ntones; j++) {
        double th = afm_drive_phase_mod(&s->drive, j, s->t_s);
        st->z_re[j] = cos(th);
        st->z_im[j] = sin(th);
    }
    r->since_sync = 0;
}

/* The full state into struct afm_sim: q = qh + sum_j Im(c_j z_j), q' = qh' + sum_j
 * Im(i wd_j c_j z_j), and the tip outputs (be_fills_tip). Once per afm_sim_run. */
static void rt_publish(afm_sim *s, const rt_state *r, const rt_snap *b) {
    for (int i = 0; i < r->n; i++) {
        double q = b->q[i], v = b->v[i];
        for (int j = 0; j < r->ntones; j++) {
            double cr = r->cq_re[j][i], ci = r->cq_im[j][i];
            q += cr * b->z_im[j] + ci * b->z_re[j];
            v += r->wd[j] * (cr * b->z_re[j] - ci * b->z_im[j]);
        }
        s->q[i] = q;
        s->qd[i] = v;
    }
    double u = 0.0;
    for (int j = 0; j < r->ntones; j++)
        u += r->amp_m[j] * b->z_im[j];
    s->f_last_n = b->tip.f_n;
    s->x_last_m = b->tip.x_m;
    s->v_last_m = b->tip.v_m_s;
    s->base_last_m = u;
}

/* One sample that touches contact, from a: m substeps, each split at a crossing. The
 * result is in *a or *b; returns which. redo: the sample's free step was taken (and its
 * thermal increment drawn: the substeps' are drawn given it, rt_noise). */
static AFM_CLONES_NOINLINE rt_snap *rt_contact(const afm_sim *s, const rt_state *r, rt_snap *a,
                                               rt_snap *b, bool redo) {
    double tau = s->dt_s / r->m;
    rt_noise *z = r->nz;
    if (r->noise) {
        z->given_cells = 0;
        z->rem_cells = redo ? r->ncell : 0;
        if (redo) {
            memcpy(z->rq, z->lq, sizeof z->rq);
            memcpy(z->rv, z->lv, sizeof z->rv);
        }
    }
    for (int k = 0; k < r->m; k++) {
        if (r->noise && z->rem_cells > 0) { /* this substep's part of the sample's increment */
            if (z->rem_cells == RT_GRID) {
                memcpy(z->gq, z->rq, sizeof z->gq);
                memcpy(z->gv, z->rv, sizeof z->gv);
                z->given_cells = RT_GRID;
            } else {
                rt_bridge_draw(r, RT_GRID, z->rem_cells, z->rq, z->rv);
            }
            z->rem_cells -= RT_GRID;
        }
        rt_substep(s, r, a, b, tau);
        rt_snap *t = a;
        a = b;
        b = t;
    }
    rt_predict(r, a);
    return a;
}

/* ---- the accurate scheme: the force cubic Hermite in time (cfg.rt_scheme) ----
 *
 * Each piece takes the force as the Hermite interpolant of F0, F1 and the slopes D0, D1
 * (afm_rt_coef.h), fourth order in the step where the force is smooth. D = tau dF/dt with
 * dF/dt = f_x v + f_v a from the force law's partials at the last evaluation and the tip's
 * velocity and acceleration. The solve takes D1 = D0 (the force's slope carried over);
 * then D1 is computed at the end and the state takes Gd1 (D1 - D0). A sample runs as one
 * such piece while its path stays clear of the contact line (as the fast scheme's free
 * step); a sample that touches it is redone in m substeps, each first taken whole, and a
 * substep whose path crosses the contact line (or starts and ends beside it) is redone with
 * the force linear in time (the fast scheme's piece), split at the located crossing: no
 * polynomial in time follows a kink, and a slope from one side does not hold on the other. */

/* dF/dt at st from its force partials and the tip's velocity and acceleration. */
static inline double rt_fdot(const rt_state *r, const rt_snap *st, int np, int nt) {
    rt_v4 a4 = rt_splat(0.0);
    for (int i = 0; i < np; i += 4)
        a4 = rt_fma4(RT_V4(r->aq + i), RT_V4(st->q + i),
                     rt_fma4(RT_V4(r->av + i), RT_V4(st->v + i), a4));
    double acc = rt_hsum(a4) + r->tip2 * st->tip.f_n;
    acc += rt_tones_im(r->ax_re, r->ax_im, st->z_re, st->z_im, nt);
    return fma(st->dfdx_n_m, st->tip.v_m_s, st->dfdv_n_s_m * acc);
}

/* Advance in by k cells into o (o may be in); herm: the force Hermite in time, else linear
 * (a piece beside a crossing). Leaves o->fdot_n_s for the next piece. */
static inline __attribute__((always_inline)) void
rt_piece_acc_t(const afm_sim *s, const rt_state *r, const rt_snap *in, rt_snap *o, int k, bool herm,
               const int np, const int nt, const bool noise) {
    const afm_rt_prop *P = &r->prop[k - 1];
    const double *c = P->c, *ch = P->c + AFM_RT_ROW_GC * np;
    const double F0 = in->tip.f_n, tau = P->tau_s;
    const double D0 = herm ? tau * in->fdot_n_s : 0.0;
    double nq[AFM_MAX_MODES] __attribute__((aligned(32)));
    double nv[AFM_MAX_MODES] __attribute__((aligned(32)));
    double xs, vs;
    rt_v4 xs4 = rt_splat(0.0), vs4 = rt_splat(0.0);
    for (int i = 0; i < np; i += 4) {
        rt_v4 q = RT_V4(in->q + i), v = RT_V4(in->v + i);
        xs4 = rt_fma4(RT_V4(c + 8 * np + i), q, rt_fma4(RT_V4(c + 9 * np + i), v, xs4));
        vs4 = rt_fma4(RT_V4(c + 10 * np + i), q, rt_fma4(RT_V4(c + 11 * np + i), v, vs4));
    }
    rt_hsum2(xs4, vs4, &xs, &vs);
    double gxe = P->gx, gve = P->gv;
    if (herm) { /* F0 (1 + c) + D0 (h10 + h11), and F1 (sigma - c) */
        xs = fma(P->gx0 + P->gcx, F0, fma(P->gd0x + P->gd1x, D0, xs));
        vs = fma(P->gv0 + P->gcv, F0, fma(P->gd0v + P->gd1v, D0, vs));
        gxe -= P->gcx;
        gve -= P->gcv;
    } else {
        xs = fma(P->gx0, F0, xs);
        vs = fma(P->gv0, F0, vs);
    }
    xs += rt_tones_im(P->dx_re, P->dx_im, in->z_re, in->z_im, nt);
    vs += rt_tones_im(P->dv_re, P->dv_im, in->z_re, in->z_im, nt);
    if (noise) {
        double xq, xv;
        rt_thermal_draw(r, k, nq, nv, &xq, &xv);
        xs += xq;
        vs += xv;
    }
    double jj = 1.0 - in->dfdx_n_m * gxe - in->dfdv_n_s_m * gve;
    const double rj = 1.0 / (jj > 0.25 ? jj : 0.25);
    const double F1 =
        rt_solve_in(s, r, xs, vs, gxe, gve, fma(in->df_per_cell_n, (double)k, F0), rj, o);
    double zr1[AFM_MAX_TONES], zi1[AFM_MAX_TONES];
    rt_tones_rotate(in->z_re, in->z_im, P->rot_re, P->rot_im, zr1, zi1, nt);
    const rt_v4 f0 = rt_splat(F0), f1 = rt_splat(F1), fc = rt_splat(F0 - F1), d0 = rt_splat(D0);
    rt_v4 a4 = rt_splat(0.0);
    for (int i = 0; i < np; i += 4) {
        rt_v4 q = RT_V4(in->q + i), v = RT_V4(in->v + i);
        rt_v4 a = rt_fma4(RT_V4(c + i), q,
                          rt_fma4(RT_V4(c + np + i), v,
                                  rt_fma4(RT_V4(c + 4 * np + i), f0, RT_V4(c + 6 * np + i) * f1)));
        rt_v4 w = rt_fma4(RT_V4(c + 2 * np + i), q,
                          rt_fma4(RT_V4(c + 3 * np + i), v,
                                  rt_fma4(RT_V4(c + 5 * np + i), f0, RT_V4(c + 7 * np + i) * f1)));
        if (herm) { /* D1 = D0 for now: Gd0 + Gd1 */
            a = rt_fma4(RT_V4(ch + i), fc,
                        rt_fma4(RT_V4(ch + 2 * np + i) + RT_V4(ch + 4 * np + i), d0, a));
            w = rt_fma4(RT_V4(ch + np + i), fc,
                        rt_fma4(RT_V4(ch + 3 * np + i) + RT_V4(ch + 5 * np + i), d0, w));
        }
        if (noise) {
            a += RT_V4(nq + i);
            w += RT_V4(nv + i);
        }
        RT_V4W(o->q + i) = a;
        RT_V4W(o->v + i) = w;
        a4 = rt_fma4(RT_V4(r->aq + i), a, rt_fma4(RT_V4(r->av + i), w, a4));
    }
    if (nt == RT_TONES_V4) {
        RT_V4W(o->z_re) = RT_V4(zr1);
        RT_V4W(o->z_im) = RT_V4(zi1);
    } else {
        for (int j = 0; j < nt; j++) {
            o->z_re[j] = zr1[j];
            o->z_im[j] = zi1[j];
        }
    }
    double x1 = fma(gxe, F1, xs), v1 = fma(gve, F1, vs);
    double acc = rt_hsum(a4) + r->tip2 * F1 + rt_tones_im(r->ax_re, r->ax_im, zr1, zi1, nt);
    double fdot = fma(o->dfdx_n_m, v1, o->dfdv_n_s_m * acc);
    if (herm) { /* the end slope found: the state takes Gd1 (D1 - D0) */
        const double dd = fma(tau, fdot, -D0);
        const rt_v4 dd4 = rt_splat(dd);
        for (int i = 0; i < np; i += 4) {
            RT_V4W(o->q + i) = rt_fma4(RT_V4(ch + 4 * np + i), dd4, RT_V4(o->q + i));
            RT_V4W(o->v + i) = rt_fma4(RT_V4(ch + 5 * np + i), dd4, RT_V4(o->v + i));
        }
        x1 = fma(P->gd1x, dd, x1);
        v1 = fma(P->gd1v, dd, v1);
    }
    o->slope_cells = 0;
    o->df_per_cell_n = (F1 - F0) * r->inv_cells[k];
    o->tip.x_m = x1;
    o->tip.v_m_s = v1;
    o->tip.f_n = F1;
    o->fdot_n_s = fdot;
}

/* rt_piece_acc_t out of line for the contact pieces, the sizes picked once. */
static AFM_CLONES_NOINLINE void rt_piece_acc(const afm_sim *s, const rt_state *r, const rt_snap *in,
                                             rt_snap *o, int k, bool herm) {
    if (r->noise)
        rt_piece_acc_t(s, r, in, o, k, herm, r->np, rt_tones_kind(r), true);
    else if (r->ntones == 1 && r->np == 4)
        rt_piece_acc_t(s, r, in, o, k, herm, 4, 1, false);
    else if (r->ntones == 1 && r->np == 8)
        rt_piece_acc_t(s, r, in, o, k, herm, 8, 1, false);
    else if (r->ntones > 1 && r->np == 4)
        rt_piece_acc_t(s, r, in, o, k, herm, 4, RT_TONES_V4, false);
    else if (r->ntones > 1 && r->np == 8)
        rt_piece_acc_t(s, r, in, o, k, herm, 8, RT_TONES_V4, false);
    else
        rt_piece_acc_t(s, r, in, o, k, herm, r->np, rt_tones_kind(r), false);
}

/* One contact substep of RT_GRID cells from a into b: Hermite, or, where its path crosses
 * the contact line, linear and split at the crossing (rt_substep's thermal bookkeeping). */
static void rt_substep_acc(const afm_sim *s, const rt_state *r, const rt_snap *a, rt_snap *b,
                           double tau) {
    rt_piece_acc(s, r, a, b, RT_GRID, true);
    int kc = rt_crossing_cell(r, a, b, tau, true);
    if (kc < 0) return;
    rt_noise *z = r->nz;
    if (kc == 0 || kc >= RT_GRID) { /* at an end: the whole substep linear */
        if (r->noise) {
            memcpy(z->gq, z->lq, sizeof z->gq);
            memcpy(z->gv, z->lv, sizeof z->gv);
            z->given_cells = RT_GRID;
        }
        rt_piece_acc(s, r, a, b, RT_GRID, false);
        return;
    }
    if (r->noise) {
        memcpy(z->sq, z->lq, sizeof z->sq);
        memcpy(z->sv, z->lv, sizeof z->sv);
        rt_bridge_draw(r, kc, RT_GRID, z->sq, z->sv);
    }
    rt_piece_acc(s, r, a, b, kc, false);
    if (r->noise) {
        memcpy(z->gq, z->sq, sizeof z->gq);
        memcpy(z->gv, z->sv, sizeof z->gv);
        z->given_cells = RT_GRID - kc;
    }
    rt_piece_acc(s, r, b, b, RT_GRID - kc, false);
}

/* rt_contact for the accurate scheme. */
static AFM_CLONES_NOINLINE rt_snap *rt_contact_acc(const afm_sim *s, const rt_state *r, rt_snap *a,
                                                   rt_snap *b, bool redo) {
    double tau = s->dt_s / r->m;
    rt_noise *z = r->nz;
    if (r->noise) {
        z->given_cells = 0;
        z->rem_cells = redo ? r->ncell : 0;
        if (redo) {
            memcpy(z->rq, z->lq, sizeof z->rq);
            memcpy(z->rv, z->lv, sizeof z->rv);
        }
    }
    for (int k = 0; k < r->m; k++) {
        if (r->noise && z->rem_cells > 0) {
            if (z->rem_cells == RT_GRID) {
                memcpy(z->gq, z->rq, sizeof z->gq);
                memcpy(z->gv, z->rv, sizeof z->gv);
                z->given_cells = RT_GRID;
            } else {
                rt_bridge_draw(r, RT_GRID, z->rem_cells, z->rq, z->rv);
            }
            z->rem_cells -= RT_GRID;
        }
        rt_substep_acc(s, r, a, b, tau);
        rt_snap *t = a;
        a = b;
        b = t;
    }
    return a;
}

/* n output steps of the accurate scheme (afm_sim_backend.run when r->acc). */
static inline __attribute__((always_inline)) int rt_run_acc_t(afm_sim *s, rt_state *r, int n,
                                                              afm_sample *out, const int np,
                                                              const int nt, const bool noise) {
    int rc = AFM_SIM_OK;
    long step = s->step;
    const double t0 = s->t_start_s, dt = s->dt_s;
    rt_snap *a = &r->buf[r->cur];
    for (int k = 0; k < n; k++) {
        if (__builtin_expect(++r->since_sync >= RT_RESYNC, 0)) {
            s->step = step;
            s->t_s = t0 + (double)step * dt;
            rt_sync_phasors(s, r, a);
            a->fdot_n_s = rt_fdot(r, a, np, nt);
        }
        rt_snap *b = a == &r->buf[0] ? &r->buf[1] : &r->buf[0];
        const bool at_once = r->kinked && a->tip.x_m < r->xc;
        bool contact = at_once;
        if (!contact) {
            rt_piece_acc_t(s, r, a, b, r->ncell, true, np, nt, noise);
            if (r->kinked) {
                /* the path's low bound; within one travel of the contact line the steep
                 * van der Waals pulse needs the substeps even where it does not cross */
                const double sp = fabs(a->tip.v_m_s) + fabs(b->tip.v_m_s);
                const double low =
                    (a->tip.x_m < b->tip.x_m ? a->tip.x_m : b->tip.x_m) - r->clear_k * sp;
                contact = low < r->xc + RT_ACC_NEAR_TRAVELS * sp * dt;
            }
        }
        if (contact) b = rt_contact_acc(s, r, a, b, noise && !at_once);
        a = b;
        step++;
        if (!(fabs(a->tip.x_m) < 1e-3) ||
            !(fabs(a->tip.v_m_s) < HUGE_VAL && fabs(a->tip.f_n) < HUGE_VAL)) {
            rc = AFM_SIM_EBLOWUP;
            break;
        }
        if (out) {
            afm_sample *o = out + k;
            rt_v4 th4 = rt_splat(0.0);
            for (int i = 0; i < np; i += 4)
                th4 = rt_fma4(RT_V4(r->rot + i), RT_V4(a->q + i), th4);
            double th = rt_hsum(th4) + rt_tones_im(r->th_re, r->th_im, a->z_re, a->z_im, nt);
            double u = 0.0;
            if (nt == RT_TONES_V4)
                u = rt_hsum(RT_V4(r->amp_m) * RT_V4(a->z_im));
            else
                for (int jt = 0; jt < nt; jt++)
                    u += r->amp_m[jt] * a->z_im[jt];
            o->t_s = t0 + (double)step * dt;
            o->x_m = a->tip.x_m;
            o->v_m_s = a->tip.v_m_s;
            o->f_n = a->tip.f_n;
            o->theta_rad = th;
            o->base_m = u;
        }
    }
    s->step = step;
    s->t_s = t0 + (double)step * dt;
    r->cur = a == &r->buf[0] ? 0 : 1;
    rt_publish(s, r, a);
    return rc;
}

/* n output steps (afm_sim_backend.run), with the common sizes (up to 8 modes, one tone)
 * and the thermal switch as constants so that the full step's loops unroll and the
 * phasors stay in registers. */
static inline __attribute__((always_inline)) int rt_run_t(afm_sim *s, rt_state *r, int n,
                                                          afm_sample *out, const int np,
                                                          const int nt, const bool noise) {
    int rc = AFM_SIM_OK;
    /* The clock, the buffer index and the resync count live in registers over the block; the
     * block is cut into segments that end before the next phasor resync, so the inner loop
     * tests neither. Blow-up: |x| is tested every sample (a non-finite q_i, v or F reaches x
     * within one step: x is a sum over every mode, affine in the last force); x', F once per
     * segment, after its last sample. */
    long step = s->step, since = r->since_sync;
    double stepd = (double)step; /* the step count as a double (exact below 2^53) */
    const double t0 = s->t_start_s, dt = s->dt_s;
    int cur = r->cur;
    const double gx_full = r->prop[r->ncell - 1].gx;
    rt_tip ta = rt_tip_of(r, &r->buf[cur]), tb; /* the tip at a and at bb, in registers */
    for (int k = 0; k < n && rc == AFM_SIM_OK;) {
        if (__builtin_expect(++since >= RT_RESYNC, 0)) {
            s->step = step;
            s->t_s = t0 + stepd * dt;
            rt_sync_phasors(s, r, &r->buf[cur]);
            since = r->since_sync;
            rt_predict(r, &r->buf[cur]);
            ta = rt_tip_of(r, &r->buf[cur]);
        }
        /* this step and the next m - 1 keep ++since below RT_RESYNC */
        int m = n - k < RT_RESYNC - since ? n - k : (int)(RT_RESYNC - since);
        int j = 0;
        rt_snap *a = &r->buf[cur], *const b0 = &r->buf[0], *const b1 = &r->buf[1];
        const rt_snap *b = a;
        afm_sample *o = out ? out + k : NULL;
        for (; j < m; j++) {
            rt_snap *bb = a == b0 ? b1 : b0;
            /* in contact at the start, or predicted to end there (the end's x with F held at
             * F0: a free step would be redone in substeps anyway) */
            const bool at_once =
                r->kinked && (ta.x_m < r->xc || fma(gx_full, ta.f_n, ta.x_free_m) < r->xc);
            bool contact = at_once;
            if (!contact) {
                const rt_piece_kind free_step = {
                    .np = np, .ntones = nt, .free_step = true, .thermal = noise, .predict = true};
                rt_piece_t(s, r, a, bb, r->ncell, free_step, &ta, &tb);
                if (r->kinked) {
                    double low = (ta.x_m < tb.x_m ? ta.x_m : tb.x_m) -
                                 r->clear_k * (fabs(ta.v_m_s) + fabs(tb.v_m_s));
                    contact = low < r->xc && rt_crossing_cell(r, a, bb, dt, false) >= 0;
                }
            }
            if (contact) {
                bb = rt_contact(s, r, a, bb, noise && !at_once);
                tb = rt_tip_of(r, bb);
            }
            a = bb;
            b = bb;
            ta = tb;
            stepd += 1.0;
            /* A tip excursion of a millimetre is no cantilever any more. */
            if (!(fabs(ta.x_m) < 1e-3)) {
                rc = AFM_SIM_EBLOWUP;
                j++;
                break;
            }
            if (o) {
                rt_v4 th4 = rt_splat(0.0);
                for (int i = 0; i < np; i += 4)
                    th4 = rt_fma4(RT_V4(r->rot + i), RT_V4(b->q + i), th4);
                double th = rt_hsum(th4), u = 0.0;
                th += rt_tones_im(r->th_re, r->th_im, b->z_re, b->z_im, nt);
                if (nt == RT_TONES_V4)
                    u = rt_hsum(RT_V4(r->amp_m) * RT_V4(b->z_im));
                else
                    for (int jt = 0; jt < nt; jt++)
                        u += r->amp_m[jt] * b->z_im[jt];
                o->t_s = t0 + stepd * dt;
                o->x_m = ta.x_m;
                o->v_m_s = ta.v_m_s;
                o->f_n = ta.f_n;
                o->theta_rad = th;
                o->base_m = u;
                o++;
            }
        }
        cur = a == b0 ? 0 : 1;
        if (rc == AFM_SIM_OK && !(fabs(b->tip.v_m_s) < HUGE_VAL && fabs(b->tip.f_n) < HUGE_VAL))
            rc = AFM_SIM_EBLOWUP;
        step += j;
        since += j - 1;
        k += j;
    }
    s->step = step;
    s->t_s = t0 + (double)step * dt;
    r->cur = cur;
    r->since_sync = since;
    rt_publish(s, r, &r->buf[r->cur]);
    return rc;
}

AFM_CLONES static int rt_run(afm_sim *s, int n, afm_sample *out) {
    rt_state *r = s->be_state;
    if (r->acc) {
        if (r->noise) return rt_run_acc_t(s, r, n, out, r->np, rt_tones_kind(r), true);
        if (r->ntones == 1 && r->np == 4) return rt_run_acc_t(s, r, n, out, 4, 1, false);
        if (r->ntones == 1 && r->np == 8) return rt_run_acc_t(s, r, n, out, 8, 1, false);
        if (r->ntones > 1 && r->np == 4) return rt_run_acc_t(s, r, n, out, 4, RT_TONES_V4, false);
        if (r->ntones > 1 && r->np == 8) return rt_run_acc_t(s, r, n, out, 8, RT_TONES_V4, false);
        return rt_run_acc_t(s, r, n, out, r->np, rt_tones_kind(r), false);
    }
    if (r->noise) return rt_run_t(s, r, n, out, r->np, rt_tones_kind(r), true);
    if (r->ntones == 1 && r->np == 4) return rt_run_t(s, r, n, out, 4, 1, false);
    if (r->ntones == 1 && r->np == 8) return rt_run_t(s, r, n, out, 8, 1, false);
    if (r->ntones > 1 && r->np == 4) return rt_run_t(s, r, n, out, 4, RT_TONES_V4, false);
    if (r->ntones > 1 && r->np == 8) return rt_run_t(s, r, n, out, 8, RT_TONES_V4, false);
    return rt_run_t(s, r, n, out, r->np, rt_tones_kind(r), false);
}

/* Make tab[acc] the tables in force (the fields of r that alias them, and the first
 * guess of a full step, which depends on them). */
static void rt_tables_use(rt_state *r, bool acc) {
    const rt_tables *t = &r->tab[acc];
    r->acc = acc;
    r->m = t->m;
    r->ncell = t->ncell;
    r->prop = t->prop;
    r->block = t->block;
    r->lth = t->lth;
    r->bridge = t->bridge;
    const afm_rt_prop *PF = &r->prop[r->ncell - 1];
    r->guess_x_per_n = PF->gx + PF->hx;
    r->guess_v_per_n = PF->gv + PF->hv;
    r->guess_gap_per_n = r->guess_x_per_n * r->cos_alpha;
}

/* Recompute the drive tables and reload the state from s->q, s->qd at s->t_s. */
static void rt_changed(afm_sim *s) {
    rt_state *r = s->be_state;
    const afm_modal *m = &s->m;
    double cx_re[AFM_MAX_TONES], cx_im[AFM_MAX_TONES];
    r->ntones = s->drive.n;
    for (int j = 0; j < AFM_MAX_TONES; j++) { /* zero past ntones (RT_TONES_V4) */
        r->wd[j] = cx_re[j] = cx_im[j] = r->th_re[j] = r->th_im[j] = r->amp_m[j] = 0.0;
    }
    for (int j = 0; j < r->ntones; j++) {
        r->amp_m[j] = s->drive.amp_m[j];
        r->wd[j] = s->drive.omega_rad_s[j];
        cx_re[j] = cx_im[j] = 0.0;
        r->th_re[j] = m->rot_base * s->drive.amp_m[j];
        r->th_im[j] = 0.0;
        for (int i = 0; i < m->n; i++) {
            /* q_p = Im(A H e^{i theta}) for the base tone A sin(theta) */
            double hr, hi;
            afm_model_mode_response(m, i, r->wd[j], &hr, &hi);
            r->cq_re[j][i] = s->drive.amp_m[j] * hr;
            r->cq_im[j][i] = s->drive.amp_m[j] * hi;
            cx_re[j] += m->tip[i] * r->cq_re[j][i];
            cx_im[j] += m->tip[i] * r->cq_im[j][i];
            r->th_re[j] += m->rot[i] * r->cq_re[j][i];
            r->th_im[j] += m->rot[i] * r->cq_im[j][i];
        }
    }
    for (int a = 0; a < 2; a++)
        for (int k = 0; k < r->tab[a].ncell; k++)
            afm_rt_coef_drive(&r->tab[a].prop[k], r->ntones, r->wd, cx_re, cx_im);
    for (int j = 0; j < AFM_MAX_TONES; j++) { /* x_p'' = -wd^2 x_p */
        r->ax_re[j] = -r->wd[j] * r->wd[j] * cx_re[j];
        r->ax_im[j] = -r->wd[j] * r->wd[j] * cx_im[j];
    }
    r->xc = afm_force_contact_x(&s->f, s->z_m);
    r->cos_alpha = s->f.cos_alpha;
    r->z_m = s->z_m;
    rt_tables_use(r, r->acc);
    afm_rt_starr_build(&r->starr, &s->f, s->z_m);
    rt_snap *st = &r->buf[r->cur];
    rt_sync_phasors(s, r, st);
    st->tip.x_m = st->tip.v_m_s = 0.0;
    for (int i = 0; i < r->n; i++) {
        double q = s->q[i], v = s->qd[i];
        for (int j = 0; j < r->ntones; j++) {
            double cr = r->cq_re[j][i], ci = r->cq_im[j][i];
            q -= cr * st->z_im[j] + ci * st->z_re[j];
            v -= r->wd[j] * (cr * st->z_re[j] - ci * st->z_im[j]);
        }
        st->q[i] = q;
        st->v[i] = v;
        st->tip.x_m += m->tip[i] * s->q[i];
        st->tip.v_m_s += m->tip[i] * s->qd[i];
    }
    st->tip.f_n = rt_force(s, r, st->tip.x_m, st->tip.v_m_s, &st->dfdx_n_m, &st->dfdv_n_s_m);
    st->slope_cells = 0;
    st->df_per_cell_n = 0.0;
    st->fdot_n_s = rt_fdot(r, st, r->np, rt_tones_kind(r));
    rt_predict(r, st);
    s->be_fills_tip = true;
    rt_publish(s, r, st);
}

/* afm_sim_set_thermal: the Cholesky factors of every step length's increment (both
 * schemes' tables), and the generator seeded. */
static int rt_thermal(afm_sim *s, const afm_cfg_thermal *t, char *err, size_t errlen) {
    rt_state *r = s->be_state;
    if (!t->enabled) {
        r->noise = false;
        return 0;
    }
    const size_t np = (size_t)r->np;
    if (!r->rng) {
        afm_rng *g = calloc(1, sizeof *g);
        rt_noise *z = calloc(1, sizeof *z);
        if (!g || !z) {
            free(g);
            free(z);
            snprintf(err, errlen, "rt integrator: out of memory");
            return -1;
        }
        r->rng = g;
        r->nz = z;
    }
    for (int a = 0; a < 2; a++) {
        rt_tables *tb = &r->tab[a];
        const size_t n_bridge = (size_t)(RT_GRID - 1 + tb->m - 1);
        if (!tb->lth) {
            tb->lth = calloc(3 * np * (size_t)tb->ncell, sizeof *tb->lth);
            tb->bridge = calloc(4 * np * n_bridge, sizeof *tb->bridge);
            if (!tb->lth || !tb->bridge) {
                snprintf(err, errlen, "rt integrator: out of memory");
                return -1; /* what was allocated is freed by rt_destroy */
            }
        }
    }
    const bool acc = r->acc;
    const double kt = RT_KB_J_K * t->temperature_k;
    for (int a = 0; a < 2; a++) {
        rt_tables_use(r, a);
        const size_t n_bridge = (size_t)(RT_GRID - 1 + r->m - 1);
        for (int k = 0; k < r->ncell; k++) {
            double *l = r->lth + 3 * np * (size_t)k;
            afm_rt_coef_thermal(&r->prop[k], r->n, r->np, s->m.omega_rad_s, s->m.xi, kt, l, l + np,
                                l + 2 * np);
        }
        /* the bridges: (kc, RT_GRID) for a crossing, (RT_GRID, j RT_GRID) for a substep */
        for (size_t b = 0; b < n_bridge; b++) {
            int k1 = b < RT_GRID - 1 ? (int)b + 1 : RT_GRID;
            int len = b < RT_GRID - 1 ? RT_GRID : (int)(b - (RT_GRID - 1) + 2) * RT_GRID;
            const double *l = r->lth;
            afm_rt_coef_bridge(r->n, r->np, r->prop[k1 - 1].tau_s, l + 3 * np * (size_t)(k1 - 1),
                               l + 3 * np * (size_t)(len - 1), r->prop[len - k1 - 1].c,
                               (double *)rt_bridge_gain(r, k1, len));
        }
    }
    rt_tables_use(r, acc);
    memset(r->nz, 0, sizeof *r->nz);
    afm_rng_seed(r->rng, (uint64_t)t->seed);
    r->noise = true;
    return 0;
}

/* afm_sim_set_scheme: hand the state over to the other scheme at this sample. Both share
 * the modal state, the phasors and the force; what each keeps of its own (the fast one's
 * predictor, the accurate one's dF/dt) is recomputed here. No allocation. */
static void rt_set_scheme(afm_sim *s, bool accurate) {
    rt_state *r = s->be_state;
    if (r->acc == accurate) return;
    rt_tables_use(r, accurate);
    rt_snap *st = &r->buf[r->cur];
    st->slope_cells = 0;
    st->fdot_n_s = rt_fdot(r, st, r->np, rt_tones_kind(r));
    rt_predict(r, st);
}

/* The scheme in force: "accurate" or "fast". */
static const char *rt_scheme_name(const afm_sim *s) {
    const rt_state *r = s->be_state;
    return r && r->acc ? "accurate" : "fast";
}

static void rt_destroy(afm_sim *s) {
    rt_state *r = s->be_state;
    if (!r) return;
    for (int a = 0; a < 2; a++) {
        free(r->tab[a].block);
        free(r->tab[a].prop);
        free(r->tab[a].lth);
        free(r->tab[a].bridge);
    }
    free(r->rng);
    free(r->nz);
    free(r);
    s->be_state = NULL;
}

static int rt_init(afm_sim *s, char *err, size_t errlen) {
    const afm_modal *m = &s->m;
    const bool acc = s->cfg.rt_scheme != AFM_RT_SCHEME_FAST;
    /* substeps in contact: the config's for both schemes, else each scheme's default */
    int sub = s->cfg.rt_substeps_contact;
    if (sub < 0 || sub > RT_MAX_SUBSTEPS) {
        snprintf(err, errlen, "rt integrator: rt_substeps_contact %d not in 1..%d", sub,
                 RT_MAX_SUBSTEPS);
        return -1;
    }
    if (!(s->dt_s > 0) || !isfinite(s->dt_s)) {
        snprintf(err, errlen, "rt integrator: bad output step %g s", s->dt_s);
        return -1;
    }
    for (int i = 0; i < m->n; i++) {
        if (!(m->omega_rad_s[i] > 0) || !isfinite(m->omega_rad_s[i]) || !(m->xi[i] >= 0) ||
            !isfinite(m->xi[i]) || !isfinite(m->tip[i]) || !isfinite(m->base_k[i]) ||
            !isfinite(m->base_m[i])) {
            snprintf(err, errlen, "rt integrator: mode %d has a bad frequency, damping or coupling",
                     i + 1);
            return -1;
        }
    }
    rt_state *r = calloc(1, sizeof *r);
    if (!r) {
        snprintf(err, errlen, "rt integrator: out of memory");
        return -1;
    }
    r->n = m->n;
    r->np = (m->n + 3) & ~3;
    for (int i = 0; i < r->n; i++) {
        r->tip[i] = m->tip[i];
        r->rot[i] = m->rot[i];
        r->aq[i] = -m->tip[i] * m->omega_rad_s[i] * m->omega_rad_s[i];
        r->av[i] = -2.0 * m->tip[i] * m->xi[i] * m->omega_rad_s[i];
        r->tip2 += m->tip[i] * m->tip[i];
    }
    for (int k = 1; k <= RT_MAX_SUBSTEPS * RT_GRID; k++)
        r->inv_cells[k] = 1.0 / k;
    const size_t per = (size_t)AFM_RT_COEF_ROWS * (size_t)r->np;
    _Static_assert(AFM_MAX_MODES % 4 == 0, "rt_piece works in blocks of 4 modes");
    for (int a = 0; a < 2; a++) {
        rt_tables *t = &r->tab[a];
        t->m = sub > 0 ? sub : a ? RT_ACC_DEFAULT_SUBSTEPS : RT_DEFAULT_SUBSTEPS;
        t->ncell = t->m * RT_GRID;
        t->prop = calloc((size_t)t->ncell, sizeof *t->prop);
        t->block = calloc((size_t)t->ncell * per, sizeof(double));
        if (!t->prop || !t->block) {
            s->be_state = r;
            rt_destroy(s);
            snprintf(err, errlen, "rt integrator: out of memory");
            return -1;
        }
        for (int k = 0; k < t->ncell; k++) {
            afm_rt_prop *P = &t->prop[k];
            P->c = t->block + (size_t)k * per;
            afm_rt_coef_modes(P, r->n, r->np, m->omega_rad_s, m->xi, m->tip,
                              s->dt_s * (double)(k + 1) / (double)t->ncell);
            if (a) afm_rt_coef_hermite(P, r->n, r->np, m->omega_rad_s, m->xi, m->tip);
        }
        for (int k = 0; k < t->ncell; k++)
            afm_rt_coef_chain(&t->prop[k], &t->prop[t->ncell - 1], r->np);
    }
    r->cos_alpha = s->f.cos_alpha;
    rt_tables_use(r, acc);
    r->kinked = s->f.vdw_contact || s->f.capillary || s->f.electrostatic;
    r->clear_k = 4.0 / 27.0 * s->dt_s;
    /* F tolerance on the estimated next Newton correction: 1e-3 of the force that bends the
     * cantilever by 1 nm (1 pm of deflection). Measured (tests/test_rt_accuracy.c): error_rel
     * against CVODE is the same as with 1e-5 on all four models, while contact pieces take
     * 1.33 force evaluations on average instead of 1.95 (nchv.conf, docs/numerics.md). */
    double k_st = m->static_stiffness_n_m > 0 ? m->static_stiffness_n_m : 1.0;
    r->ftol = 1e-3 * k_st * 1e-9;
    s->be_state = r;
    rt_changed(s);
    return 0;
}

/* Only Z changed (afm_sim_set_separation; a ramp calls it every 64 samples): the contact
 * line, the force and the next step's guess at the current state, and the Starr interpolant
 * only when the rest gap left AFM_RT_STARR_KEEP of its window. The drive tables, the
 * phasors and the homogeneous state are untouched (rt_changed recomputes all of them). */
static void rt_changed_z(afm_sim *s) {
    rt_state *r = s->be_state;
    r->xc = afm_force_contact_x(&s->f, s->z_m);
    r->z_m = s->z_m;
    if (s->f.squeeze == AFM_SQUEEZE_STARR &&
        !(r->starr.on && fabs(afm_force_starr_h(&s->f, s->z_m, 0.0) - r->starr.h0) <=
                             AFM_RT_STARR_KEEP * r->starr.hw))
        afm_rt_starr_build(&r->starr, &s->f, s->z_m);
    rt_snap *st = &r->buf[r->cur];
    st->tip.f_n = rt_force(s, r, st->tip.x_m, st->tip.v_m_s, &st->dfdx_n_m, &st->dfdv_n_s_m);
    st->slope_cells = 0;
    st->df_per_cell_n = 0.0;
    st->fdot_n_s = rt_fdot(r, st, r->np, rt_tones_kind(r));
    rt_predict(r, st);
    s->f_last_n = st->tip.f_n;
}

const afm_sim_backend AFM_RT_BACKEND = {
    .name = "rt",
    .scheme = rt_scheme_name,
    .set_scheme = rt_set_scheme,
    .init = rt_init,
    .run = rt_run,
    .changed = rt_changed,
    .changed_z = rt_changed_z,
    .thermal = rt_thermal,
    .destroy = rt_destroy,
};
