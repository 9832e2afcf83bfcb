/* SPDX-License-Identifier: MIT */
/* afm_rt_acc.h -- the accurate scheme: the tip force cubic Hermite in time (issue 28,
 * docs/numerics.md), its contact samples and its sample loop (rt_run_acc_t).
 * Private to the rt backend: included once, by afm_rt.c (which is compiled once per CPU copy,
 * AFM_RT_COPY), so its static functions stay in that one translation unit. */
#ifndef AFM_RT_ACC_H
#define AFM_RT_ACC_H

#include "integrators/afm_rt_cross.h"
#include "integrators/afm_rt_evrec.h"
#include "integrators/afm_rt_force.h"
#include "integrators/afm_rt_noise.h"

/* ---- the accurate scheme: the force cubic Hermite in time (cfg.rt_scheme) ----
 *
 * Each piece takes the force as the Hermite interpolant of F0, F1 and the slopes D0, D1
 * (afm_rt_coef.h), fourth order in the step where the force is smooth. D = tau dF/dt with
 * dF/dt = f_x v + f_v a from the force law's partials at the last evaluation and the tip's
 * velocity and acceleration. The solve takes D1 = D0 (the force's slope carried over);
 * then D1 is computed at the end and the state takes Gd1 (D1 - D0). A sample runs as one
 * such piece while its path stays clear of the contact line (as the fast scheme's free
 * step); a sample that comes near it is redone in RT_ACC_NEAR_PIECES whole pieces, and
 * those at the contact line in their share of the m substeps (rt_graded_acc; with thermal
 * noise, the whole sample in the m substeps: rt_contact_acc), each first taken whole; a
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

/* A graded piece's end into o (its tip x1, v1, force F1 and dF/dt fdot; the force from F0
 * at its start, over k cells): what a following piece or step reads. Both forms of a graded
 * piece end with it (rt_piece_acc_t here, the tip-channel node in afm_rt_tc.h). */
static inline __attribute__((always_inline)) void rt_piece_end(const rt_state *r, rt_snap *o, int k,
                                                               double F0, double F1, double x1,
                                                               double v1, double fdot) {
    o->slope_cells = 0;
    o->acc_free = false;
    o->df_per_cell_n = (F1 - F0) * r->inv_cells[k];
    o->tip.x_m = x1;
    o->tip.v_m_s = v1;
    o->tip.f_n = F1;
    o->fdot_n_s = fdot;
}

/* Advance in by k cells into o (o may be in); herm: the force Hermite in time, else linear
 * (a piece beside a crossing). Leaves o->fdot_n_s for the next piece, and with rec (a step
 * record is kept: afm_rt_evrec.h) o->acc_m_s2, from the sums the piece forms anyway. */
