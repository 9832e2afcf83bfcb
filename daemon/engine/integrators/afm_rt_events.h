/* SPDX-License-Identifier: MIT */
/* afm_rt_events.h -- what the rt integrator knows of each output step beyond its end sample:
 * contact crossings, the minimum of x and the tip-sample work, from its own pieces (issue 28).
 *
 * Layer integrators/ (3), the type shared with estimators/afm_cycle (which takes these instead
 * of re-deriving them from the samples on their Hermite cubics). Filled, when the caller handed
 * a ring (afm_sim_set_events), by the accurate scheme without thermal noise (below) and by the
 * CVODE reference from its dense output (afm_sundials_ev.c: its continuous solution's own
 * crossings, minimum and work, the truth the accurate scheme's record is tested against); the
 * fast scheme and ARKODE leave it alone, and afm_sim_events_at then says "not known" (NULL).
 *
 * Where the numbers come from: a step near or in contact is taken in pieces (graded Hermite
 * pieces of dt / 8, contact substeps of dt / 32, split pieces at a crossing; afm_rt_acc.h).
 * Every piece the integrator keeps (not the trial pieces it redoes) has exact ends (x, v, F,
 * dF/dt, the tip's acceleration a). On each of them:
 *  - a crossing of the contact line: the ends on opposite sides, located on the piece's cubic
 *    Hermite in (x, v) (a piece of dt / 32: ~1e-7 of the piece), its velocity the cubic's slope;
 *  - the minimum of x: the ends, and the piece's Hermite cubic where v turns from - to +;
 *  - the work int (F - F_sq) v dt: F is the piece's own force polynomial (the scheme's model:
 *    Hermite in time, or linear beside a crossing), v the exact modal velocity, by the
 *    end-corrected trapezoid tau/2 (g0 + g1) + tau^2/12 (g0' - g1'), g = F_ts v, g' = F_ts' v +
 *    F_ts a (exact for a cubic g); F_sq the squeeze film at the ends (rt_force's expression),
 *    taken out as afm_cycle does.
 * A step taken as one free piece (clear of contact) has no crossing, x_min_m NAN (its path is
 * the samples' own Hermite cubic: nothing to add) and its work from that one piece. */
#ifndef AFM_RT_EVENTS_H
#define AFM_RT_EVENTS_H

#include <math.h>

typedef struct {
    long step;           /* the output step this record is for (afm_sim's step count after it);
                            -1: empty */
    int n_in, n_out;     /* inward and outward crossings of the contact line in the step */
    double contact_frac; /* share of the step with x below the contact line, [0, 1] */
    double in_frac;      /* first inward crossing, fraction of the step (NAN: none) */
    double out_frac;     /* first outward crossing, fraction of the step (NAN: none) */
    double v_in_m_s;     /* tip velocity at the first inward crossing (NAN: none) */
    double x_min_m;      /* min of x over the step's pieces (NAN: one free piece) */
    double work_ts_j;    /* int (F - F_sq) v dt over the step (J): the tip-sample force's work
                            on the cantilever, the squeeze film apart */
} afm_step_events;

#endif
