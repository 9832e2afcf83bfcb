/* SPDX-License-Identifier: MIT */
/* afm_scheme_cost.h -- what each scheme of the rt integrator costs per sample on a model on
 * this machine: the measurement behind the daemon's `--scheme auto` (daemon/scheme.c) and
 * `afmtwin bench-scheme`, in the runner layer so that both use one method.
 *
 * Method: a twin of the config per scheme, settled from rest at each state for
 * AFM_SCHEME_SETTLE_S, then AFM_SCHEME_REPEATS timed windows of AFM_SCHEME_WINDOW_S model
 * time; a state's cost is its median window, a scheme's the worst state. States: the
 * config's operating point, half its separation (harder contact) and free (Z 1 um). The
 * accurate scheme is measured with the integrator's per-step record when a runner of cfg
 * would hand it to the chain (afm_runner_step_events: ~+41 % on the integrator thread,
 * docs/numerics.md), so that the pick counts what the daemon will run.
 * Wall-clock: call it before real time starts, never on the real-time thread. */
#ifndef AFM_SCHEME_COST_H
#define AFM_SCHEME_COST_H

#include "config/afm_config.h"

#include <stddef.h>

#define AFM_SCHEME_SETTLE_S 2e-3
#define AFM_SCHEME_WINDOW_S 0.5e-3
#define AFM_SCHEME_REPEATS 3
#define AFM_SCHEME_STATES 3
/* The accurate scheme runs when its worst state fits this share of the budget 1 / rate. */
#define AFM_SCHEME_FIT_SHARE 0.9

typedef struct {
    double ns[AFM_SCHEME_STATES]; /* per state: operating point, half Z, free */
    double worst_ns;
    bool step_events; /* measured with the per-step record (afm_runner_step_events) */
} afm_scheme_cost;

/* Cost of cfg's rt twin in scheme (AFM_RT_SCHEME_ACCURATE or _FAST), with the record when cfg
 * asks for it (sim.step_events not "off": pass a copy with "off" to measure without). 0, or -1
 * with err. */
int afm_scheme_cost_measure(const afm_config *cfg, afm_rt_scheme_kind scheme, afm_scheme_cost *out,
                            char *err, size_t errlen);

#endif
