/* SPDX-License-Identifier: MIT */
/* afm_rt_evrec.h -- the accurate scheme's per-step record (afm_step_events, afm_rt_events.h):
 * crossings, minimum of x and tip-sample work, gathered from the pieces it keeps.
 * Private to the rt backend: included once, by afm_rt.c (which is compiled once per CPU copy,
 * AFM_RT_COPY), so its static functions stay in that one translation unit. Only the sample
 * loop instantiated with events on (rt_run_acc_t, evs) calls these: without a ring the
 * scheme's code is what it was. */
#ifndef AFM_RT_EVREC_H
#define AFM_RT_EVREC_H

#include "integrators/afm_rt_cross.h"
#include "integrators/afm_rt_force.h"

/* What a kept piece's end contributes: the tip, its force and their time derivatives. */
typedef struct {
    double x, v, a;  /* tip displacement (m), velocity (m/s), acceleration (m/s^2) */
    double f, fdot;  /* total tip force (N) and the scheme's dF/dt there (N/s) */
    double fsq, sqd; /* the squeeze film's force (N) and its dF_sq/dt (N/s) */
} rt_ev_end;

/* The end-corrected trapezoid's g = (F - F_sq) v at e and its slope d (Hermite: the force's
 * slope fdot). */
static inline __attribute__((always_inline)) void rt_ev_gd(const rt_ev_end *e, double *g,
                                                           double *d) {
    const double t = e->f - e->fsq;
    *g = t * e->v;
    *d = (e->fdot - e->sqd) * e->v + t * e->a;
}

/* The record being gathered over one output step. The last kept end is always a live snapshot
 * (the sample's start, a graded piece's or a substep's end); what a later piece needs of it is
 * carried here, not the end itself (issue 29, tenth round): its g and Hermite d (the work's end
 * terms) and its x, v (the crossing test). A linear piece (beside a crossing) rebuilds its
 * start's whole end from the snapshot (rt_ev_lin). */
typedef struct rt_evacc {
    double g, d;  /* the last kept end's g and Hermite d (rt_ev_gd) */
    double x, v;  /* its tip displacement (m) and velocity (m/s) */
    double frac0; /* its time in the step (fraction of dt) */
    double xmin;  /* min of x over the kept path so far */
    afm_step_events rec;
    long slot; /* the ring entry of the step being gathered: its step count % ev_cap, carried
                * (rt_ev_step_end; a division per sample otherwise) */
} rt_evacc;

/* The tip's acceleration at st (rt_fdot's sum). */
static inline double rt_ev_acc(const rt_state *r, const rt_snap *st, int np, int nt) {
    rt_v4 a4 = rt_splat(0.0);
    for (int i = 0; i < np; i += 4)
        a4 = rt_fma4(RT_V4(r->aq + i), RT_V4(st->q + i),
                     rt_fma4(RT_V4(r->av + i), RT_V4(st->v + i), a4));
    return rt_hsum(a4) + r->tip2 * st->tip.f_n +
           rt_tones_im(r->ax_re, r->ax_im, st->z_re, st->z_im, nt);
}

/* The end quantities of st (rt_force's squeeze film expressions), a its acceleration. */
static inline __attribute__((always_inline)) void
rt_ev_end_of(const afm_sim *s, const rt_state *r, const rt_snap *st, double a, rt_ev_end *e) {
    const afm_force_params *p = &s->f;
    e->x = st->tip.x_m;
    e->v = st->tip.v_m_s;
    e->f = st->tip.f_n;
    e->fdot = st->fdot_n_s;
    e->a = a;
    e->fsq = e->sqd = 0.0;
    if (p->squeeze == AFM_SQUEEZE_LINEAR) {
        double c = fma(p->p1, s->z_m + e->x, p->p2);
        if (c > 0.0) {
            e->fsq = -c * e->v;
            e->sqd = -p->p1 * e->v * e->v - c * e->a;
        }
    } else if (p->squeeze == AFM_SQUEEZE_STARR) {
        double kx, kv;
        e->fsq = rt_squeeze(s, r, e->x, e->v, &kx, &kv);
        e->sqd = kx * e->v + kv * e->a;
    }
}

