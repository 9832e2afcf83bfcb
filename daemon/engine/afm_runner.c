/* SPDX-License-Identifier: MIT */
/* afm_runner.c -- simulator + output chain driven by commands at block boundaries
 * (contract in afm_runner.h). */
#include "afm_runner.h"

#include "afm_force.h"
#include "afm_sim_live.h"
#include "afm_twin.h"

#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct afm_runner_model {
    afm_config cfg;
    afm_sim *sim;
    afm_chain *chain; /* NULL: keep the running chain */
};

struct afm_runner {
    afm_config cfg;
    afm_sim *sim;
    afm_chain *chain;
    afm_sample *buf;
    int block_max;
    bool lockstep, running;
    long long step_budget, tick_budget;
    long long samples;
    int64_t seq_applied;
    /* Z ramp: Z = z0 + dir rate (samples - s0) dt, updated at multiples of RAMP_SAMPLES */
    bool ramping;
    double z0, z_target, z_rate;
    long long s0;
    long long blowups, applied, swaps;
    double last_blowup_t_s;
};

static void set_err(char *err, size_t errlen, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void set_err(char *err, size_t errlen, const char *fmt, ...) {
    if (!err || !errlen) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

void afm_runner_model_destroy(afm_runner_model **mp) {
    if (!mp || !*mp) return;
    afm_runner_model *m = *mp;
    afm_sim_destroy(&m->sim);
    afm_chain_destroy(&m->chain);
    free(m);
    *mp = NULL;
}

afm_runner_model *afm_runner_model_build(const afm_config *cfg, bool new_chain, char *err,
                                         size_t errlen) {
    afm_runner_model *m = calloc(1, sizeof *m);
    if (!m) {
        set_err(err, errlen, "out of memory");
        return NULL;
    }
    m->cfg = *cfg;
    if (afm_config_validate(cfg, err, errlen)) goto fail;
    m->sim = afm_twin_create(cfg, NULL, NULL, err, errlen);
    if (!m->sim) goto fail;
    if (cfg->thermal.enabled && afm_sim_set_thermal(m->sim, &cfg->thermal, err, errlen)) goto fail;
    if (new_chain) {
        m->chain = afm_chain_create(cfg, afm_sim_model(m->sim), err, errlen);
        if (!m->chain) goto fail;
    }
    return m;
fail:
    afm_runner_model_destroy(&m);
    return NULL;
}

afm_runner *afm_runner_create(const afm_config *cfg, int block_max, bool lockstep, char *err,
                              size_t errlen) {
    if (!cfg || block_max < 1 || block_max > (1 << 24)) {
        set_err(err, errlen, "runner: no config, or block_max %d not in 1..%d", block_max,
                1 << 24);
        return NULL;
    }
    afm_runner *r = calloc(1, sizeof *r);
    afm_runner_model *m = NULL;
    if (!r) {
        set_err(err, errlen, "out of memory");
        return NULL;
    }
    r->buf = malloc((size_t)block_max * sizeof *r->buf);
    if (!r->buf) {
        set_err(err, errlen, "runner: cannot allocate %d samples", block_max);
        goto fail;
    }
    m = afm_runner_model_build(cfg, true, err, errlen);
    if (!m) goto fail;
    r->cfg = *cfg;
    r->sim = m->sim;
    r->chain = m->chain;
    m->sim = NULL;
    m->chain = NULL;
    afm_runner_model_destroy(&m);
    if (afm_chain_attach(r->chain, r->sim, err, errlen)) goto fail;
    r->block_max = block_max;
    r->lockstep = lockstep;
    r->running = true;
    r->seq_applied = -1;
    r->last_blowup_t_s = NAN;
    return r;
fail:
    afm_runner_destroy(&r);
    return NULL;
}

void afm_runner_destroy(afm_runner **rp) {
    if (!rp || !*rp) return;
    afm_runner *r = *rp;
    afm_chain_destroy(&r->chain);
    afm_sim_destroy(&r->sim);
    free(r->buf);
    free(r);
    *rp = NULL;
}

int afm_runner_cmd_needs_model(const afm_config *cfg, const afm_cmd *c, bool *new_chain) {
    bool nc = false;
    int need = 0;
    if (c->kind == AFM_CMD_RELOAD) {
        need = 1;
        nc = true;
    } else if (c->kind == AFM_CMD_PARAM) {
        afm_config t = *cfg;
        afm_param_effect e;
        if (afm_param_apply(&t, &c->u.param, &e, NULL, 0) == 0 && e >= AFM_PARAM_DAMPING) {
            need = 1;
            nc = e == AFM_PARAM_GEOMETRY;
        }
    }
    if (new_chain) *new_chain = nc;
    return need;
}

/* ---- commands ----------------------------------------------------------------------- */

static void set_z(afm_runner *r, double z) {
    afm_sim_set_separation(r->sim, z); /* z is validated */
    afm_chain_set_separation(r->chain, z);
    r->cfg.drive.separation_m = z;
}

static int apply_dither(afm_runner *r, const afm_cmd_dither *d, char *err, size_t errlen) {
    afm_sim *s = r->sim;
    const afm_drive *dr = afm_sim_drive(s);
    int n_run = dr->n;
    for (int j = 0; j < d->n_tones; j++) {
        int rc = j < n_run ? afm_sim_set_tone(s, j, d->amplitude_m[j], d->frequency_hz[j])
                           : afm_sim_start_tone(s, j, d->amplitude_m[j], d->frequency_hz[j],
                                                d->phase_rad[j]);
        if (rc != AFM_SIM_OK) { /* not reached after afm_cmd_validate with this sample rate */
            set_err(err, errlen, "dither: tone %d rejected by the simulator", j);
            return -1;
        }
    }
    for (int j = d->n_tones; j < n_run; j++) /* tones the command leaves out fall silent */
        afm_sim_set_tone(s, j, 0.0, dr->omega_rad_s[j] / 6.283185307179586476925286766559);
    return 0;
}

static void apply_setpoint(afm_runner *r, const afm_cmd_setpoint *p) {
    double z = afm_sim_separation(r->sim);
    if (p->ramp_rate_m_s == 0 || z == p->separation_m) {
        r->ramping = false;
        set_z(r, p->separation_m);
        return;
    }
    r->ramping = true;
    r->z0 = z;
    r->z_target = p->separation_m;
    r->z_rate = p->ramp_rate_m_s;
    r->s0 = r->samples;
}

/* Swap model m in: time always continues; `what` as afm_sim_continue. On return m holds the
 * objects swapped out. */
static int swap_in(afm_runner *r, afm_runner_model *m, unsigned what, char *err, size_t errlen) {
    if (afm_sim_continue(m->sim, r->sim, what) != AFM_SIM_OK) {
        set_err(err, errlen, "the new model has %d modes, the running one %d: cannot carry "
                "the state over", afm_sim_model(m->sim)->n, afm_sim_model(r->sim)->n);
        return -1;
    }
    afm_chain *c = m->chain ? m->chain : r->chain;
    if (afm_chain_attach(c, m->sim, err, errlen)) return -1;
    afm_sim *old_sim = r->sim;
    r->sim = m->sim;
    m->sim = old_sim;
    if (m->chain) {
        afm_chain *old_chain = r->chain;
        r->chain = m->chain;
        m->chain = old_chain;
        afm_chain_attach(m->chain, NULL, NULL, 0);
    }
    r->swaps++;
    return 0;
}

static int apply_param(afm_runner *r, const afm_cmd_param *p, afm_runner_model **model,
                       char *err, size_t errlen) {
    afm_config t = r->cfg;
    afm_param_effect e;
    if (afm_param_apply(&t, p, &e, err, errlen)) return -1;
    bool has_z = false;
    for (int i = 0; i < p->n; i++)
        if (afm_param_table(NULL)[p->entry[i]].effect == AFM_PARAM_SEPARATION) has_z = true;
    if (e >= AFM_PARAM_DAMPING) {
        if (!model || !*model) {
            set_err(err, errlen, "param: a %s change needs a model built off the real-time "
                    "thread (afm_runner_model_build)", e == AFM_PARAM_DAMPING ? "damping" : "geometry");
            return -1;
        }
        if (e == AFM_PARAM_GEOMETRY && !(*model)->chain) {
            set_err(err, errlen, "param: a geometry change needs a model with a new chain");
            return -1;
        }
        unsigned what = AFM_SIM_KEEP_DRIVE | (e == AFM_PARAM_DAMPING ? AFM_SIM_KEEP_STATE : 0);
        if (swap_in(r, *model, what, err, errlen)) return -1;
    } else if (e == AFM_PARAM_FORCE) {
        const afm_modal *m = afm_sim_model(r->sim);
        double len = m->beam_length_m > 0 ? m->beam_length_m : t.forces.plate_length_m;
        double wid = m->beam_mean_width_m > 0 ? m->beam_mean_width_m : t.forces.plate_width_m;
        afm_force_params f;
        if (afm_force_init(&f, &t.forces, len, wid, err, errlen)) return -1;
        if (afm_sim_set_forces(r->sim, &f) != AFM_SIM_OK) {
            set_err(err, errlen, "param: the simulator refused the new force constants");
            return -1;
        }
        /* a0 may have moved: the contact line of the cycle metrics with it */
        afm_chain_set_separation(r->chain, afm_sim_separation(r->sim));
    }
    r->cfg = t;
    if (has_z) {
        r->ramping = false;
        set_z(r, t.drive.separation_m);
    } else {
        r->cfg.drive.separation_m = afm_sim_separation(r->sim);
    }
    return 0;
}

int afm_runner_apply(afm_runner *r, const afm_cmd *c, afm_runner_model **model, char *err,
                     size_t errlen) {
    afm_cmd_limits lim = {.sample_rate_hz = r->cfg.sim.sample_rate_hz};
    if (afm_cmd_validate(c, &lim, err, errlen)) return -1;
    switch (c->kind) {
    case AFM_CMD_DITHER:
        if (apply_dither(r, &c->u.dither, err, errlen)) return -1;
        break;
    case AFM_CMD_SETPOINT: apply_setpoint(r, &c->u.setpoint); break;
    case AFM_CMD_PARAM:
        if (apply_param(r, &c->u.param, model, err, errlen)) return -1;
        break;
    case AFM_CMD_CONTROL:
        switch (c->u.control.action) {
        case AFM_CTL_RUN:
            r->running = true;
            r->step_budget = 0;
            break;
        case AFM_CTL_PAUSE: r->running = false; break;
        case AFM_CTL_RESET:
            afm_sim_reset(r->sim);
            afm_chain_reset(r->chain);
            r->ramping = false;
            break;
        case AFM_CTL_STEP:
            r->running = false;
            if (r->step_budget > LLONG_MAX - c->u.control.n_samples)
                r->step_budget = LLONG_MAX;
            else
                r->step_budget += c->u.control.n_samples;
            break;
        }
        break;
    case AFM_CMD_TICK:
        if (!r->lockstep) {
            set_err(err, errlen, "tick: the twin is not in lockstep mode");
            return -1;
        }
        if (r->tick_budget > LLONG_MAX - c->u.tick.n_samples)
            r->tick_budget = LLONG_MAX;
        else
            r->tick_budget += c->u.tick.n_samples;
        break;
    case AFM_CMD_RELOAD:
        if (!model || !*model || !(*model)->chain) {
            set_err(err, errlen, "reload: needs a model with a chain (afm_runner_model_build)");
            return -1;
        }
        if (swap_in(r, *model, 0, err, errlen)) return -1;
        r->cfg = (*model)->cfg;
        r->ramping = false;
        break;
    }
    if (c->kind != AFM_CMD_RELOAD) r->seq_applied = c->seq; /* a reload is no sender's */
    r->applied++;
    return 0;
}

/* ---- running ------------------------------------------------------------------------ */

static void ramp_update(afm_runner *r) {
    double dz = r->z_rate * (double)(r->samples - r->s0) * afm_sim_dt(r->sim);
    double z;
    if (r->z_target > r->z0) {
        z = r->z0 + dz;
        if (z >= r->z_target) z = r->z_target;
    } else {
        z = r->z0 - dz;
        if (z <= r->z_target) z = r->z_target;
    }
    if (z == r->z_target) r->ramping = false;
    set_z(r, z);
}

long long afm_runner_budget(const afm_runner *r) {
    if (!r->running) return r->step_budget;
    if (r->lockstep) return r->tick_budget;
    return LLONG_MAX;
}

long long afm_runner_run(afm_runner *r, long long n) {
    long long want = n, b = afm_runner_budget(r);
    if (want > b) want = b;
    long long done = 0;
    while (done < want) {
        if (r->ramping && r->samples % AFM_RUNNER_RAMP_SAMPLES == 0) ramp_update(r);
        long long k = want - done;
        if (k > r->block_max) k = r->block_max;
        if (r->ramping) {
            long long to_edge = AFM_RUNNER_RAMP_SAMPLES - r->samples % AFM_RUNNER_RAMP_SAMPLES;
            if (k > to_edge) k = to_edge;
        }
        double t0 = afm_sim_time(r->sim);
        int rc = afm_sim_run(r->sim, (int)k, r->buf);
        long long adv = k;
        if (rc == AFM_SIM_OK) {
            afm_chain_push(r->chain, r->buf, (int)k);
        } else {
            /* The simulator reset itself to rest; its clock counts the steps it took. */
            adv = llround((afm_sim_time(r->sim) - t0) / afm_sim_dt(r->sim));
            if (adv > k) adv = k;
            r->blowups++;
            r->last_blowup_t_s = afm_sim_time(r->sim);
            afm_chain_reset(r->chain);
            if (adv <= 0) break; /* the integrator cannot even start: report, go no further */
        }
        r->samples += adv;
        done += adv;
    }
    if (!r->running)
        r->step_budget -= done;
    else if (r->lockstep)
        r->tick_budget -= done;
    return done;
}

int afm_runner_n_streams(const afm_runner *r) { return afm_chain_n_streams(r->chain); }

int afm_runner_take_block(afm_runner *r, int stream, afm_chain_block *b, int max_n) {
    return afm_chain_take_block(r->chain, stream, b, max_n);
}

int afm_runner_take_periods(afm_runner *r, afm_chain_period *out, int max) {
    return afm_chain_take_periods(r->chain, out, max);
}

void afm_runner_status_get(const afm_runner *r, afm_runner_status *st) {
    const afm_drive *d = afm_sim_drive(r->sim);
    st->seq_applied = r->seq_applied;
    st->samples = r->samples;
    st->t_s = afm_sim_time(r->sim);
    st->dt_s = afm_sim_dt(r->sim);
    st->running = r->running;
    st->lockstep = r->lockstep;
    st->step_budget = r->step_budget;
    st->tick_budget = r->tick_budget;
    st->separation_m = afm_sim_separation(r->sim);
    st->separation_target_m = r->ramping ? r->z_target : st->separation_m;
    st->fe_hz = d->n > 0 ? d->omega_rad_s[0] / 6.283185307179586476925286766559 : 0.0;
    st->amplitude_m = d->n > 0 ? d->amp_m[0] : 0.0;
    st->blowups = r->blowups;
    st->last_blowup_t_s = r->last_blowup_t_s;
    st->applied = r->applied;
    st->swaps = r->swaps;
    st->chain = afm_chain_stats_get(r->chain);
}

const afm_config *afm_runner_config(const afm_runner *r) { return &r->cfg; }
const afm_sim *afm_runner_sim(const afm_runner *r) { return r->sim; }
