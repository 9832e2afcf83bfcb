/* SPDX-License-Identifier: MIT */
/* afm_scheme_cost.c -- per-sample cost of each rt scheme on a model (see afm_scheme_cost.h). */
#include "runner/afm_scheme_cost.h"

#include "runner/afm_runner.h"
#include "runner/afm_twin.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double mono_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Records the measurement cycles through with the record on: about the runner's ring (the
 * daemon's default 5 ms at 14.06 MHz is 70300 samples), so that the records go to memory as
 * cold as the ring items the runner points the integrator at (a small ring stays in cache). */
#define RING_EV (64 * AFM_RUNNER_SLOT_SAMPLES)

/* ns per sample of cfg's twin in scheme sc at separation z_m: the median window. With ring
 * (RING_EV entries), the integrator records every step (afm_sim_set_events), as in the runner
 * with the record on. */
static double state_ns(const afm_config *cfg, afm_rt_scheme_kind sc, double z_m,
                       afm_step_events *ring, char *err, size_t errlen) {
    static afm_config c; /* large; one caller at a time (start-up, tools) */
    c = *cfg;
    c.sim.integrator = AFM_INTEGRATOR_RT;
    c.sim.rt_scheme = sc;
    afm_sim *s = afm_twin_create(&c, NULL, NULL, err, errlen);
    if (!s) return -1;
    if (ring) afm_sim_set_events(s, ring, RING_EV);
    double dt = afm_sim_dt(s), t[AFM_SCHEME_REPEATS];
    if (afm_sim_set_separation(s, z_m) != AFM_SIM_OK) {
        afm_sim_destroy(&s);
        snprintf(err, errlen, "cannot set Z %g m", z_m);
        return -1;
    }
    long n_settle = lround(AFM_SCHEME_SETTLE_S / dt), n_win = lround(AFM_SCHEME_WINDOW_S / dt);
    afm_sim_run(s, (int)n_settle, NULL);
    for (int k = 0; k < AFM_SCHEME_REPEATS; k++) {
        double t0 = mono_s();
        afm_sim_run(s, (int)n_win, NULL);
        t[k] = (mono_s() - t0) / (double)n_win * 1e9;
    }
    afm_sim_destroy(&s);
    for (int i = 0; i < AFM_SCHEME_REPEATS; i++)
        for (int j = i + 1; j < AFM_SCHEME_REPEATS; j++)
            if (t[j] < t[i]) {
                double x = t[i];
                t[i] = t[j];
                t[j] = x;
            }
    return t[AFM_SCHEME_REPEATS / 2];
}

int afm_scheme_cost_measure(const afm_config *cfg, afm_rt_scheme_kind scheme, afm_scheme_cost *out,
                            char *err, size_t errlen) {
    const double z0 = cfg->drive.separation_m, zs[AFM_SCHEME_STATES] = {z0, 0.5 * z0, 1e-6};
    static afm_config c;
    c = *cfg;
    c.sim.integrator = AFM_INTEGRATOR_RT;
    c.sim.rt_scheme = scheme;
    /* the record as a runner of cfg makes it: only the accurate scheme records */
    out->step_events = scheme == AFM_RT_SCHEME_ACCURATE && afm_runner_step_events(&c);
    afm_step_events *ring = NULL;
    if (out->step_events && !(ring = malloc(RING_EV * sizeof *ring))) {
        snprintf(err, errlen, "out of memory");
        return -1;
    }
    int rc = 0;
    out->worst_ns = 0;
    for (int i = 0; i < AFM_SCHEME_STATES && rc == 0; i++) {
        out->ns[i] = state_ns(cfg, scheme, zs[i], ring, err, errlen);
        if (out->ns[i] < 0) rc = -1;
        if (out->ns[i] > out->worst_ns) out->worst_ns = out->ns[i];
    }
    free(ring);
    return rc;
}