/* e becomes the last kept end, at frac1 of the step. */
static inline __attribute__((always_inline)) void rt_ev_keep(rt_evacc *ea, const rt_ev_end *e,
                                                             double g, double d, double frac1) {
    ea->g = g;
    ea->d = d;
    ea->x = e->x;
    ea->v = e->v;
    ea->frac0 = frac1;
}

/* A new run of samples from st (the first sample's start, or after a phasor resync). carry:
 * the first sample of a call, whose start is the last run's end when nothing touched the
 * state since (rt_state.ev_a_ok): that end's acceleration, as one run would have had it. The
 * acceleration is left in st->acc_m_s2, as a piece leaves it (a linear piece from st reads it). */
static inline void rt_ev_start(rt_evacc *ea, const afm_sim *s, const rt_state *r, rt_snap *st,
                               int np, int nt, bool carry) {
    const bool same = carry && r->ev_a_ok && st->tip.x_m == r->ev_x_m &&
                      st->tip.v_m_s == r->ev_v_m_s && st->tip.f_n == r->ev_f_n;
    st->acc_m_s2 = same ? r->ev_a_m_s2 : rt_ev_acc(r, st, np, nt);
    rt_ev_end e;
    double g, d;
    rt_ev_end_of(s, r, st, st->acc_m_s2, &e);
    rt_ev_gd(&e, &g, &d);
    rt_ev_keep(ea, &e, g, d, 0.0);
}

/* The run ends at st (ok: without a blow-up): its last kept end for the next run
 * (rt_ev_start). */
static inline void rt_ev_finish(rt_state *r, const rt_snap *st, bool ok) {
    r->ev_a_ok = ok;
    r->ev_a_m_s2 = st->acc_m_s2;
    r->ev_x_m = st->tip.x_m;
    r->ev_v_m_s = st->tip.v_m_s;
    r->ev_f_n = st->tip.f_n;
}

/* A new output step: nothing gathered yet. */
static inline void rt_ev_step_begin(rt_evacc *ea) {
    ea->frac0 = 0.0;
    ea->xmin = ea->x;
    ea->rec.n_in = ea->rec.n_out = 0;
    ea->rec.contact_frac = 0.0;
    ea->rec.in_frac = ea->rec.out_frac = ea->rec.v_in_m_s = NAN;
    ea->rec.work_ts_j = 0.0;
}

/* The work int F_ts v dt over a kept linear piece from e0 to e1 of tau (end-corrected
 * trapezoid, the force's slope the secant's at both ends; a Hermite piece's sum is
 * rt_ev_herm_t's, from the ends' rt_ev_gd). */
static inline __attribute__((always_inline)) double
rt_ev_work_lin(const rt_ev_end *e0, const rt_ev_end *e1, double tau) {
    const double fd = (e1->f - e0->f) / tau;
    double t0 = e0->f - e0->fsq, t1 = e1->f - e1->fsq;
    double g0 = t0 * e0->v, g1 = t1 * e1->v;
    double d0 = (fd - e0->sqd) * e0->v + t0 * e0->a, d1 = (fd - e1->sqd) * e1->v + t1 * e1->a;
    return 0.5 * tau * (g0 + g1) + tau * tau * (1.0 / 12.0) * (d0 - d1);
}

/* A step taken as one free piece (the accurate scheme kept its trial: its path stays above
 * the contact line, so no crossing, and x_min_m is not kept for it): its work alone, and its
 * record written at once, step its step count (issue 29, eighth round: what rt_ev_step_begin,
 * the piece and rt_ev_step_end gave it, the same bits: tau = (1 - 0) dt, the work added to 0,
 * without the accumulator's round trip; ea->rec is left as it was, rt_ev_step_begin resets it
 * for a step in pieces). Its weights 0.5 dt (half_dt) and dt dt / 12 (dt2_12) are the caller's
 * loop constants (rt_ev_herm_t's products, so the same bits). The piece left st->acc_m_s2. */
