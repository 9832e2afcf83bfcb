/* SPDX-License-Identifier: MIT */
/* afm_sim_impl.h -- private: the simulator struct and the backend vtable that each
 * integrator (afm_rt.c, afm_sundials.c) fills. Only afm_sim.c and backends include it. */
#ifndef AFM_SIM_IMPL_H
#define AFM_SIM_IMPL_H

#include "integrators/afm_sim.h"

typedef struct afm_sim_backend {
    const char *name;
    /* Allocate and precompute; s->be_state is the backend's. 0 or -1 with err. */
    int (*init)(afm_sim *s, char *err, size_t errlen);
    /* Advance the modal state s->q, s->qd from s->t_s by exactly s->dt_s (one output step)
     * and set s->f_last_n to the tip force at the end. Does not touch s->t_s. May be NULL
     * when run is set. */
    int (*advance)(afm_sim *s);
    /* Optional batch form of afm_sim_run (afm_sim_run calls it when set, instead of
     * advance): n output steps, each sampled at its end into out[k] (out may be NULL) with
     * the fields afm_sim_run documents; s->step and s->t_s (= t_start + step dt) advanced
     * per step. On return s->q, s->qd, s->f_last_n, x/v/base_last are the current state.
     * A step whose state is non-finite or runs away (|x| >= 1 mm) is counted (step, t_s)
     * and ends the call with AFM_SIM_EBLOWUP; afm_sim_run then resets. */
    int (*run)(afm_sim *s, int n, afm_sample *out);
    /* Optional: s->thermal changed (afm_sim_set_thermal). Precompute (may allocate);
     * 0, or -1 with err and nothing changed. NULL: the backend has no thermal force, and
     * afm_sim_set_thermal rejects enabled settings. */
    int (*thermal)(afm_sim *s, const afm_cfg_thermal *t, char *err, size_t errlen);
    /* The state, Z or the drive was changed from outside at s->t_s: resynchronise. */
    void (*changed)(afm_sim *s);
    /* Optional: only Z (s->z_m) changed (afm_sim_set_separation): update what depends on Z
     * alone (a Z ramp calls this every AFM_RUNNER_RAMP_SAMPLES samples). NULL: changed. */
    void (*changed_z)(afm_sim *s);
    void (*destroy)(afm_sim *s);
    /* Optional: the name of the scheme in force ("accurate", "fast"); NULL: no schemes. */
    const char *(*scheme)(const afm_sim *s);
    /* Optional: switch to the accurate (true) or fast scheme at the current state, without
     * allocating; NULL: no schemes. */
    void (*set_scheme)(afm_sim *s, bool accurate);
} afm_sim_backend;

struct afm_sim {
    afm_modal m;
    afm_force_params f;
    afm_drive drive;
    afm_cfg_sim cfg;
    double z_m;  /* separation Z */
    double dt_s; /* output step */
    double t_s;  /* model time */
    long step;   /* output steps taken since create; t_s = t_start + step * dt */
    double t_start_s;
    double q[AFM_MAX_MODES], qd[AFM_MAX_MODES];
    double f_last_n;         /* tip force at the current state */
    afm_cfg_thermal thermal; /* Langevin force settings (afm_sim_set_thermal; off at create) */
    /* A backend that sets be_fills_tip keeps these at the current state in advance and
     * changed (the rt backend does); afm_sim_run then takes the output from them instead of
     * summing over the modes and calling sin for the base. Others leave it false. */
    bool be_fills_tip;
    double x_last_m, v_last_m; /* tip displacement and velocity */
    double base_last_m;        /* base displacement x_dit at t_s */
    const afm_sim_backend *be;
    void *be_state;
    /* afm_sim_set_events: the caller's ring of step records (NULL: none), ev_cap entries;
     * step k's at ev_ring[k % ev_cap] (the rt accurate scheme fills it, afm_rt_evrec.h) */
    afm_step_events *ev_ring;
    int ev_cap;
};

extern const afm_sim_backend afm_rt_backend;
/* A portable x86-64 build's two copies of afm_rt.c (AFM_RT_COPY): afm_sim picks one. */
extern const afm_sim_backend afm_rt_backend_base, afm_rt_backend_v3;
extern const afm_sim_backend afm_cvode_backend;
extern const afm_sim_backend afm_arkode_erk_backend;

/* Tip displacement and velocity of the current state. */
double afm_sim_tip_x(const afm_sim *s, const double *q);

/* Modal accelerations at (t, q, qd): the right-hand side every backend can share.
 * Writes qdd (n) and returns the tip force used. */
double afm_sim_rhs(const afm_sim *s, double t_s, const double *q, const double *qd, double *qdd);

#endif