static inline __attribute__((always_inline)) void
rt_piece_acc_t(const afm_sim *s, const rt_state *r, const rt_snap *in, rt_snap *o, int k, bool herm,
               const int np, const int nt, const bool noise, const bool rec) {
    const afm_rt_prop *P = &r->prop[k - 1];
    const double *c = P->c;
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
    double gxe = herm ? P->hx1 : P->gx, gve = herm ? P->hv1 : P->gv;
    if (herm) { /* F0 (1 + c) + D0 (h10 + h11), and F1 (sigma - c) */
        xs = fma(P->hx0, F0, fma(P->hd0x, D0, xs));
        vs = fma(P->hv0, F0, fma(P->hd0v, D0, vs));
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
    double zr1[AFM_MAX_TONES], zi1[AFM_MAX_TONES];
    rt_tones_rotate(in->z_re, in->z_im, P->rot_re, P->rot_im, zr1, zi1, nt);
    const double tones_a = rt_tones_im(r->ax_re, r->ax_im, zr1, zi1, nt);
    double x1, v1, F1, fdot;
    if (herm) {
        /* the modal update's part that does not wait for F1, D1 (Phi q + K0 F0 + Gd0 D0) and
         * its acceleration, formed beside the solve; then the state written once with
         * K1 F1 + Gd1 D1 (rt_free_acc_t's arrangement; P->acc_k1, P->acc_gd1) */
        const double *k0 = c + AFM_RT_ROW_K0 * np, *k1 = c + AFM_RT_ROW_K1 * np;
        const double *gd0 = c + (AFM_RT_ROW_GC + 2) * np, *gd1 = c + (AFM_RT_ROW_GC + 4) * np;
        const rt_v4 f0 = rt_splat(F0), d0 = rt_splat(D0);
        rt_v4 pq[AFM_MAX_MODES / 4], pv[AFM_MAX_MODES / 4], a4 = rt_splat(0.0);
        for (int i = 0; i < np; i += 4) {
            rt_v4 q = RT_V4(in->q + i), v = RT_V4(in->v + i);
            rt_v4 a = rt_fma4(
                RT_V4(c + i), q,
                rt_fma4(RT_V4(c + np + i), v, rt_fma4(RT_V4(k0 + i), f0, RT_V4(gd0 + i) * d0)));
            rt_v4 w = rt_fma4(RT_V4(c + 2 * np + i), q,
                              rt_fma4(RT_V4(c + 3 * np + i), v,
                                      rt_fma4(RT_V4(k0 + np + i), f0, RT_V4(gd0 + np + i) * d0)));
            if (noise) {
                a += RT_V4(nq + i);
                w += RT_V4(nv + i);
            }
            a4 = rt_fma4(RT_V4(r->aq + i), a, rt_fma4(RT_V4(r->av + i), w, a4));
            pq[i / 4] = a;
            pv[i / 4] = w;
        }
        const double aa = fma(P->acc_gd1, D0, rt_hsum(a4) + tones_a);
        F1 = rt_solve_in_t(s, r, xs, vs, gxe, gve, fma(in->df_per_cell_n, (double)k, F0), rj, o,
                           true);
        x1 = fma(gxe, F1, xs);
        v1 = fma(gve, F1, vs);
        const double acc = fma(P->acc_k1, F1, aa); /* D1 held at D0, as the solve */
        fdot = fma(o->dfdx_n_m, v1, o->dfdv_n_s_m * acc);
        const double D1 = tau * fdot, dd = fma(tau, fdot, -D0);
        x1 = fma(P->gd1x, dd, x1);
        v1 = fma(P->gd1v, dd, v1);
        const rt_v4 f1 = rt_splat(F1), d1 = rt_splat(D1);
        for (int i = 0; i < np; i += 4) {
            RT_V4W(o->q + i) = rt_fma4(RT_V4(k1 + i), f1, rt_fma4(RT_V4(gd1 + i), d1, pq[i / 4]));
            RT_V4W(o->v + i) =
                rt_fma4(RT_V4(k1 + np + i), f1, rt_fma4(RT_V4(gd1 + np + i), d1, pv[i / 4]));
        }
        if (rec) o->acc_m_s2 = fma(P->acc_gd1, dd, acc); /* the state's own */
    } else {
        F1 = rt_solve_in_t(s, r, xs, vs, gxe, gve, fma(in->df_per_cell_n, (double)k, F0), rj, o,
                           true);
        const rt_v4 f0 = rt_splat(F0), f1 = rt_splat(F1);
        rt_v4 a4 = rt_splat(0.0);
        for (int i = 0; i < np; i += 4) {
            rt_v4 q = RT_V4(in->q + i), v = RT_V4(in->v + i);
            rt_v4 a =
                rt_fma4(RT_V4(c + i), q,
                        rt_fma4(RT_V4(c + np + i), v,
                                rt_fma4(RT_V4(c + 4 * np + i), f0, RT_V4(c + 6 * np + i) * f1)));
            rt_v4 w =
                rt_fma4(RT_V4(c + 2 * np + i), q,
                        rt_fma4(RT_V4(c + 3 * np + i), v,
                                rt_fma4(RT_V4(c + 5 * np + i), f0, RT_V4(c + 7 * np + i) * f1)));
            if (noise) {
                a += RT_V4(nq + i);
                w += RT_V4(nv + i);
            }
            RT_V4W(o->q + i) = a;
            RT_V4W(o->v + i) = w;
            a4 = rt_fma4(RT_V4(r->aq + i), a, rt_fma4(RT_V4(r->av + i), w, a4));
        }
        x1 = fma(gxe, F1, xs);
        v1 = fma(gve, F1, vs);
        const double acc = rt_hsum(a4) + r->tip2 * F1 + tones_a;
        fdot = fma(o->dfdx_n_m, v1, o->dfdv_n_s_m * acc);
        if (rec) o->acc_m_s2 = acc; /* the state is final */
    }
    rt_tones_store(o->z_re, o->z_im, zr1, zi1, nt);
    rt_piece_end(r, o, k, F0, F1, x1, v1, fdot);
}

/* rt_piece_acc_t out of line for the contact pieces, the sizes picked once. */
static AFM_CLONES_NOINLINE void rt_piece_acc_n(const afm_sim *s, const rt_state *r,
                                               const rt_snap *in, rt_snap *o, int k, bool herm) {
    if (r->noise)
        rt_piece_acc_t(s, r, in, o, k, herm, r->np, rt_tones_kind(r), true, false);
    else if (r->ntones == 1 && r->np == 4)
        rt_piece_acc_t(s, r, in, o, k, herm, 4, 1, false, false);
    else if (r->ntones == 1 && r->np == 8)
        rt_piece_acc_t(s, r, in, o, k, herm, 8, 1, false, false);
    else if (r->ntones > 1 && r->np == 4)
        rt_piece_acc_t(s, r, in, o, k, herm, 4, RT_TONES_V4, false, false);
    else if (r->ntones > 1 && r->np == 8)
        rt_piece_acc_t(s, r, in, o, k, herm, 8, RT_TONES_V4, false, false);
    else
        rt_piece_acc_t(s, r, in, o, k, herm, r->np, rt_tones_kind(r), false, false);
}

/* The same for a step whose record is kept (rec; without noise): its own copy, so that the
 * loop without a record is the scheme's code alone. */
static AFM_CLONES_NOINLINE void rt_piece_acc_rec(const afm_sim *s, const rt_state *r,
                                                 const rt_snap *in, rt_snap *o, int k, bool herm) {
    if (r->ntones == 1 && r->np == 4)
        rt_piece_acc_t(s, r, in, o, k, herm, 4, 1, false, true);
    else if (r->ntones == 1 && r->np == 8)
        rt_piece_acc_t(s, r, in, o, k, herm, 8, 1, false, true);
    else
        rt_piece_acc_t(s, r, in, o, k, herm, r->np, rt_tones_kind(r), false, true);
}

/* rt_piece_acc_n, or rt_piece_acc_rec when rec. */
static inline void rt_piece_acc(const afm_sim *s, const rt_state *r, const rt_snap *in, rt_snap *o,
                                int k, bool herm, bool rec) {
    if (rec)
        rt_piece_acc_rec(s, r, in, o, k, herm);
    else
        rt_piece_acc_n(s, r, in, o, k, herm);
}

/* ---- the free step (issue 29, fourth round) ----
 *
 * A sample clear of the contact line is one full Hermite step, rt_piece_acc_t's arithmetic
 * rearranged as the fast scheme's free step is (rt_piece_t): the tip values the next step
 * starts from are carried in registers from sample to sample (rt_acc_tip), and the next
 * step's x*, v* are chained from this one's end force F1 and end slope D1 = tau dF/dt: the part
 * of the modal update that does not wait for them (Phi q + (G0 + Gc) F0 + Gd0 D0) is formed
 * beside the force solve, together with its tip rows and its acceleration, and what waits is
 * per model (rt_state.fa_*: the K1 and Gd1 rows seen through the full step's tip rows and the
 * acceleration). So the chain from one force to the next is the force, the chord update,
 * dF/dt and a few multiply-adds, and the modal state is written once. The same scheme as
 * rt_piece_acc_t's full Hermite step up to rounding. */

/* The tip after a free step and what the next full step needs of it. */
typedef struct {
    double x_m, v_m_s, f_n;      /* tip displacement (m), velocity (m/s), force (N) */
    double fdot_n_s;             /* dF/dt (N/s) */
    double fx, fv;               /* df/dx (N/m), df/dv (N s/m) at the last force evaluation */
    double df_per_cell_n;        /* force change per cell over the last piece (N): the guess */
    double inv_slope;            /* 1 / max(1 - fx hx1 - fv hv1, 1/4) of the full step */
    double x_free_m, v_free_m_s; /* the full step's x*, v* (F0, D0 terms and tones in) */
} rt_acc_tip;

/* rt_acc_tip of st for a following full step: its carried x*, v* (acc_free), else from its
 * modal state as rt_piece_acc_t forms them. */
static inline __attribute__((always_inline)) rt_acc_tip
rt_acc_tip_of(const rt_state *r, const rt_snap *st, const int np, const int nt) {
    const afm_rt_prop *P = &r->prop[r->ncell - 1];
    rt_acc_tip t = {.x_m = st->tip.x_m,
                    .v_m_s = st->tip.v_m_s,
                    .f_n = st->tip.f_n,
                    .fdot_n_s = st->fdot_n_s,
                    .fx = st->dfdx_n_m,
                    .fv = st->dfdv_n_s_m,
                    .df_per_cell_n = st->df_per_cell_n};
    double jj = 1.0 - st->dfdx_n_m * P->hx1 - st->dfdv_n_s_m * P->hv1;
    t.inv_slope = 1.0 / (jj > 0.25 ? jj : 0.25);
    if (st->acc_free) {
        t.x_free_m = st->tip.x_free_m;
        t.v_free_m_s = st->tip.v_free_m_s;
        return t;
    }
    const double *c = P->c, F0 = st->tip.f_n, D0 = P->tau_s * st->fdot_n_s;
    double xs, vs;
    rt_v4 xs4 = rt_splat(0.0), vs4 = rt_splat(0.0);
    for (int i = 0; i < np; i += 4) {
        rt_v4 q = RT_V4(st->q + i), v = RT_V4(st->v + i);
        xs4 = rt_fma4(RT_V4(c + 8 * np + i), q, rt_fma4(RT_V4(c + 9 * np + i), v, xs4));
        vs4 = rt_fma4(RT_V4(c + 10 * np + i), q, rt_fma4(RT_V4(c + 11 * np + i), v, vs4));
    }
    rt_hsum2(xs4, vs4, &xs, &vs);
    xs = fma(P->hx0, F0, fma(P->hd0x, D0, xs));
    vs = fma(P->hv0, F0, fma(P->hd0v, D0, vs));
    t.x_free_m = xs + rt_tones_im(P->dx_re, P->dx_im, st->z_re, st->z_im, nt);
    t.v_free_m_s = vs + rt_tones_im(P->dv_re, P->dv_im, st->z_re, st->z_im, nt);
    return t;
}

/* rt_solve_fast with the force's partials and the reciprocal slope also left in *fx, *fv, *rj
 * (the free step reads them at once: no reload after the stores into o). */
static inline __attribute__((always_inline)) double
rt_solve_fast_reg(const afm_sim *s, const rt_state *r, double xs, double vs, double gx, double gv,
                  double F, double rj0, double x, double v, double d, rt_snap *o, double *fx,
                  double *fv, double *rj) {
    const afm_force_params *p = &s->f;
    if (__builtin_expect(d >= p->a0_m, 1)) {
        double f = rt_force_out(s, r, x, v, d, fx, fv);
        double fn = fma(f - F, rj0, F);
        double jac = 1.0 - *fx * gx - *fv * gv;
        jac = jac > 0.25 ? jac : 0.25;
        double est = fabs(fn - F) * fabs(1.0 - jac * rj0);
        if (__builtin_expect(!(est > r->ftol), 1)) {
            *rj = 1.0 / jac;
            o->dfdx_n_m = *fx;
            o->dfdv_n_s_m = *fv;
            o->tip.inv_slope = *rj;
            return fn;
        }
    }
    const double F1 = rt_solve(s, r, xs, vs, gx, gv, F, rj0, o);
    *fx = o->dfdx_n_m;
    *fv = o->dfdv_n_s_m;
    *rj = o->tip.inv_slope;
    return F1;
}

/* One free step from in (its tip *ti) into o (and *to); rec: o->acc_m_s2 for the step record. */
static inline __attribute__((always_inline)) void
rt_free_acc_t(const afm_sim *s, const rt_state *r, const rt_snap *in, rt_snap *o, const int np,
              const int nt, const bool rec, const rt_acc_tip *ti, rt_acc_tip *to) {
    const afm_rt_prop *P = &r->prop[r->ncell - 1];
    const double *c = P->c, *k0 = c + AFM_RT_ROW_K0 * np, *k1 = c + AFM_RT_ROW_K1 * np;
    const double *gd0 = c + (AFM_RT_ROW_GC + 2) * np, *gd1 = c + (AFM_RT_ROW_GC + 4) * np;
    const double F0 = ti->f_n, tau = P->tau_s, D0 = tau * ti->fdot_n_s;
    const double xs = ti->x_free_m, vs = ti->v_free_m_s, gx = P->hx1, gv = P->hv1;
    /* the force first (the critical path), from the guess extrapolated along the last piece */
    const double Fg = fma(ti->df_per_cell_n, (double)r->ncell, F0);
    const double xg = fma(gx, Fg, xs);
    double fx, fv, rj;
    const double F1 = rt_solve_fast_reg(s, r, xs, vs, gx, gv, Fg, ti->inv_slope, xg,
                                        fma(gv, Fg, vs), rt_gap(r, xg), o, &fx, &fv, &rj);
    /* the modal update's part that does not wait for F1, D1, its tip rows and acceleration */
    double zr1[AFM_MAX_TONES], zi1[AFM_MAX_TONES];
    rt_tones_rotate(in->z_re, in->z_im, P->rot_re, P->rot_im, zr1, zi1, nt);
    const rt_v4 f0 = rt_splat(F0), d0 = rt_splat(D0);
    rt_v4 pq[AFM_MAX_MODES / 4], pv[AFM_MAX_MODES / 4];
    rt_v4 xn4 = rt_splat(0.0), vn4 = rt_splat(0.0), a4 = rt_splat(0.0);
    for (int i = 0; i < np; i += 4) {
        rt_v4 q = RT_V4(in->q + i), v = RT_V4(in->v + i);
        rt_v4 a =
            rt_fma4(RT_V4(c + i), q,
                    rt_fma4(RT_V4(c + np + i), v, rt_fma4(RT_V4(k0 + i), f0, RT_V4(gd0 + i) * d0)));
        rt_v4 w = rt_fma4(RT_V4(c + 2 * np + i), q,
                          rt_fma4(RT_V4(c + 3 * np + i), v,
                                  rt_fma4(RT_V4(k0 + np + i), f0, RT_V4(gd0 + np + i) * d0)));
        xn4 = rt_fma4(RT_V4(c + 8 * np + i), a, rt_fma4(RT_V4(c + 9 * np + i), w, xn4));
        vn4 = rt_fma4(RT_V4(c + 10 * np + i), a, rt_fma4(RT_V4(c + 11 * np + i), w, vn4));
        a4 = rt_fma4(RT_V4(r->aq + i), a, rt_fma4(RT_V4(r->av + i), w, a4));
        pq[i / 4] = a;
        pv[i / 4] = w;
    }
    double xh, vh;
    rt_hsum2(xn4, vn4, &xh, &vh);
    const double xr = xh + rt_tones_im(P->dx_re, P->dx_im, zr1, zi1, nt);
    const double vr = vh + rt_tones_im(P->dv_re, P->dv_im, zr1, zi1, nt);
    const double aa =
        fma(r->fa_ad, D0, rt_hsum(a4) + rt_tones_im(r->ax_re, r->ax_im, zr1, zi1, nt));
    /* the end: the tip, dF/dt there (D1 held at D0 in the acceleration, as rt_piece_acc_t),
     * the state with Gd1 D1 */
    double x1 = fma(gx, F1, xs), v1 = fma(gv, F1, vs);
    const double acc = fma(r->fa_af, F1, aa);
    const double fdot = fma(fx, v1, fv * acc);
    const double D1 = tau * fdot, dd = fma(tau, fdot, -D0);
    x1 = fma(P->gd1x, dd, x1);
    v1 = fma(P->gd1v, dd, v1);
    const rt_v4 f1 = rt_splat(F1), d1 = rt_splat(D1);
    for (int i = 0; i < np; i += 4) {
        RT_V4W(o->q + i) = rt_fma4(RT_V4(k1 + i), f1, rt_fma4(RT_V4(gd1 + i), d1, pq[i / 4]));
        RT_V4W(o->v + i) =
            rt_fma4(RT_V4(k1 + np + i), f1, rt_fma4(RT_V4(gd1 + np + i), d1, pv[i / 4]));
    }
    rt_tones_store(o->z_re, o->z_im, zr1, zi1, nt);
    const rt_acc_tip t = {.x_m = x1,
                          .v_m_s = v1,
                          .f_n = F1,
                          .fdot_n_s = fdot,
                          .fx = fx,
                          .fv = fv,
                          .df_per_cell_n = (F1 - F0) * r->inv_cells[r->ncell],
                          .inv_slope = rj,
                          .x_free_m = fma(r->fa_xd, D1, fma(r->fa_xf, F1, xr)),
                          .v_free_m_s = fma(r->fa_vd, D1, fma(r->fa_vf, F1, vr))};
    if (rec) o->acc_m_s2 = fma(r->fa_ad, dd, acc); /* the state's own, Gd1 (D1 - D0) in */
    o->slope_cells = 0;
    o->df_per_cell_n = t.df_per_cell_n;
    o->tip.x_m = x1;
    o->tip.v_m_s = v1;
    o->tip.f_n = F1;
    o->tip.x_free_m = t.x_free_m;
    o->tip.v_free_m_s = t.v_free_m_s;
    o->acc_free = true;
    o->fdot_n_s = fdot;
    *to = t;
}

/* One contact substep of RT_GRID cells from a into b: Hermite, or, where its path crosses
 * the contact line, linear and split at the crossing (rt_contact_t's thermal bookkeeping).
 * ea (NULL: none) gathers the pieces kept, the substep being the j0-th of the sample. */
static void rt_substep_acc(const afm_sim *s, const rt_state *r, const rt_snap *a, rt_snap *b,
                           double tau, rt_evacc *ea, int j0) {
    rt_piece_acc(s, r, a, b, RT_GRID, true, ea);
    int kc = rt_crossing_cell(r, a, b, tau, true);
    const double f0 = ea ? (double)j0 / r->m : 0.0;
    if (kc < 0) {
        if (ea) rt_ev_herm(ea, s, r, b, f0 + 1.0 / r->m);
        return;
    }
    /* the last kept end (a) for the linear pieces' records */
    rt_ev_end e0 = ea ? rt_ev_end_at(s, r, a) : (rt_ev_end){0};
    rt_noise *z = r->nz;
    if (kc == 0 || kc >= RT_GRID) { /* at an end: the whole substep linear */
        if (r->noise) {
            memcpy(z->gq, z->lq, sizeof z->gq);
            memcpy(z->gv, z->lv, sizeof z->gv);
            z->given_cells = RT_GRID;
        }
        rt_piece_acc(s, r, a, b, RT_GRID, false, ea);
        if (ea) rt_ev_lin(ea, s, r, &e0, b, f0 + 1.0 / r->m, NULL);
        return;
    }
    if (r->noise) {
        memcpy(z->sq, z->lq, sizeof z->sq);
        memcpy(z->sv, z->lv, sizeof z->sv);
        rt_bridge_draw(r, kc, RT_GRID, z->sq, z->sv);
    }
    rt_piece_acc(s, r, a, b, kc, false, ea);
    if (ea) rt_ev_lin(ea, s, r, &e0, b, f0 + (double)kc / (double)r->ncell, &e0);
    if (r->noise) {
        memcpy(z->gq, z->sq, sizeof z->gq);
        memcpy(z->gv, z->sv, sizeof z->gv);
        z->given_cells = RT_GRID - kc;
    }
    rt_piece_acc(s, r, b, b, RT_GRID - kc, false, ea);
    if (ea) rt_ev_lin(ea, s, r, &e0, b, f0 + 1.0 / r->m, NULL);
}

/* rt_substep_acc without noise, its pieces inlined with the sizes as constants (rec: ea set). */
static inline __attribute__((always_inline)) void
rt_substep_acc_t(const afm_sim *s, const rt_state *r, const rt_snap *a, rt_snap *b, double tau,
                 rt_evacc *ea, int j0, const int np, const int nt, const bool rec) {
    rt_piece_acc_t(s, r, a, b, RT_GRID, true, np, nt, false, rec);
    int kc = rt_crossing_cell(r, a, b, tau, true);
    const double f0 = rec ? (double)j0 / r->m : 0.0;
    if (kc < 0) {
        if (rec) rt_ev_herm(ea, s, r, b, f0 + 1.0 / r->m);
        return;
    }
    /* the last kept end (a) for the linear pieces' records */
    rt_ev_end e0 = rec ? rt_ev_end_at(s, r, a) : (rt_ev_end){0};
    if (kc == 0 || kc >= RT_GRID) { /* at an end: the whole substep linear */
        rt_piece_acc_t(s, r, a, b, RT_GRID, false, np, nt, false, rec);
        if (rec) rt_ev_lin(ea, s, r, &e0, b, f0 + 1.0 / r->m, NULL);
        return;
    }
    rt_piece_acc_t(s, r, a, b, kc, false, np, nt, false, rec);
    if (rec) rt_ev_lin(ea, s, r, &e0, b, f0 + (double)kc / (double)r->ncell, &e0);
    rt_piece_acc_t(s, r, b, b, RT_GRID - kc, false, np, nt, false, rec);
    if (rec) rt_ev_lin(ea, s, r, &e0, b, f0 + 1.0 / r->m, NULL);
}

/* The sub substeps of one graded piece from in into o (w: two scratch snapshots), the j0-th
 * substep of the sample first: one call and one dispatch on the sizes per graded piece
 * redone, not one per piece of its substeps (issue 29, fifth round). */
static inline __attribute__((always_inline)) void
rt_substeps_acc_t(const afm_sim *s, const rt_state *r, const rt_snap *in, rt_snap *o, rt_snap *w,
                  int j0, int sub, double taus, rt_evacc *ea, const int np, const int nt,
                  const bool rec) {
    const rt_snap *x = in;
    for (int j = 0; j < sub; j++) {
        rt_snap *y = j == sub - 1 ? o : &w[j & 1];
        rt_substep_acc_t(s, r, x, y, taus, ea, j0 + j, np, nt, rec);
        x = y;
    }
}

/* rt_substeps_acc_t out of line, the sizes picked once (as rt_piece_acc_n, rt_piece_acc_rec). */
static AFM_CLONES_NOINLINE void rt_substeps_acc(const afm_sim *s, const rt_state *r,
                                                const rt_snap *in, rt_snap *o, rt_snap *w, int j0,
                                                int sub, double taus, rt_evacc *ea) {
    if (ea) {
        if (r->ntones == 1 && r->np == 4)
            rt_substeps_acc_t(s, r, in, o, w, j0, sub, taus, ea, 4, 1, true);
        else if (r->ntones == 1 && r->np == 8)
            rt_substeps_acc_t(s, r, in, o, w, j0, sub, taus, ea, 8, 1, true);
        else
            rt_substeps_acc_t(s, r, in, o, w, j0, sub, taus, ea, r->np, rt_tones_kind(r), true);
    } else if (r->ntones == 1 && r->np == 4)
        rt_substeps_acc_t(s, r, in, o, w, j0, sub, taus, NULL, 4, 1, false);
    else if (r->ntones == 1 && r->np == 8)
        rt_substeps_acc_t(s, r, in, o, w, j0, sub, taus, NULL, 8, 1, false);
    else if (r->ntones > 1 && r->np == 4)
        rt_substeps_acc_t(s, r, in, o, w, j0, sub, taus, NULL, 4, RT_TONES_V4, false);
    else if (r->ntones > 1 && r->np == 8)
        rt_substeps_acc_t(s, r, in, o, w, j0, sub, taus, NULL, 8, RT_TONES_V4, false);
    else
        rt_substeps_acc_t(s, r, in, o, w, j0, sub, taus, NULL, r->np, rt_tones_kind(r), false);
}

/* rt_contact for the accurate scheme. */
static AFM_CLONES_NOINLINE rt_snap *rt_contact_acc(const afm_sim *s, const rt_state *r, rt_snap *a,
                                                   rt_snap *b, bool redo, rt_evacc *ea) {
    double tau = s->dt_s / r->m;
    if (r->noise) rt_noise_sample_begin(r, redo);
    for (int k = 0; k < r->m; k++) {
        if (r->noise) rt_noise_substep(r);
        rt_substep_acc(s, r, a, b, tau, ea, k);
        rt_snap *t = a;
        a = b;
        b = t;
    }
    return a;
}

/* The tip at a merged piece's midpoint (rt_merge_ok_t): what the step record's end needs. */
typedef struct {
    double x_m, v_m_s, a_m_s2; /* quintic Hermite of the ends' x, v, a */
    double f_n, fdot_n_s;      /* the force law there and its dF/dt (f_x v + f_v a) */
} rt_mid;

/* The embedded error estimate of a Hermite piece of length T in contact from in to o (o's
 * acc_m_s2 set; a0 the tip's acceleration at in): the tip at the midpoint from the ends' x,
 * v, a (quintic Hermite: its error is ~T^6 x^(6) / 46080, far below the force's), the force
 * law there against the Hermite interpolant's midpoint value (F0 + F1) / 2 + (D0 - D1) / 8
 * (its error ~T^4 F^(4) / 384). True where the two agree within tol (N); *m the midpoint. */
static inline __attribute__((always_inline)) bool rt_merge_ok_t(const afm_sim *s, const rt_state *r,
                                                                const rt_snap *in, const rt_snap *o,
                                                                double T, double a0, double tol,
                                                                rt_mid *m) {
    const double x0 = in->tip.x_m, v0 = in->tip.v_m_s, x1 = o->tip.x_m, v1 = o->tip.v_m_s;
    const double a1 = o->acc_m_s2;
    m->x_m = 0.5 * (x0 + x1) + T * (5.0 / 32.0) * (v0 - v1) + T * T * (a0 + a1) / 64.0;
    m->v_m_s = (15.0 / 8.0) * (x1 - x0) / T - (7.0 / 16.0) * (v0 + v1) + T * (a1 - a0) / 32.0;
    m->a_m_s2 = 1.5 * (v1 - v0) / T - 0.25 * (a0 + a1);
    double fx, fv;
    m->f_n = rt_force_in(s, r, m->x_m, m->v_m_s, &fx, &fv);
    m->fdot_n_s = fma(fx, m->v_m_s, fv * m->a_m_s2);
    const double fh = 0.5 * (in->tip.f_n + o->tip.f_n) + T * (in->fdot_n_s - o->fdot_n_s) / 8.0;
    return fabs(m->f_n - fh) <= tol;
}

/* A merged piece's record from the last kept end to o (frac1; the piece T = 2 tau long): one
 * record update, its work corrected with the midpoint m from the end-corrected trapezoid to
 * T [7/30 (g0 + g1) + 8/15 gm] + T^2/60 (g0' - g1') (exact to degree 5; the trapezoid over
 * the long piece errs 16 times its halves'). */
static inline void rt_ev_merged(rt_evacc *ea, const afm_sim *s, const rt_state *r, const rt_snap *o,
                                const rt_mid *m, double T, double frac1) {
    const double g0 = ea->g, d0 = ea->d;
    rt_ev_herm(ea, s, r, o, frac1);
    const double g1 = ea->g, d1 = ea->d;
    rt_snap hs, *h = &hs; /* only the tip fields rt_ev_end_of reads */
    h->tip.x_m = m->x_m;
    h->tip.v_m_s = m->v_m_s;
    h->tip.f_n = m->f_n;
    h->fdot_n_s = m->fdot_n_s;
    rt_ev_end em;
    rt_ev_end_of(s, r, h, m->a_m_s2, &em);
    double gm, dm;
    rt_ev_gd(&em, &gm, &dm);
    ea->rec.work_ts_j += (4.0 / 15.0) * T * (2.0 * gm - g0 - g1 - 0.25 * T * (d0 - d1));
}

/* Where a merge's end st is (T its length): 1 where far |v| above the contact line (and, with
 * RT_ACC_GAP_MERGE, that many of its travels |v| T above d = 0), 2 where only the latter holds
 * and the merge is kept on the embedded estimate (RT_ACC_GAP_TOL > 0), 0 where neither. */
static inline __attribute__((always_inline)) int
rt_merge_clear(const rt_state *r, const rt_snap *st, double far, double T) {
    const double x = st->tip.x_m, av = fabs(st->tip.v_m_s);
    if (!(RT_ACC_GAP_MERGE > 0)) return x - r->xc > far * av;
    const double xg = -r->z_m / r->cos_alpha; /* the tip x at which the gap is 0 */
    if (!(x - xg > RT_ACC_GAP_MERGE * T * av) || !(x > r->xc)) return 0;
    return x - r->xc > far * av ? 1 : RT_ACC_GAP_TOL > 0 ? 2 : 0;
}

/* Several graded pieces as one (kc cells, T long) out of contact from in into o, its start
 * already clear of the line (rt_merge_clear, the caller's test): kept where its end is too and
 * its path does not cross the line (and, where either end is clear only by RT_ACC_GAP_MERGE,
 * the embedded estimate agrees), its record (ea) to frac1 of the sample. False (o scratch)
 * where not kept. rt_graded_acc's merges and the tip-channel form's. */
static inline __attribute__((always_inline)) bool
rt_graded_merge_t(const afm_sim *s, const rt_state *r, const rt_snap *in, rt_snap *o, int kc,
                  double T, double far, double frac1, const int np, const int nt, const bool evs,
                  rt_evacc *ea) {
    const bool est = RT_ACC_GAP_TOL > 0; /* the estimate reads o's acceleration */
    const int c0 = est ? rt_merge_clear(r, in, far, T) : 1;
    rt_piece_acc_t(s, r, in, o, kc, true, np, nt, false, evs || est);
    const int c1 = rt_merge_clear(r, o, far, T);
    if (!c1 || rt_crosses(r, in, o, T)) return false;
    rt_mid mid;
    if (est && (c0 != 1 || c1 != 1) &&
        !rt_merge_ok_t(s, r, in, o, T, rt_ev_acc(r, in, np, nt), RT_ACC_GAP_TOL * r->ftol, &mid))
        return false;
    if (ea) rt_ev_herm(ea, s, r, o, frac1);
    return true;
}

/* the same sample in the tip-channel form (RT_ACC_TC): its nodes use rt_substeps_acc above */
#include "integrators/afm_rt_tc.h"

/* A sample near or in contact, without thermal noise, from a into b: RT_ACC_NEAR_PIECES whole
 * Hermite pieces, a piece whose path crosses the contact line or has an end in contact close
 * to it (RT_ACC_CLOSE_TRAVELS) redone in its share of the m contact substeps (rt_substep_acc:
 * split at the located crossing). The indentation's square root (DMT, viscoelastic) is no
 * polynomial in time near the line; away from it the pieces are fourth order. Out of contact
 * and far from the line four (RT_ACC_MERGE4_TRAVELS) or two (RT_ACC_MERGE_TRAVELS) pieces are
 * taken as one; in contact every piece is dt / RT_ACC_NEAR_PIECES long (longer ones miss NCHV's
 * dissipated energy, docs/numerics.md eleventh round). evs: ea gathers the pieces kept (else
 * NULL). */
static inline __attribute__((always_inline)) void rt_graded_acc(const afm_sim *s, const rt_state *r,
                                                                const rt_snap *a, rt_snap *b,
                                                                const int np, const int nt,
                                                                const bool evs, rt_evacc *ea) {
    const int K = RT_ACC_NEAR_PIECES, k = r->ncell / K, sub = r->m / K;
    const double tau = s->dt_s / K, taus = s->dt_s / r->m, xc = r->xc;
    const double close = RT_ACC_CLOSE_TRAVELS * tau;
    const double far2 = RT_ACC_MERGE_TRAVELS * 2.0 * tau;
    const double far4 = RT_ACC_MERGE4_TRAVELS * 4.0 * tau;
    const double close2 = RT_ACC_CLOSE_TRAVELS * 2.0 * tau, mtol = RT_ACC_MERGE_TOL * r->ftol;
    rt_snap t[2], w[2];
    const rt_snap *in = a;
    for (int p = 0; p < K; p++) {
        rt_snap *o = p == K - 1 ? b : in == &t[0] ? &t[1] : &t[0];
        /* out of contact, far from the line at both ends: four pieces in one
         * (RT_ACC_MERGE4_TRAVELS), else two (RT_ACC_MERGE_TRAVELS) */
        if (RT_ACC_MERGE4_TRAVELS > 0 && (p & 3) == 0 && rt_merge_clear(r, in, far4, 4.0 * tau)) {
            rt_snap *o4 = p + 4 == K ? b : o;
            if (rt_graded_merge_t(s, r, in, o4, 4 * k, 4.0 * tau, far4, (double)(p + 4) / K, np, nt,
                                  evs, ea)) {
                in = o4;
                p += 3;
                continue;
            }
        }
        if (RT_ACC_MERGE_TRAVELS > 0 && (p & 1) == 0 && rt_merge_clear(r, in, far2, 2.0 * tau)) {
            rt_snap *o2 = p + 2 == K ? b : o;
            if (rt_graded_merge_t(s, r, in, o2, 2 * k, 2.0 * tau, far2, (double)(p + 2) / K, np, nt,
                                  evs, ea)) {
                in = o2;
                p++;
                continue;
            }
        }
        /* in contact, clear of the line at both ends (RT_ACC_CLOSE_TRAVELS of the long
         * piece's travel) and the embedded estimate small (RT_ACC_MERGE_TOL): two in one */
        if (RT_ACC_MERGE_TOL > 0 && (p & 1) == 0 && in->tip.x_m < xc &&
            xc - in->tip.x_m >= close2 * fabs(in->tip.v_m_s)) {
            rt_snap *o2 = p + 2 == K ? b : o;
            const double a0 = rt_ev_acc(r, in, np, nt), T = 2.0 * tau;
            /* the end predicted from the start (x0 + v0 T + a0 T^2 / 2): a trial whose end
             * would come close to the line is not taken (its result would be discarded) */
            const double xp = fma(fma(0.5 * a0, T, in->tip.v_m_s), T, in->tip.x_m);
            const double vp = fma(a0, T, in->tip.v_m_s);
            rt_mid mid;
            if (xc - xp >= close2 * fabs(vp)) {
                rt_piece_acc_t(s, r, in, o2, 2 * k, true, np, nt, false, true);
                if (o2->tip.x_m < xc && xc - o2->tip.x_m >= close2 * fabs(o2->tip.v_m_s) &&
                    rt_merge_ok_t(s, r, in, o2, T, a0, mtol, &mid)) {
                    if (ea) rt_ev_merged(ea, s, r, o2, &mid, T, (double)(p + 2) / K);
                    in = o2;
                    p++;
                    continue;
                }
            }
        }
        /* a start in contact close to the line: the piece is redone whatever its end, so
         * it is not taken whole first (its result would be discarded) */
        bool near = in->tip.x_m < xc && xc - in->tip.x_m < close * fabs(in->tip.v_m_s);
        if (!near) {
            rt_piece_acc_t(s, r, in, o, k, true, np, nt, false, evs);
            near = o->tip.x_m < xc && xc - o->tip.x_m < close * fabs(o->tip.v_m_s);
        }
        if (near || rt_crosses(r, in, o, tau)) {
            rt_substeps_acc(s, r, in, o, w, p * sub, sub, taus, ea);
        } else if (ea) {
            rt_ev_herm(ea, s, r, o, (double)(p + 1) / K);
        }
        in = o;
    }
}

/* n output steps of the accurate scheme (afm_sim_backend.run when r->acc). evs: each step's
 * record (afm_rt_evrec.h) into s->ev_ring (without noise only; a constant: the loop without it
 * is the scheme's own). */
static inline __attribute__((always_inline)) int rt_run_acc_t(afm_sim *s, rt_state *r, int n,
                                                              afm_sample *out, const int np,
                                                              const int nt, const bool noise,
                                                              const bool evs) {
    int rc = AFM_SIM_OK;
    /* the clock, the resync count and what the tests read of r in registers over the block
     * (stores through the snapshots may alias r, so they would be reloaded every sample) */
    long step = s->step, since = r->since_sync;
    double stepd = (double)step; /* the step count as a double (exact below 2^53) */
    const double t0 = s->t_start_s, dt = s->dt_s;
    const double half_dt = 0.5 * dt, dt2_12 = dt * dt * (1.0 / 12.0); /* rt_ev_free's weights */
    const bool kinked = r->kinked;
    const double xc = r->xc, sure_k = r->sure_k, clear_k = r->clear_k;
    rt_snap *a = &r->buf[r->cur], *const b0 = &r->buf[0], *const b1 = &r->buf[1];
    rt_evacc eacc, *ea = evs ? &eacc : NULL;
    if (evs) {
        rt_ev_start(ea, s, r, a, np, nt, true);
        ea->slot = (step + 1) % s->ev_cap; /* the first step ends at step + 1 */
    }
    rt_acc_tip ta = rt_acc_tip_of(r, a, np, nt), tb; /* the tip at a and at b, in registers */
    for (int k = 0; k < n; k++) {
        if (__builtin_expect(++since >= RT_RESYNC, 0)) {
            s->step = step;
            s->t_s = t0 + stepd * dt;
            rt_sync_phasors(s, r, a);
            since = r->since_sync;
            a->fdot_n_s = rt_fdot(r, a, np, nt);
            a->acc_free = false;
            ta = rt_acc_tip_of(r, a, np, nt);
            if (evs) rt_ev_start(ea, s, r, a, np, nt, false);
        }
        rt_snap *b = a == b0 ? b1 : b0;
        const bool at_once = kinked && ta.x_m < xc;
        /* Without noise, a start so close to the line that the free step's low bound (below)
         * is certainly in the band: no trial step (its result would be discarded). The path's
         * low bound is at most x0 - clear_k |v0| and the band at least NEAR_TRAVELS |v0| dt;
         * the margin RT_ACC_SURE keeps a rounding at the edge from taking a sample the trial
         * would have kept. */
        bool contact = at_once || (!noise && kinked && ta.x_m - xc < sure_k * fabs(ta.v_m_s));
        if (!contact) {
            if (noise) { /* rt_piece_acc_t draws the increment before its solve */
                rt_piece_acc_t(s, r, a, b, r->ncell, true, np, nt, true, false);
                tb = rt_acc_tip_of(r, b, np, nt);
            } else {
                rt_free_acc_t(s, r, a, b, np, nt, evs, &ta, &tb);
            }
            if (kinked) {
                /* the path's low bound; within one travel of the contact line the steep
                 * van der Waals pulse needs the substeps even where it does not cross */
                const double sp = fabs(ta.v_m_s) + fabs(tb.v_m_s);
                const double low = (ta.x_m < tb.x_m ? ta.x_m : tb.x_m) - clear_k * sp;
                contact = low < xc + RT_ACC_NEAR_TRAVELS * sp * dt;
            }
        }
        /* a step in pieces gathers its record (a kept free step writes it at once) */
        const bool ev_free = evs && kinked && !contact;
        if (evs && !ev_free) rt_ev_step_begin(ea);
        if (contact && !noise && r->m % RT_ACC_NEAR_PIECES == 0)
            /* near or in contact: whole Hermite pieces follow the van der Waals pulse and
             * the indentation; substeps only for the pieces at the contact line */
            if (RT_ACC_TC)
                rt_graded_tc_t(s, r, a, b, np, nt, evs, ea);
            else
                rt_graded_acc(s, r, a, b, np, nt, evs, ea);
        else if (contact)
            b = rt_contact_acc(s, r, a, b, noise && !at_once, ea); /* noise: trial taken */
        if (contact)
            tb = rt_acc_tip_of(r, b, np, nt);
        else if (ev_free) /* kept whole: clear of the contact line */
            rt_ev_free(ea, s, r, b, step + 1, half_dt, dt2_12);
        else if (evs)
            rt_ev_herm(ea, s, r, b, 1.0);
        a = b;
        ta = tb;
        step++;
        stepd += 1.0;
        if (evs && !ev_free) rt_ev_step_end(ea, s, step, contact);
        if (!(fabs(ta.x_m) < 1e-3) || !(fabs(ta.v_m_s) < HUGE_VAL && fabs(ta.f_n) < HUGE_VAL)) {
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
            o->t_s = t0 + stepd * dt;
            o->x_m = ta.x_m;
            o->v_m_s = ta.v_m_s;
            o->f_n = ta.f_n;
            o->theta_rad = th;
            o->base_m = u;
        }
    }
    s->step = step;
    s->t_s = t0 + (double)step * dt;
    r->since_sync = since;
    r->cur = a == b0 ? 0 : 1;
    if (evs) rt_ev_finish(r, a, rc == AFM_SIM_OK);
    rt_publish(s, r, a);
    return rc;
}

#endif