static inline __attribute__((always_inline)) void rt_ev_free(rt_evacc *ea, afm_sim *s,
                                                             const rt_state *r, const rt_snap *st,
                                                             long step, double half_dt,
                                                             double dt2_12) {
    rt_ev_end e1;
    double g1, d1;
    rt_ev_end_of(s, r, st, st->acc_m_s2, &e1);
    rt_ev_gd(&e1, &g1, &d1);
    const double w = half_dt * (ea->g + g1) + dt2_12 * (ea->d - d1);
    ea->g = g1;
    ea->d = d1;
    ea->x = e1.x;
    ea->v = e1.v;
    afm_step_events *o = &s->ev_ring[ea->slot];
    ea->slot = ea->slot + 1 < s->ev_cap ? ea->slot + 1 : 0;
    o->step = step;
    o->n_in = o->n_out = 0;
    o->contact_frac = 0.0;
    o->in_frac = o->out_frac = o->v_in_m_s = NAN;
    o->x_min_m = NAN;
    o->work_ts_j = 0.0 + w;
}

/* The rare part of a kept piece's record (its path crosses the contact line, or turns): the
 * crossing from the path's cubic Hermite in (x, v) between the ends (x0, v0) at ea->frac0 and
 * (x1, v1), df of the step long (tau s); the minimum inside a turn. */
static AFM_CLONES_NOINLINE void rt_ev_cross(rt_evacc *ea, const rt_state *r, double x0, double v0,
                                            double x1, double v1, double tau, double df) {
    const double xc = r->xc;
    const bool in0 = x0 < xc, in1 = x1 < xc, turn = v0 < 0.0 && v1 > 0.0;
    rt_cubic p = {2.0 * (x0 - x1) + tau * (v0 + v1), 3.0 * (x1 - x0) - tau * (2.0 * v0 + v1),
                  tau * v0, x0};
    if (in0 != in1) {
        double sg = rt_cubic_root(&p, xc, 0.0, 1.0), fr = ea->frac0 + sg * df;
        if (in1) {
            ea->rec.contact_frac += (1.0 - sg) * df;
            if (ea->rec.n_in++ == 0) {
                ea->rec.in_frac = fr;
                ea->rec.v_in_m_s = ((3.0 * p.a * sg + 2.0 * p.b) * sg + p.c) / tau;
            }
        } else {
            ea->rec.contact_frac += sg * df;
            if (ea->rec.n_out++ == 0) ea->rec.out_frac = fr;
        }
    }
    if (turn) { /* a minimum inside: 3 a s^2 + 2 b s + c = 0, c < 0 */
        double A = 3.0 * p.a, B = 2.0 * p.b, disc = fma(B, B, -4.0 * A * p.c);
        if (disc >= 0.0) {
            double qq = -0.5 * (B + (B >= 0 ? sqrt(disc) : -sqrt(disc)));
            double r0 = A != 0.0 ? qq / A : -1.0, r1 = qq != 0.0 ? p.c / qq : -1.0;
            for (int k = 0; k < 2; k++) {
                double sg = k ? r1 : r0;
                if (sg > 0.0 && sg < 1.0) {
                    double x = rt_cubic_at(&p, sg);
                    if (x < ea->xmin) ea->xmin = x;
                }
            }
        }
    }
}

/* The crossing test and minimum of a kept piece from the last kept end to (x1, v1), df of the
 * step long (tau s): the common case inline, a crossing or turn rt_ev_cross. */
