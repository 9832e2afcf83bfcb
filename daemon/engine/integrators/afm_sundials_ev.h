/* SPDX-License-Identifier: MIT */
/* afm_sundials_ev.h -- private to afm_sundials.c: the CVODE reference's record of one output
 * step (afm_step_events, afm_rt_events.h) from its continuous solution, so that its per-period
 * metrics (afm_cycle_push_ev) are the solution's own and not the samples' estimate (issue 28).
 * Offline only (CVODE allocates anyway). */
#ifndef AFM_SUNDIALS_EV_H
#define AFM_SUNDIALS_EV_H

#include "integrators/afm_sim_impl.h"

#include <sundials/sundials_nvector.h>

/* Advance CVODE (mem, set up with its stop time at tout, the end of the output step that
 * starts at s->t_s) to tout in its own internal steps (CV_ONE_STEP: the same steps as
 * CV_NORMAL), y the state at tout on return, tmp a scratch vector of y's length; rec: the
 * step's crossings (located on the dense output), its share in contact, the minimum of x
 * (never NAN) and the tip-sample work int (F - F_sq) v dt (Gauss-Legendre between the
 * step's turns and crossings). rec->step is the caller's. 0, or -1 when CVODE failed. */
int afm_cv_step_events(afm_sim *s, void *mem, N_Vector y, N_Vector tmp, double tout,
                       afm_step_events *rec);

#endif
