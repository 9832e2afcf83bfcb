/* SPDX-License-Identifier: MIT */
/* afm_rt_force.h -- the tip force at (x, v) with its partials, and the implicit solve of a piece's
 * end force F1 = f(x* + gx F1, v* + gv F1): safeguarded chord/Newton (rt_solve_in), and the
 * linearly implicit step out of contact (rt_solve_fast). Shared by both schemes.
 * Private to the rt backend: included once, by afm_rt.c (which is compiled once per CPU copy,
 * AFM_RT_COPY), so its static functions stay in that one translation unit. */
#ifndef AFM_RT_FORCE_H
#define AFM_RT_FORCE_H

#include "integrators/afm_rt_impl.h"
#include "forces/afm_force_inline.h"

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
static inline __attribute__((always_inline)) double
rt_force_in(const afm_sim *s, const rt_state *r, double x, double v, double *fx, double *fv) {
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

/* rt_force_in out of line (the fast scheme's contact pieces, a state's first force). */
AFM_CLONES static inline double rt_force(const afm_sim *s, const rt_state *r, double x, double v,
                                         double *fx, double *fv) {
    return rt_force_in(s, r, x, v, fx, fv);
}

/* ---- one implicit piece ---- */

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

/* rt_force with the evaluation out of contact (most of them) inlined: the same values (there
 * afm_force_near_terms is afm_force_out_terms), the contact branch a call, or with inl
 * inlined too (the accurate scheme's pieces, issue 29, sixth round). */
static inline __attribute__((always_inline)) double rt_force_at(const afm_sim *s, const rt_state *r,
                                                                double x, double v, double *fx,
                                                                double *fv, const bool inl) {
    const double d = fma(x, s->f.cos_alpha, s->z_m);
    if (__builtin_expect(d >= s->f.a0_m, 1)) return rt_force_out(s, r, x, v, d, fx, fv);
    return inl ? rt_force_in(s, r, x, v, fx, fv) : rt_force(s, r, x, v, fx, fv);
}

/* Solve F = f(xs + gx F, vs + gv F) from the guess F. Each iteration corrects with the
 * newest reciprocal slope rj = 1 / g'(F) known before it (a chord step: out of contact g'
 * is 1 to 1e-5, so this is Newton there), which keeps the division off the critical path;
 * a bracket turns a step that leaves it into bisection. Leaves f's partials and rj in o. */
static inline __attribute__((always_inline)) double
rt_solve_in_t(const afm_sim *s, const rt_state *r, double xs, double vs, double gx, double gv,
              double F, double rj, rt_snap *o, const bool inl) {
    double fx, fv;
    double f = rt_force_at(s, r, fma(gx, F, xs), fma(gv, F, vs), &fx, &fv, inl);
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
            f = rt_force_at(s, r, fma(gx, F, xs), fma(gv, F, vs), &fx, &fv, inl);
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

/* rt_solve_in_t with the contact force a call. */
static inline __attribute__((always_inline)) double rt_solve_in(const afm_sim *s, const rt_state *r,
                                                                double xs, double vs, double gx,
                                                                double gv, double F, double rj,
                                                                rt_snap *o) {
    return rt_solve_in_t(s, r, xs, vs, gx, gv, F, rj, o, false);
}

/* rt_solve_in out of line: the rare fallback of the free step (rt_solve_fast). The
 * contact pieces inline rt_solve_in. */
static AFM_CLONES_NOINLINE double rt_solve(const afm_sim *s, const rt_state *r, double xs,
                                           double vs, double gx, double gv, double F, double rj,
                                           rt_snap *o) {
    return rt_solve_in(s, r, xs, vs, gx, gv, F, rj, o);
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

#endif