static inline __attribute__((always_inline)) void
rt_ev_path(rt_evacc *ea, const rt_state *r, double x1, double v1, double tau, double df) {
    const double x0 = ea->x, v0 = ea->v, xc = r->xc;
    const bool in0 = x0 < xc, in1 = x1 < xc;
    if (in0 && in1) ea->rec.contact_frac += df;
    if (x1 < ea->xmin) ea->xmin = x1;
    if (__builtin_expect(in0 != in1 || (v0 < 0.0 && v1 > 0.0), 0))
        rt_ev_cross(ea, r, x0, v0, x1, v1, tau, df);
}

/* A kept Hermite piece (its force the Hermite cubic, ends' slopes fdot) from the last kept end
 * to st, ending at frac1 of the step: the end-corrected trapezoid from the carried g, d.
 * The piece left st->acc_m_s2. */
static inline __attribute__((always_inline)) void
rt_ev_herm_t(rt_evacc *ea, const afm_sim *s, const rt_state *r, const rt_snap *st, double frac1) {
    rt_ev_end e1;
    double g1, d1;
    rt_ev_end_of(s, r, st, st->acc_m_s2, &e1);
    rt_ev_gd(&e1, &g1, &d1);
    const double df = frac1 - ea->frac0, tau = df * s->dt_s;
    ea->rec.work_ts_j += 0.5 * tau * (ea->g + g1) + tau * tau * (1.0 / 12.0) * (ea->d - d1);
    rt_ev_path(ea, r, e1.x, e1.v, tau, df);
    rt_ev_keep(ea, &e1, g1, d1, frac1);
}

/* rt_ev_herm_t out of line (the substeps, the tip-channel form, rt_ev_merged). */
static AFM_CLONES_NOINLINE void rt_ev_herm(rt_evacc *ea, const afm_sim *s, const rt_state *r,
                                           const rt_snap *st, double frac1) {
    rt_ev_herm_t(ea, s, r, st, frac1);
}

/* A kept linear piece (beside a crossing: its force linear in time, the secant slope at both
 * ends) from e0 (the last kept end, rebuilt by the caller from its snapshot: rt_ev_end_of
 * with its acc_m_s2) to st, ending at frac1; e1o (NULL: not wanted) gets st's end, for a
 * following linear piece from st taken in place. The piece left st->acc_m_s2. */
static AFM_CLONES_NOINLINE void rt_ev_lin(rt_evacc *ea, const afm_sim *s, const rt_state *r,
                                          const rt_ev_end *e0, const rt_snap *st, double frac1,
                                          rt_ev_end *e1o) {
    rt_ev_end e1;
    double g1, d1;
    rt_ev_end_of(s, r, st, st->acc_m_s2, &e1);
    rt_ev_gd(&e1, &g1, &d1);
    const double df = frac1 - ea->frac0, tau = df * s->dt_s;
    ea->rec.work_ts_j += rt_ev_work_lin(e0, &e1, tau);
    rt_ev_path(ea, r, e1.x, e1.v, tau, df);
    rt_ev_keep(ea, &e1, g1, d1, frac1);
    if (e1o) *e1o = e1;
}

/* The last kept end rebuilt from its snapshot st (a linear piece's start). */
static inline __attribute__((always_inline)) rt_ev_end
rt_ev_end_at(const afm_sim *s, const rt_state *r, const rt_snap *st) {
    rt_ev_end e;
    rt_ev_end_of(s, r, st, st->acc_m_s2, &e);
    return e;
}

/* The step is done (its kept pieces all taken): its record into the caller's ring.
 * piecewise: it was taken in pieces (x_min_m known), else one free piece. */
static inline void rt_ev_step_end(rt_evacc *ea, afm_sim *s, long step, bool piecewise) {
    afm_step_events *o = &s->ev_ring[ea->slot];
    ea->slot = ea->slot + 1 < s->ev_cap ? ea->slot + 1 : 0;
    ea->rec.step = step;
    ea->rec.x_min_m = piecewise ? ea->xmin : NAN;
    *o = ea->rec;
}

#endif
