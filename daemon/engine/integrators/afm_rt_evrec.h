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

/* The record being gathered over one output step. */
typedef struct rt_evacc {
    rt_ev_end e0; /* the last kept end */
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

/* A new run of samples from st (the first sample's start, or after a phasor resync). carry:
 * the first sample of a call, whose start is the last run's end when nothing touched the
 * state since (rt_state.ev_a_ok): that end's acceleration, as one run would have had it. */
static inline void rt_ev_start(rt_evacc *ea, const afm_sim *s, const rt_state *r, const rt_snap *st,
                               int np, int nt, bool carry) {
    const bool same = carry && r->ev_a_ok && st->tip.x_m == r->ev_x_m &&
                      st->tip.v_m_s == r->ev_v_m_s && st->tip.f_n == r->ev_f_n;
    rt_ev_end_of(s, r, st, same ? r->ev_a_m_s2 : rt_ev_acc(r, st, np, nt), &ea->e0);
}

/* The run ends (ok: without a blow-up): its last kept end for the next run (rt_ev_start). */
static inline void rt_ev_finish(const rt_evacc *ea, rt_state *r, bool ok) {
    r->ev_a_ok = ok;
    r->ev_a_m_s2 = ea->e0.a;
    r->ev_x_m = ea->e0.x;
    r->ev_v_m_s = ea->e0.v;
    r->ev_f_n = ea->e0.f;
}

/* A new output step: nothing gathered yet. */
static inline void rt_ev_step_begin(rt_evacc *ea) {
    ea->frac0 = 0.0;
    ea->xmin = ea->e0.x;
    ea->rec.n_in = ea->rec.n_out = 0;
    ea->rec.contact_frac = 0.0;
    ea->rec.in_frac = ea->rec.out_frac = ea->rec.v_in_m_s = NAN;
    ea->rec.work_ts_j = 0.0;
}

/* The work int F_ts v dt over a kept piece from e0 to e1 of tau (end-corrected trapezoid);
 * herm: its force is the Hermite cubic (ends' slopes fdot), else linear. */
static inline __attribute__((always_inline)) double
rt_ev_work_of(const rt_ev_end *e0, const rt_ev_end *e1, double tau, bool herm) {
    double fd0 = herm ? e0->fdot : (e1->f - e0->f) / tau, fd1 = herm ? e1->fdot : fd0;
    double t0 = e0->f - e0->fsq, t1 = e1->f - e1->fsq;
    double g0 = t0 * e0->v, g1 = t1 * e1->v;
    double d0 = (fd0 - e0->sqd) * e0->v + t0 * e0->a, d1 = (fd1 - e1->sqd) * e1->v + t1 * e1->a;
    return 0.5 * tau * (g0 + g1) + tau * tau * (1.0 / 12.0) * (d0 - d1);
}

/* rt_ev_work_of's Hermite value over a whole step, its weights 0.5 dt (half_dt) and
 * dt dt / 12 (dt2_12) the caller's loop constants (the same products, so the same bits). */
static inline __attribute__((always_inline)) double
rt_ev_work_dt(const rt_ev_end *e0, const rt_ev_end *e1, double half_dt, double dt2_12) {
    double t0 = e0->f - e0->fsq, t1 = e1->f - e1->fsq;
    double g0 = t0 * e0->v, g1 = t1 * e1->v;
    double d0 = (e0->fdot - e0->sqd) * e0->v + t0 * e0->a;
    double d1 = (e1->fdot - e1->sqd) * e1->v + t1 * e1->a;
    return half_dt * (g0 + g1) + dt2_12 * (d0 - d1);
}

/* rt_ev_work_of added to the step's work. */
static inline __attribute__((always_inline)) void
rt_ev_work(rt_evacc *ea, const rt_ev_end *e0, const rt_ev_end *e1, double tau, bool herm) {
    ea->rec.work_ts_j += rt_ev_work_of(e0, e1, tau, herm);
}

/* A step taken as one free piece (the accurate scheme kept its trial: its path stays above
 * the contact line, so no crossing, and x_min_m is not kept for it): its work alone, and its
 * record written at once, step its step count (issue 29, eighth round: what rt_ev_step_begin,
 * the piece and rt_ev_step_end gave it, the same bits: tau = (1 - 0) dt, the work added to 0,
 * without the accumulator's round trip; ea->rec is left as it was, rt_ev_step_begin resets it
 * for a step in pieces). The piece left st->acc_m_s2. */
static inline __attribute__((always_inline)) void rt_ev_free(rt_evacc *ea, afm_sim *s,
                                                             const rt_state *r, const rt_snap *st,
                                                             long step, double half_dt,
                                                             double dt2_12) {
    rt_ev_end e1;
    rt_ev_end_of(s, r, st, st->acc_m_s2, &e1);
    const double w = rt_ev_work_dt(&ea->e0, &e1, half_dt, dt2_12);
    ea->e0 = e1;
    afm_step_events *o = &s->ev_ring[ea->slot];
    ea->slot = ea->slot + 1 < s->ev_cap ? ea->slot + 1 : 0;
    o->step = step;
    o->n_in = o->n_out = 0;
    o->contact_frac = 0.0;
    o->in_frac = o->out_frac = o->v_in_m_s = NAN;
    o->x_min_m = NAN;
    o->work_ts_j = 0.0 + w;
}

/* A kept piece from the last kept end to st, ending at frac1 of the step; herm: its force is
 * the Hermite cubic (ends' slopes fdot), else linear. The piece left st->acc_m_s2. */
static AFM_CLONES_NOINLINE void rt_ev_piece(rt_evacc *ea, const afm_sim *s, const rt_state *r,
                                            const rt_snap *st, double frac1, bool herm) {
    rt_ev_end e1;
    rt_ev_end_of(s, r, st, st->acc_m_s2, &e1);
    const rt_ev_end *e0 = &ea->e0;
    const double df = frac1 - ea->frac0, tau = df * s->dt_s;
    rt_ev_work(ea, e0, &e1, tau, herm);
    const double xc = r->xc;
    const bool in0 = e0->x < xc, in1 = e1.x < xc, turn = e0->v < 0.0 && e1.v > 0.0;
    if (in0 && in1) ea->rec.contact_frac += df;
    if (e1.x < ea->xmin) ea->xmin = e1.x;
    if (in0 == in1 && !turn) { /* most pieces: no crossing, no minimum */
        ea->e0 = e1;
        ea->frac0 = frac1;
        return;
    }
    /* the path's cubic Hermite in (x, v) */
    rt_cubic p = {2.0 * (e0->x - e1.x) + tau * (e0->v + e1.v),
                  3.0 * (e1.x - e0->x) - tau * (2.0 * e0->v + e1.v), tau * e0->v, e0->x};
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
    ea->e0 = e1;
    ea->frac0 = frac1;
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
