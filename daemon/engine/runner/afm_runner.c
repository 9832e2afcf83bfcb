/* SPDX-License-Identifier: MIT */
/* afm_runner.c -- simulator + output chain driven by commands at block boundaries
 * (contract in afm_runner.h).
 *
 * Two halves joined by a lock-free ring (afm_spsc) of fixed-size items:
 *  - the front (integrator side): commands, Z ramp, budgets, the simulator. It writes
 *    afm_sample blocks straight into ring items (SAMPLES), each stamped with the drive,
 *    seq_applied and the Z in force for its samples, and turns every change the chain must
 *    follow into an item in the same order (RESET, FORCES, ATTACH);
 *  - the back (chain side): the output chain, attached to a mirror of the simulator
 *    (afm_sim_mirror_create) that the items keep in step; it pushes the samples and
 *    applies the changes in ring order.
 * With the integrator's per-step record on (afm_runner_step_events; issue 28), a SAMPLES item
 * also carries the record of each of its samples (ev), which the back hands to the chain
 * (afm_chain_push_ev) in place of re-deriving crossings, minimum and work from the samples.
 * Inline (afm_runner_create) the back runs on the caller's thread right after every item;
 * pipelined (afm_runner_create_pipelined) on a thread of the caller's. Either way the
 * chain sees the same calls with the same data in the same order: the outputs are
 * bit-identical (test_runner checks it). */
#include "runner/afm_runner.h"

#include "estimators/afm_phase_gen.h"
#include "config/afm_err.h"

#include "forces/afm_force.h"
#include "forces/afm_surface.h"
#include "integrators/afm_sim_live.h"
#include "runner/afm_a0.h"
#include "runner/afm_fm.h"
#include "runner/afm_pi.h"
#include "runner/afm_scan.h"
#include "runner/afm_spsc.h"
#include "runner/afm_twin.h"

#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SLOT AFM_RUNNER_SLOT_SAMPLES
#define ZC_MAX (SLOT / AFM_RUNNER_RAMP_SAMPLES + 2) /* Z changes one item can carry */
#define PENDING_MAX 16   /* change items waiting for ring space (front) */
#define EVENTS_PER_CMD 2 /* most change items one command makes */
#define TRASH_CAP 1024
#define TRASH_HELD 16
#define LAT AFM_RUNNER_SCAN_SAMPLES

enum { IT_SAMPLES, IT_RESET, IT_FORCES, IT_ATTACH, IT_DONE };

typedef struct {
    int at; /* first sample (index into s) with this Z */
    double z_m;
} z_change;

/* With a sample (issue 18): from sample `at` on, the stage Z, the tip's place, z_s there and
 * the material: the operating point the period records that end there carry. */
typedef struct {
    int at;
    double z_m, x_m, y_m, h_m;
    int mat;
} lat_change;

/* One ring item. SAMPLES: n samples s[0..n) run with drive `drive`, Z z0_m then the
 * changes zc, after the command seq. FORCES: new force constants f. ATTACH: the chain
 * follows a swapped-in simulator (drive, f, z_m); model: the objects to hand back (and,
 * when model->chain is set, the chain to swap in). RESET: clear the chain. DONE: a tick or
 * step budget was used up (seq: that command, done_samples and done_t_s: where). */
typedef struct {
    int kind;
    int n;
    int64_t seq;
    double z0_m;
    int n_zc;
    z_change zc[ZC_MAX];
    int n_lc; /* with a sample: the stage Z and what is under the tip, from sample lc[i].at */
    lat_change lc[ZC_MAX];
    afm_drive drive;
    afm_force_params f;
    afm_runner_model *model;
    long long done_samples;
    double done_t_s;
    /* the sample under the tip at the last of the samples (lat_on: the config has one) */
    bool lat_on;
    double lat_z_m, lat_x_m, lat_y_m, lat_h_m; /* stage Z, tip x, y, true height z_s */
    int lat_mat;
    /* the internal FM loops (fm_on) when the item was opened: after their last update before
     * its first sample (an NCO step commits the open item, so tone 0 is constant in it) */
    int fm_lock;  /* afm_fm_lock, -1 without the loops */
    int fm_drive; /* afm_fm_drive, -1 without the loops */
    double fm_shift_hz, fm_phase_error_deg;
    afm_sample s[SLOT];
    /* The integrator's records (afm_rt_events.h) of samples [ev_begin, ev_end): the
     * simulator's ring is this array while the item is open (open_item), so each
     * record is written once, by the integrator, straight where the back reads it: no copy
     * on the real-time thread, no allocation (the array is part of the ring's slot), and the
     * simulator never holds a committed item (detached at commit). The step ending at sample
     * i (ev_begin <= i < ev_end) is ev_step0 + i, its record at ev[(ev_step0 + i) % SLOT]
     * when that entry's step says so (else none: the fast scheme, thermal noise, or steps
     * overwritten after a blow-up). ev_end == ev_begin: no record in this item. */
    int ev_begin, ev_end;
    bool ev_broken; /* a blow-up in this item: no record after it */
    long ev_step0;
    afm_step_events ev[SLOT];
} ring_item;

/* A change item waiting for ring space (no samples). */
typedef struct {
    int kind;
    afm_drive drive;
    afm_force_params f;
    double z_m;
    afm_runner_model *model;
    int64_t seq; /* DONE: the tick or step command */
    long long done_samples;
    double done_t_s;
} pending_item;

struct afm_runner_model {
    afm_config cfg;
    afm_sim *sim;
    afm_chain *chain;  /* NULL: keep the running chain */
    afm_surface *surf; /* cfg's sample (NULL without a sample group); taken by a reload */
    double a0_m;       /* A0 of cfg (runner/afm_a0.h) with am.control = "internal", else 0 */
};

struct afm_runner {
    /* front */
    afm_config cfg;
    afm_sim *sim;
    int block_max;
    bool lockstep, running, pipelined;
    long long step_budget, tick_budget;
    long long samples;
    int64_t seq_applied;
    bool ramping;
    double z0, z_target, z_rate;
    long long s0;
    long long blowups, applied, swaps, stalls;
    double last_blowup_t_s;
    int blowup_streak; /* blow-ups each within AFM_RUNNER_BLOWUP_WINDOW_S of the last */
    bool auto_paused;  /* paused by itself (streak reached AFM_RUNNER_BLOWUP_PAUSE) */
    long long auto_pauses;
    int64_t tick_seq, step_seq; /* the last tick and step commands applied (IT_DONE names
                                 * the one whose budget was used up) */
    ring_item *open;            /* reserved, being filled; committed at the end of every run */
    bool ev_on; /* the integrator's per-step record into the items (afm_runner_step_events) */
    /* internal FM control (fm.control = "internal", issue 32): the PLL and amplitude loops on
     * tone 0, fed by a lock-in of their own on the front's samples (the chain's is on the
     * other thread) */
    bool fm_on;
    bool fm_hold_pending; /* amplitude set-point 0: hold the amplitude of the first lock */
    afm_fm fm;
    afm_lockin fm_lk;
    afm_phase_gen fm_pg; /* fm_lk's reference phase, as the chain's (from the sample index) */
    long long fm_tone_changes, fm_tone_refused;
    double fm_u[SLOT], fm_th[SLOT]; /* one slice's deflection and reference phase */
    /* internal AM Z control (am.control = "internal", issue 18): the reference PI (afm_pi)
     * on the amplitude of fm_lk (FM and AM control exclude each other: the config says so),
     * updated every LAT samples counted from create; it waits for the lock-in to settle
     * (zc_hold_until) after create, a reset and a reload. */
    bool zc_on;
    afm_pi zc;
    double zc_a_m;           /* the lock-in amplitude of the last update (NAN before) */
    long long zc_hold_until; /* sample count before which the PI does not move Z */
    long long zc_updates;    /* updates that moved Z */
    /* the sample under the tip (issue 18; the config's sample group, else surf NULL and none
     * of this runs): the integrator's separation is the stage Z (cfg.drive.separation_m)
     * less z_s(x, y), its forces those of the material there. The tip moves by scan
     * commands; its position is updated every LAT samples counted from create. */
    afm_surface *surf;
    afm_force_params mat[AFM_MAX_MATERIALS + 1], mat_tmp[AFM_MAX_MATERIALS + 1];
    int lat_mode;                               /* afm_scan_mode */
    double lat_x, lat_y, lat_h;                 /* where the tip is, z_s there */
    int lat_mat;                                /* the material there (the simulator's forces) */
    long long lat_s0;                           /* the sample count the motion started at */
    double lat_x0, lat_y0;                      /* ... and where */
    double lat_tx, lat_ty, lat_dist, lat_speed; /* MOVE */
    double lat_vx, lat_vy;                      /* VELOCITY */
    afm_scan_cfg lat_sc;                        /* RASTER */
    int lat_line, lat_pixel;                    /* RASTER: where it is (-1: none) */
    bool lat_retrace;
    long long lat_clamps; /* updates where the surface rose past the stage Z (gap held at 0) */
    pending_item pending[PENDING_MAX];
    int n_pending;
    /* between */
    afm_spsc ring;  /* front -> back */
    afm_spsc trash; /* back -> whoever calls afm_runner_take_trash */
    /* back */
    afm_chain *chain;
    afm_sim *mirror;
    double b_z;
    int64_t b_seq;
    double b_fe_hz, b_t_s;
    afm_runner_oppoint b_op;
    /* the operating point of every period record the chain holds, in its order: the op of
     * the item its period ended in (the chain's ring and its drop-the-oldest rule, so that
     * the two stay aligned; cleared with the chain's queue). By runs: the records of one push
     * share one op (one copy a push, not one a period: issue 12); b_pop_n records in
     * b_pop_runs runs from b_pop_head, each run at least one record */
    struct {
        afm_runner_oppoint op;
        int n;
    } b_pop[AFM_CHAIN_PERIOD_RING];
    int b_pop_head, b_pop_runs, b_pop_n;
    long long b_samples, b_items, b_attach_errors, b_trash_lost;
    const afm_step_events *b_ev[SLOT]; /* the item's samples' records (NULL: none) */
    int b_ends[SLOT];       /* with a sample: the sample each record of a push ended on */
    long long b_ev_samples; /* samples whose metrics took a record */
    afm_runner_model *held[TRASH_HELD]; /* trash waiting for space */
    int n_held;
    bool b_done_waiting; /* a DONE item passed, not yet taken (afm_runner_take_done) */
    afm_runner_done b_done;
};

static const double two_pi = 6.283185307179586476925286766559;

const afm_modal *afm_runner_model_modal(const afm_runner_model *m) {
    return m && m->sim ? afm_sim_model(m->sim) : NULL;
}

void afm_runner_model_destroy(afm_runner_model **mp) {
    if (!mp || !*mp) return;
    afm_runner_model *m = *mp;
    afm_surface_destroy(&m->surf);
    afm_sim_destroy(&m->sim);
    afm_chain_destroy(&m->chain);
    free(m);
    *mp = NULL;
}

/* cfg's A0 config with tone 0 of the drive in force (drive NULL: cfg's own tone 0). */
static void a0_config(afm_config *out, const afm_config *cfg, const afm_cmd_dither *drive) {
    *out = *cfg;
    if (drive && drive->n_tones >= 1 && out->drive.n_tones >= 1) {
        out->drive.tones[0].frequency_hz = drive->frequency_hz[0];
        out->drive.tones[0].amplitude_m = drive->amplitude_m[0];
    }
}

afm_runner_model *afm_runner_model_build(const afm_config *cfg, bool new_chain, char *err,
                                         size_t errlen) {
    return afm_runner_model_build_at(cfg, new_chain, NULL, err, errlen);
}

afm_runner_model *afm_runner_model_a0(const afm_config *cfg, const afm_cmd_dither *drive, char *err,
                                      size_t errlen) {
    afm_runner_model *m = calloc(1, sizeof *m);
    if (!m) {
        afm_err_set(err, errlen, "out of memory");
        return NULL;
    }
    m->cfg = *cfg;
    afm_config tc;
    a0_config(&tc, cfg, drive);
    if (cfg->sample.enabled) /* the forces of material 0, as the running twin's A0 */
        afm_surface_material_forces(&cfg->sample, &cfg->forces, 0, &tc.forces);
    afm_a0 a0;
    if (afm_a0_compute(&tc, &a0, err, errlen)) {
        free(m);
        return NULL;
    }
    m->a0_m = a0.amplitude_m;
    return m;
}

afm_runner_model *afm_runner_model_build_at(const afm_config *cfg, bool new_chain,
                                            const afm_cmd_dither *drive, char *err, size_t errlen) {
    afm_runner_model *m = calloc(1, sizeof *m);
    if (!m) {
        afm_err_set(err, errlen, "out of memory");
        return NULL;
    }
    m->cfg = *cfg;
    if (afm_config_validate(cfg, err, errlen)) goto fail;
    /* With a sample: the simulator starts with material 0's forces, every material's terms
     * on (afm_surface_material_forces), as afm_scan_twin_create does. */
    afm_config tc = *cfg;
    if (cfg->sample.enabled) {
        if (afm_surface_create(&m->surf, &cfg->sample, cfg->forces.radius_m, err, errlen))
            goto fail;
        afm_surface_material_forces(&cfg->sample, &cfg->forces, 0, &tc.forces);
    }
    m->sim = afm_twin_create(&tc, NULL, NULL, err, errlen);
    if (!m->sim) goto fail;
    for (int k = 1; m->surf && k <= cfg->sample.n_materials; k++) { /* every material's forces */
        afm_cfg_forces f;
        afm_force_params fp;
        afm_surface_material_forces(&cfg->sample, &cfg->forces, k, &f);
        if (afm_twin_forces(cfg, afm_sim_model(m->sim), &f, &fp, err, errlen)) goto fail;
    }
    if (cfg->thermal.enabled && afm_sim_set_thermal(m->sim, &cfg->thermal, err, errlen)) goto fail;
    if (cfg->am.control == AFM_AM_CONTROL_INTERNAL) { /* the set-point's reference, off-thread */
        afm_a0 a0;
        afm_config ac;
        a0_config(&ac, &tc, drive); /* at the drive in force: dithers may have moved tone 0 */
        if (afm_a0_compute(&ac, &a0, err, errlen)) goto fail;
        m->a0_m = a0.amplitude_m;
    }
    if (new_chain) {
        m->chain = afm_chain_create(&tc, afm_sim_model(m->sim), err, errlen);
        if (!m->chain) goto fail;
    }
    return m;
fail:
    afm_runner_model_destroy(&m);
    return NULL;
}

/* ---- back: the chain side ----------------------------------------------------------- */

static void back_trash(afm_runner *r, afm_runner_model *m) {
    while (r->n_held > 0 && afm_spsc_push(&r->trash, &r->held[r->n_held - 1]))
        r->n_held--;
    if (afm_spsc_push(&r->trash, &m)) return;
    if (r->n_held < TRASH_HELD)
        r->held[r->n_held++] = m;
    else
        r->b_trash_lost++; /* leaked rather than blocking: nobody drains the trash */
}

static void back_separation(afm_runner *r, double z) {
    r->b_z = z;
    afm_sim_mirror_set(r->mirror, NULL, NULL, z);
    afm_chain_set_separation(r->chain, z);
}

/* The operating point of the samples the back just took. */
static void back_oppoint(afm_runner *r, const afm_drive *d) {
    r->b_op.z_m = r->b_z;
    r->b_op.n_tones = d->n;
    for (int j = 0; j < d->n && j < AFM_MAX_TONES; j++) {
        r->b_op.freq_hz[j] = d->omega_rad_s[j] / two_pi;
        r->b_op.amp_m[j] = d->amp_m[j];
    }
}

/* The oldest n records of b_pop gone (n <= b_pop_n), their ops into ops[0..n) if ops. */
static void back_pop_drop(afm_runner *r, int n, afm_runner_oppoint *ops) {
    const unsigned mask = AFM_CHAIN_PERIOD_RING - 1;
    _Static_assert((AFM_CHAIN_PERIOD_RING & (AFM_CHAIN_PERIOD_RING - 1)) == 0, "a power of 2");
    while (n > 0) {
        int h = r->b_pop_head, d = n < r->b_pop[h].n ? n : r->b_pop[h].n;
        for (int i = 0; ops && i < d; i++)
            *ops++ = r->b_pop[h].op;
        n -= d;
        r->b_pop_n -= d;
        if ((r->b_pop[h].n -= d) == 0) {
            r->b_pop_head = (int)((unsigned)(h + 1) & mask);
            r->b_pop_runs--;
        }
    }
}

/* k period records more in the chain: their op is b_op (the item's they ended in). The
 * chain drops its oldest beyond AFM_CHAIN_PERIOD_RING: so do we. */
static void back_pop_put(afm_runner *r, long long k) {
    const int N = AFM_CHAIN_PERIOD_RING;
    if (k <= 0) return;
    if (k > N) k = N;
    if (r->b_pop_n + k > N) back_pop_drop(r, (int)(r->b_pop_n + k - N), NULL);
    const unsigned w = (unsigned)(r->b_pop_head + r->b_pop_runs) & (unsigned)(N - 1);
    r->b_pop[w].op = r->b_op;
    r->b_pop[w].n = (int)k;
    r->b_pop_runs++;
    r->b_pop_n += (int)k;
}

/* n records taken from the chain: their ops into ops[0..n) (if ops), in order (b_op for
 * any beyond those b_pop knows). */
static void back_pop_take(afm_runner *r, int n, afm_runner_oppoint *ops) {
    int d = n < r->b_pop_n ? n : r->b_pop_n;
    back_pop_drop(r, d, ops);
    for (int i = d; ops && i < n; i++)
        ops[i] = r->b_op;
}

/* What is under the tip (and the stage Z) from sample l->at on, into b_op. */
static void back_lat(afm_runner *r, const lat_change *l) {
    r->b_op.z_m = l->z_m; /* the stage Z, not the gap, and what is under the tip */
    r->b_op.tip_x_m = l->x_m;
    r->b_op.tip_y_m = l->y_m;
    r->b_op.true_height_m = l->h_m;
    r->b_op.material = l->mat;
}

/* With a sample: the k records of a push of the item's samples [from, to), the j-th ended on
 * sample from + b_ends[j]: each gets the stage Z and the tip's place in force at that sample
 * (the item's lc from *il on, applied to b_op as the ends pass them), by runs of equal ops.
 * The same ops as a push cut at every lc would give (issue 18), without the cuts. */
static void back_pop_put_ends(afm_runner *r, const ring_item *it, int from, int to, int k,
                              int *il) {
    int run = 0;
    for (int j = 0; j < k; j++) {
        const int a = j < SLOT ? from + r->b_ends[j] : to - 1; /* j < SLOT: k <= to - from */
        if (*il < it->n_lc && it->lc[*il].at <= a) {
            back_pop_put(r, run);
            run = 0;
            while (*il < it->n_lc && it->lc[*il].at <= a)
                back_lat(r, &it->lc[(*il)++]);
        }
        run++;
    }
    back_pop_put(r, run);
}

/* The records of the item's samples into r->b_ev (afm_runner_step_events): true when at least
 * one sample has one. */
static bool back_events(afm_runner *r, const ring_item *it) {
    if (it->ev_end <= it->ev_begin) return false;
    int n = 0;
    for (int i = 0; i < it->n; i++) {
        const afm_step_events *e = NULL;
        if (i >= it->ev_begin && i < it->ev_end) {
            long step = it->ev_step0 + i;
            e = step >= 0 ? &it->ev[step % SLOT] : NULL;
            if (e && e->step != step) e = NULL;
        }
        r->b_ev[i] = e;
        n += e != NULL;
    }
    r->b_ev_samples += n;
    return n > 0;
}

static void back_item(afm_runner *r, ring_item *it) {
    switch (it->kind) {
    case IT_SAMPLES: {
        afm_sim_mirror_set(r->mirror, &it->drive, NULL, r->b_z);
        if (it->z0_m != r->b_z) back_separation(r, it->z0_m);
        r->b_seq = it->seq;
        r->b_fe_hz = it->drive.n > 0 ? it->drive.omega_rad_s[0] / two_pi : 0.0;
        back_oppoint(r, &it->drive);
        r->b_op.fm_lock = it->fm_lock;
        r->b_op.fm_drive = it->fm_drive;
        r->b_op.fm_shift_hz = it->fm_shift_hz;
        r->b_op.fm_phase_error_deg = it->fm_phase_error_deg;
        if (!it->lat_on) {
            r->b_op.tip_x_m = r->b_op.tip_y_m = r->b_op.true_height_m = 0.0;
            r->b_op.material = 0;
        }
        /* Sub-slices between the changes of Z (zc: the chain's contact line follows the gap),
         * so that every period record gets the operating point of the sample it ended on,
         * however the samples were sliced into items (replay = daemon, bit for bit). With a
         * sample, the stage Z and the tip (lc, every AFM_RUNNER_SCAN_SAMPLES while the tip
         * moves) cut no push: the chain says where each record ended (afm_chain_push_ev_ends)
         * and the record takes the lc in force at that sample, the op a cut there gave
         * (issue 18: a cut costs the chain ~3100 instructions; on a grating the gap stands
         * still over the flat 80 % of a line, and so do the pushes). */
        const bool ev = back_events(r, it);
        int from = 0, iz = 0, il = 0;
        while (from < it->n || iz < it->n_zc) {
            while (iz < it->n_zc && it->zc[iz].at <= from)
                back_separation(r, it->zc[iz++].z_m);
            if (!it->lat_on) r->b_op.z_m = r->b_z;
            int to = it->n;
            if (iz < it->n_zc && it->zc[iz].at < to) to = it->zc[iz].at;
            if (to <= from) {
                if (from >= it->n) break;
                continue;
            }
            while (il < it->n_lc && it->lc[il].at <= from) /* in force from the push's start */
                back_lat(r, &it->lc[il++]);
            const afm_step_events *const *e = ev ? r->b_ev + from : NULL;
            if (il < it->n_lc && it->lc[il].at < to) { /* the tip moves within the push */
                int k =
                    afm_chain_push_ev_ends(r->chain, it->s + from, e, to - from, r->b_ends, SLOT);
                back_pop_put_ends(r, it, from, to, k, &il);
            } else { /* one op for the push (no sample, or a tip that holds), as before */
                long long p0 = afm_chain_periods(r->chain);
                afm_chain_push_ev(r->chain, it->s + from, e, to - from);
                back_pop_put(r, afm_chain_periods(r->chain) - p0);
            }
            from = to;
        }
        if (it->lat_on) { /* after the item: its last sample's */
            r->b_op.z_m = it->lat_z_m;
            r->b_op.tip_x_m = it->lat_x_m;
            r->b_op.tip_y_m = it->lat_y_m;
            r->b_op.true_height_m = it->lat_h_m;
            r->b_op.material = it->lat_mat;
        }
        if (it->n > 0) r->b_t_s = it->s[it->n - 1].t_s;
        r->b_samples += it->n;
        break;
    }
    case IT_RESET:
        afm_chain_reset(r->chain);
        r->b_pop_n = r->b_pop_runs = 0; /* the chain's queue is empty */
        break;
    case IT_FORCES:
        afm_sim_mirror_set(r->mirror, NULL, &it->f, r->b_z);
        afm_chain_set_separation(r->chain, r->b_z); /* a0 may have moved the contact line */
        break;
    case IT_DONE:
        r->b_done = (afm_runner_done){it->seq, it->done_samples, it->done_t_s};
        r->b_done_waiting = true;
        break;
    case IT_ATTACH: {
        afm_runner_model *m = it->model;
        afm_sim_mirror_set(r->mirror, &it->drive, &it->f, it->z0_m);
        r->b_z = it->z0_m;
        if (m && m->chain) {
            afm_chain *old = r->chain;
            r->chain = m->chain;
            m->chain = old;
            afm_chain_attach(m->chain, NULL, NULL, 0);
            r->b_pop_n = r->b_pop_runs = 0; /* the old chain's records went with it */
        }
        if (afm_chain_attach(r->chain, r->mirror, NULL, 0)) r->b_attach_errors++;
        if (m) back_trash(r, m);
        break;
    }
    }
    r->b_items++;
}

int afm_runner_chain_run(afm_runner *r, int max_items) {
    int done = 0;
    ring_item *it;
    while ((max_items <= 0 || done < max_items) && (it = afm_spsc_peek(&r->ring)) != NULL) {
        /* Outputs waiting were made after command b_seq: hand them out before samples of a
         * later command join them. */
        if (done > 0 && ((it->kind == IT_SAMPLES && it->seq != r->b_seq) || it->kind == IT_RESET))
            break; /* a reset clears the chain's queues: what waits goes out first */
        bool is_done = it->kind == IT_DONE;
        back_item(r, it);
        afm_spsc_release(&r->ring);
        done++;
        if (is_done && r->pipelined) break; /* the caller hands out outputs and completion */
    }
    return done;
}

int afm_runner_take_done(afm_runner *r, afm_runner_done *d) {
    if (!r->b_done_waiting) return 0;
    *d = r->b_done;
    r->b_done_waiting = false;
    return 1;
}

bool afm_runner_chain_seq_next(afm_runner *r) {
    const ring_item *it = afm_spsc_peek(&r->ring);
    return it && ((it->kind == IT_SAMPLES && it->seq != r->b_seq) || it->kind == IT_RESET);
}

int afm_runner_take_trash(afm_runner *r, afm_runner_model **m) {
    return afm_spsc_pop(&r->trash, m) ? 1 : 0;
}

void afm_runner_chain_status_get(const afm_runner *r, afm_runner_chain_status *st) {
    st->seq_applied = r->b_seq;
    st->fe_hz = r->b_fe_hz;
    st->op = r->b_op;
    st->t_s = r->b_t_s;
    st->samples = r->b_samples;
    st->attach_errors = r->b_attach_errors;
    st->trash_lost = r->b_trash_lost;
    st->ev_samples = r->b_ev_samples;
    st->chain = afm_chain_stats_get(r->chain);
}

/* ---- front: ring items -------------------------------------------------------------- */

/* Inline: the back runs here, right away. */
static void inline_back(afm_runner *r) {
    if (!r->pipelined) afm_runner_chain_run(r, 0);
}

/* The simulator records into the open item (open_item) and nowhere else: detached
 * before the item goes to the back, and before the simulator is swapped out. */
static void front_events_detach(afm_runner *r) {
    if (r->ev_on) afm_sim_set_events(r->sim, NULL, 0);
}

static void commit_open(afm_runner *r) {
    if (!r->open) return;
    front_events_detach(r);
    afm_spsc_commit(&r->ring);
    r->open = NULL;
    inline_back(r);
}

/* Move waiting change items into the ring. true when none is left. */
static bool flush_pending(afm_runner *r) {
    int i = 0;
    for (; i < r->n_pending; i++) {
        ring_item *it = afm_spsc_reserve(&r->ring);
        if (!it) {
            inline_back(r);
            it = afm_spsc_reserve(&r->ring);
            if (!it) break;
        }
        const pending_item *p = &r->pending[i];
        it->kind = p->kind;
        it->n = 0;
        it->n_zc = 0;
        it->seq = r->seq_applied;
        it->z0_m = p->z_m;
        it->drive = p->drive;
        it->f = p->f;
        it->model = p->model;
        if (p->kind == IT_DONE) {
            it->seq = p->seq;
            it->done_samples = p->done_samples;
            it->done_t_s = p->done_t_s;
        }
        afm_spsc_commit(&r->ring);
        inline_back(r);
    }
    if (i > 0) {
        memmove(r->pending, r->pending + i, (size_t)(r->n_pending - i) * sizeof r->pending[0]);
        r->n_pending -= i;
    }
    return r->n_pending == 0;
}

/* Queue a change for the chain behind everything produced so far. The caller checked that
 * there is room (front_room). */
static void emit(afm_runner *r, int kind, afm_runner_model *m) {
    commit_open(r);
    pending_item *p = &r->pending[r->n_pending++];
    p->kind = kind;
    p->drive = *afm_sim_drive(r->sim);
    p->f = *afm_sim_forces(r->sim);
    p->z_m = afm_sim_separation(r->sim);
    p->model = m;
    p->seq = r->running ? r->tick_seq : r->step_seq; /* DONE: whose budget it was */
    p->done_samples = r->samples;
    p->done_t_s = afm_sim_time(r->sim);
    flush_pending(r);
}

static bool front_room(const afm_runner *r) {
    return r->n_pending + EVENTS_PER_CMD <= PENDING_MAX;
}

/* What is under the tip now, into the item (the values its last sample ran with). */
static void item_lat(const afm_runner *r, ring_item *it) {
    it->lat_on = r->surf != NULL;
    if (!it->lat_on) return;
    it->lat_z_m = r->cfg.drive.separation_m;
    it->lat_x_m = r->lat_x;
    it->lat_y_m = r->lat_y;
    it->lat_h_m = r->lat_h;
    it->lat_mat = r->lat_mat;
}

/* The FM loops' state into a new item (issue 32: the harmonics records carry it). */
static void item_fm(const afm_runner *r, ring_item *it) {
    if (!r->fm_on || it->drive.n < 1) {
        it->fm_lock = it->fm_drive = -1;
        it->fm_shift_hz = it->fm_phase_error_deg = NAN;
        return;
    }
    it->fm_lock = (int)r->fm.lock;
    it->fm_drive = (int)r->fm.c.drive;
    it->fm_shift_hz = it->drive.omega_rad_s[0] / two_pi - r->fm.f_center_hz;
    it->fm_phase_error_deg = r->fm.phase_error_deg;
}

/* The item to write samples into (reserving one), or NULL when the ring is full. */
static ring_item *open_item(afm_runner *r) {
    ring_item *it = r->open;
    if (it && (it->n == SLOT || it->n_zc == ZC_MAX || it->n_lc == ZC_MAX)) {
        commit_open(r);
        it = NULL;
    }
    if (it) return it;
    it = afm_spsc_reserve(&r->ring);
    if (!it) {
        inline_back(r);
        it = afm_spsc_reserve(&r->ring);
        if (!it) return NULL;
    }
    it->kind = IT_SAMPLES;
    it->n = 0;
    it->n_zc = 0;
    it->n_lc = 0;
    it->seq = r->seq_applied;
    it->z0_m = afm_sim_separation(r->sim);
    it->drive = *afm_sim_drive(r->sim);
    it->model = NULL;
    it->ev_begin = it->ev_end = 0;
    it->ev_broken = false;
    it->ev_step0 = 0;
    /* Only a scheme that records gets the ring: marking its SLOT entries empty touches 64 kB
     * of the item per item, a cache line per sample the fast scheme would pay for nothing (a
     * hand-over to the accurate scheme records from the next item on). */
    if (r->ev_on && strcmp(afm_sim_scheme_name(r->sim), "fast") != 0)
        afm_sim_set_events(r->sim, it->ev, SLOT);
    item_lat(r, it);
    item_fm(r, it);
    r->open = it;
    return it;
}

/* After a run of k samples into it at it->n: where its samples' records are (ring_item.ev).
 * The first run whose first sample has a record sets the base; later runs extend it while
 * the steps stay consecutive (no blow-up). One look-up per run, none per sample. */
static void front_events_note(afm_runner *r, ring_item *it, int k) {
    const int n0 = it->n;
    if (it->ev_broken) return;
    if (it->ev_end > it->ev_begin) {
        if (it->ev_end == n0) it->ev_end = n0 + k;
        return;
    }
    const afm_step_events *e = afm_sim_events_at(r->sim, it->s[n0].t_s);
    if (!e || e < it->ev || e >= it->ev + SLOT) return;
    it->ev_step0 = e->step - n0;
    it->ev_begin = n0;
    it->ev_end = n0 + k;
}

/* ---- internal FM control ----------------------------------------------------------- */

/* Start (or, after a reload, restart) the FM loops of r->cfg on r->sim, or turn them off
 * when the config does not ask for them. No allocation. 0, or -1 with err (nothing changed
 * then but fm_on cleared). */
static int fm_setup(afm_runner *r, char *err, size_t errlen) {
    r->fm_on = false;
    const afm_config *c = &r->cfg;
    if (c->fm.control != AFM_FM_CONTROL_INTERNAL) return 0;
    const afm_drive *d = afm_sim_drive(r->sim);
    if (d->n < 1) {
        afm_err_set(err, errlen, "fm.control = \"internal\": the drive has no tone 0 to control");
        return -1;
    }
    afm_fm_plant p;
    afm_fm_plant_of(afm_sim_model(r->sim), &p);
    afm_phase_gen_reset(&r->fm_pg, c->sim.sample_rate_hz);
    if (afm_lockin_init(&r->fm_lk, &c->lockin, afm_sim_dt(r->sim), err, errlen) ||
        afm_fm_init(&r->fm, &c->fm, &c->lockin, &p, c->sim.sample_rate_hz, p.f0_hz, p.f0_hz,
                    fmin(d->amp_m[0], c->fm.drive_max_m), err, errlen))
        return -1;
    if (afm_sim_set_tone(r->sim, 0, r->fm.drive_m, r->fm.freq_hz) != AFM_SIM_OK) {
        afm_err_set(err, errlen, "fm: tone 0 (%g m, %g Hz) refused by the simulator", r->fm.drive_m,
                    r->fm.freq_hz);
        return -1;
    }
    r->fm_hold_pending = !(c->fm.amplitude_setpoint_m > 0);
    r->fm_on = true;
    return 0;
}

/* Feed the k samples s[0..k) just run to the controllers' lock-in (fm_lk) at tone 0. */
static void ctl_lockin_feed(afm_runner *r, const afm_sample *s, int k) {
    /* The reference phase as the chain computes it (afm_phase_gen: from the sample index, so
     * that the slices the runner happens to cut change no bit: replay --block 700 and 1024,
     * and lockstep, image a scan alike). A tone-0 change right before s[0] (an NCO step, a
     * dither) is followed O(1) (afm_lockin_rebase), a jump by a retune. */
    if (k <= 0) return;
    afm_phase_change ch = afm_phase_gen_run(&r->fm_pg, afm_sim_drive(r->sim), s, k, r->fm_th);
    for (int i = 0; i < k; i++)
        r->fm_u[i] = s[i].x_m;
    if (ch == AFM_PHASE_STEP) {
        const double wdt = r->fm_pg.wdt;
        if (!afm_lockin_rebase(&r->fm_lk, r->fm_th[0] - wdt, wdt)) afm_lockin_retune(&r->fm_lk);
    } else if (ch == AFM_PHASE_JUMP) {
        afm_lockin_retune(&r->fm_lk);
    }
    afm_lockin_push_n(&r->fm_lk, r->fm_u, r->fm_th, k);
}

/* The state went back to rest (a reset, a blow-up): the controllers' lock-in starts over,
 * and the self-excited drive's delay line, whose samples no longer continue, refills (the
 * counter keeps the frequency in force). */
static void ctl_restart(afm_runner *r) {
    if (!r->fm_on && !r->zc_on) return;
    afm_lockin_reset(&r->fm_lk);
    afm_phase_gen_reset(&r->fm_pg, r->cfg.sim.sample_rate_hz);
    if (r->fm_on && r->fm.c.drive == AFM_FM_DRIVE_SELF)
        afm_fm_self_init(&r->fm.self, r->cfg.sim.sample_rate_hz, r->fm.freq_hz,
                         r->fm.c.pll_bandwidth_hz);
}

/* After the k samples s[0..k) just run: feed the FM lock-in; at an update boundary (every
 * update_samples samples counted from create) update the loops and set tone 0, phase
 * continuous. The open item is committed first: an item carries one drive. */
static void fm_after(afm_runner *r, const afm_sample *s, int k) {
    const afm_drive *d = afm_sim_drive(r->sim);
    if (k <= 0) return;
    ctl_lockin_feed(r, s, k);
    const bool self = r->fm.c.drive == AFM_FM_DRIVE_SELF;
    if (self) /* the self-excited drive's delay line: one store a sample */
        for (int i = 0; i < k; i++)
            afm_fm_self_push(&r->fm.self, s[i].x_m);
    const int u = r->fm.c.update_samples;
    if (r->samples % u != 0) return;
    double a, lag;
    afm_lockin_polar(&r->fm_lk, &a, &lag);
    const double dt = u * afm_sim_dt(r->sim);
    /* self-excited: count the oscillation's frequency first, as afm_fm_run does */
    if (self) r->fm.self_ok = afm_fm_self_measure(&r->fm.self, r->fm.freq_hz, dt);
    afm_fm_update(&r->fm, a, lag, dt);
    if (r->fm_hold_pending && r->fm.lock == AFM_FM_LOCKED) {
        afm_fm_hold_amplitude(&r->fm, a);
        r->fm_hold_pending = false;
    }
    if (self && r->fm.self_ok) {
        /* re-synthesised every update (afm_fm_run's order): tone 0 at the deflection's phase
         * plus the set-point, the counted frequency and the amplitude loop's drive -- a phase
         * jump, which the lock-ins here and in the chain follow by a retune (the phase does
         * not continue: afm_phase_gen says STEP, the O(1) rebase declines). No NCO quantum:
         * the tone changes every update anyway. */
        commit_open(r);
        if (afm_sim_set_tone_phase(r->sim, 0, r->fm.drive_m, r->fm.freq_hz,
                                   r->fm.drive_phase_rad) != AFM_SIM_OK) {
            r->fm_tone_refused++;
            return;
        }
        r->fm_tone_changes++;
        return;
    }
    /* The NCO's resolution: tone 0 moves only when the loop's frequency leaves the quantum
     * it is in. A locked PLL moves by far less than that per update; each step costs the
     * integrator a drive-table recompute and every tone-0 estimator (here and in the chain)
     * an O(1) rebase (afm_lockin_rebase above; before the rebase a table rebuild, which at
     * every update took ~40 % of the per-sample budget on this VM). */
    const double q = AFM_RUNNER_FM_NCO_HZ;
    const double f_set = nearbyint(r->fm.freq_hz / q) * q;
    const double f_now = d->omega_rad_s[0] / two_pi;
    const bool f_move = fabs(f_set - f_now) >= 0.5 * q;
    const bool d_move = fabs(r->fm.drive_m - d->amp_m[0]) > AFM_RUNNER_FM_DRIVE_REL * d->amp_m[0];
    if (!f_move && !d_move) return;
    commit_open(r);
    if (afm_sim_set_tone(r->sim, 0, d_move ? r->fm.drive_m : d->amp_m[0], f_move ? f_set : f_now) !=
        AFM_SIM_OK) {
        r->fm_tone_refused++; /* kept at the last tone 0 the simulator took */
        return;
    }
    r->fm_tone_changes++;
}

/* ---- internal AM Z control (issue 18) ---------------------------------------------- */

static void set_z(afm_runner *r, double z);

/* The stage Z: the config's with a sample (the simulator has the gap), else the simulator's. */
static double stage_z(const afm_runner *r) {
    return r->surf ? r->cfg.drive.separation_m : afm_sim_separation(r->sim);
}

/* The lock-in's settling, in samples from now: 12 time constants per filter order, as
 * afm_scan_run rings up before its engage, plus 5 envelope times of mode 1 (Q / (pi f0))
 * for the lever to ring up from rest. */
static long long zc_settle_samples(const afm_runner *r) {
    const afm_config *c = &r->cfg;
    afm_fm_plant p;
    afm_fm_plant_of(afm_sim_model(r->sim), &p);
    double t = 12.0 * c->lockin.time_constant_s * c->lockin.order +
               (p.f0_hz > 0 ? 5.0 * p.q / (3.14159265358979323846 * p.f0_hz) : 0.0);
    return (long long)ceil(t / afm_sim_dt(r->sim));
}

/* Start (or, after a reload, restart) the AM Z loop of r->cfg with free amplitude a0_m (the
 * model's, afm_runner_model_build), from the stage Z now, or turn it off when the config does
 * not ask for it. No allocation. 0, or -1 with err (zc_on cleared). */
static int zc_setup(afm_runner *r, double a0_m, char *err, size_t errlen) {
    r->zc_on = false;
    const afm_config *c = &r->cfg;
    if (c->am.control != AFM_AM_CONTROL_INTERNAL) return 0;
    if (afm_sim_drive(r->sim)->n < 1 || !(a0_m > 0)) {
        afm_err_set(err, errlen,
                    "am.control = \"internal\": no free amplitude A0 (the drive has no tone 0)");
        return -1;
    }
    if (afm_lockin_init(&r->fm_lk, &c->lockin, afm_sim_dt(r->sim), err, errlen)) return -1;
    afm_pi_cfg pc = {.kp = c->am.kp,
                     .ki_hz = c->am.ki_hz,
                     .setpoint_ratio = c->am.setpoint_ratio,
                     .z_rate_max_m_s = c->am.z_rate_max_m_s,
                     .z_min_m = c->am.z_min_m,
                     .z_max_m = c->am.z_max_m};
    afm_pi_init(&r->zc, &pc, a0_m, stage_z(r));
    r->zc_a_m = NAN;
    r->zc_hold_until = r->samples + zc_settle_samples(r);
    afm_phase_gen_reset(&r->fm_pg, c->sim.sample_rate_hz);
    r->zc_on = true;
    return 0;
}

/* After the k samples s[0..k) just run: feed the lock-in; at an update boundary (every LAT
 * samples counted from create, the moving tip's grid) once the lock-in has settled, one PI
 * update on its amplitude, and Z (the gap follows: Z - z_s under the tip). */
static void zc_after(afm_runner *r, const afm_sample *s, int k) {
    if (k <= 0 || afm_sim_drive(r->sim)->n < 1) return; /* no tone 0: the loop holds */
    ctl_lockin_feed(r, s, k);
    if (r->samples % LAT != 0 || r->samples < r->zc_hold_until) return;
    r->zc_a_m = afm_lockin_amplitude(&r->fm_lk);
    double z = afm_pi_update(&r->zc, r->zc_a_m, LAT * afm_sim_dt(r->sim));
    if (z != stage_z(r)) {
        set_z(r, z);
        r->zc_updates++;
    }
}

/* ---- create / destroy --------------------------------------------------------------- */

static int lat_materials(const afm_runner *r, const afm_config *c, afm_force_params *out, char *err,
                         size_t errlen);
static void lat_place(afm_runner *r, double x, double y, bool emit_forces, bool force);

bool afm_runner_step_events(const afm_config *cfg) {
    const char *env = getenv("AFMTWIN_STEP_EVENTS");
    if (cfg->sim.step_events == AFM_STEP_EVENTS_OFF || (env && strcmp(env, "0") == 0)) return false;
    if (cfg->sim.integrator == AFM_INTEGRATOR_REFERENCE) return true;
    return cfg->sim.integrator == AFM_INTEGRATOR_RT && !cfg->thermal.enabled;
}

afm_runner *afm_runner_create_pipelined(const afm_config *cfg, int block_max, bool lockstep,
                                        bool pipelined, int ring_items, char *err, size_t errlen) {
    if (!cfg || block_max < 1 || block_max > (1 << 24)) {
        afm_err_set(err, errlen, "runner: no config, or block_max %d not in 1..%d", block_max,
                    1 << 24);
        return NULL;
    }
    if (ring_items < 2 || ring_items > 65536) {
        afm_err_set(err, errlen, "runner: ring of %d items not in 2..65536", ring_items);
        return NULL;
    }
    afm_runner *r = calloc(1, sizeof *r);
    afm_runner_model *m = NULL;
    if (!r) {
        afm_err_set(err, errlen, "out of memory");
        return NULL;
    }
    if (afm_spsc_init(&r->ring, (size_t)ring_items, sizeof(ring_item), err, errlen) ||
        afm_spsc_init(&r->trash, TRASH_CAP, sizeof(afm_runner_model *), err, errlen))
        goto fail;
    m = afm_runner_model_build(cfg, true, err, errlen);
    if (!m || afm_cmd_check_cfg_drive(afm_sim_model(m->sim), &cfg->drive, err, errlen)) goto fail;
    r->cfg = *cfg;
    r->sim = m->sim;
    r->chain = m->chain;
    r->surf = m->surf;
    double a0_m = m->a0_m;
    m->sim = NULL;
    m->chain = NULL;
    m->surf = NULL;
    afm_runner_model_destroy(&m);
    /* the tip over (0, 0) of the sample, if any: before the back's mirror copies the sim */
    if (r->surf) {
        if (lat_materials(r, &r->cfg, r->mat, err, errlen)) goto fail;
        r->lat_mat = -1;
        lat_place(r, 0.0, 0.0, false, true);
        r->lat_line = r->lat_pixel = -1;
    }
    r->mirror = afm_sim_mirror_create(r->sim, err, errlen);
    if (!r->mirror) goto fail;
    r->b_z = afm_sim_separation(r->sim);
    if (afm_chain_attach(r->chain, r->mirror, err, errlen)) goto fail;
    r->block_max = block_max;
    r->lockstep = lockstep;
    r->pipelined = pipelined;
    r->running = true;
    r->seq_applied = -1;
    r->b_seq = -1;
    r->b_t_s = afm_sim_time(r->sim);
    r->last_blowup_t_s = NAN;
    r->ev_on = afm_runner_step_events(cfg);
    if (fm_setup(r, err, errlen)) goto fail; /* may set tone 0: before the back's view */
    if (zc_setup(r, a0_m, err, errlen)) goto fail;
    {
        const afm_drive *d = afm_sim_drive(r->sim);
        r->b_fe_hz = d->n > 0 ? d->omega_rad_s[0] / two_pi : 0.0;
        back_oppoint(r, d);
        r->b_op.fm_lock = r->b_op.fm_drive = -1;
        r->b_op.fm_shift_hz = r->b_op.fm_phase_error_deg = NAN;
    }
    return r;
fail:
    afm_runner_model_destroy(&m);
    afm_runner_destroy(&r);
    return NULL;
}

afm_runner *afm_runner_create(const afm_config *cfg, int block_max, bool lockstep, char *err,
                              size_t errlen) {
    return afm_runner_create_pipelined(cfg, block_max, lockstep, false, 4, err, errlen);
}

void afm_runner_destroy(afm_runner **rp) {
    if (!rp || !*rp) return;
    afm_runner *r = *rp;
    if (r->ring.slots) { /* models still travelling */
        if (r->open) afm_spsc_commit(&r->ring);
        ring_item *it;
        while ((it = afm_spsc_peek(&r->ring)) != NULL) {
            if (it->kind == IT_ATTACH) afm_runner_model_destroy(&it->model);
            afm_spsc_release(&r->ring);
        }
    }
    for (int i = 0; i < r->n_pending; i++)
        afm_runner_model_destroy(&r->pending[i].model);
    for (int i = 0; i < r->n_held; i++)
        afm_runner_model_destroy(&r->held[i]);
    if (r->trash.slots) {
        afm_runner_model *m;
        while (afm_spsc_pop(&r->trash, &m))
            afm_runner_model_destroy(&m);
    }
    afm_chain_destroy(&r->chain);
    afm_surface_destroy(&r->surf);
    afm_sim_destroy(&r->mirror);
    afm_sim_destroy(&r->sim);
    afm_spsc_destroy(&r->ring);
    afm_spsc_destroy(&r->trash);
    free(r);
    *rp = NULL;
}

int afm_runner_set_time(afm_runner *r, double t_s, char *err, size_t errlen) {
    if (r->samples != 0 || r->open || r->n_pending || afm_spsc_count(&r->ring) ||
        afm_sim_set_time(r->sim, t_s) != AFM_SIM_OK) {
        afm_err_set(err, errlen, "runner: model time %g s: only 0..1e9 s, before the first run",
                    t_s);
        return -1;
    }
    r->b_t_s = t_s;
    return 0;
}

/* Whether a FORCE param moves the free amplitude A0: only the squeeze film's constants.
 * A0 is the amplitude far from the sample (afm_a0.h: Z 1 um, the gap-dependent tip forces
 * -- vdW/DMT contact and its Hamaker constant, modulus and a0, viscoelastic, capillary,
 * electrostatic, the tip radius they scale with -- switched off), so a tip-sample force
 * constant leaves A0 as it is, bit for bit (tests/test_runner.c); the squeeze film damps
 * the beam at any Z and moves it (~10 % on default.conf). */
static bool param_moves_a0(const afm_cmd_param *p) {
    static const char sq[] = "forces.squeeze.";
    for (int i = 0; i < p->n; i++) {
        const afm_param_def *d = &afm_param_table(NULL)[p->entry[i]];
        if (d->effect >= AFM_PARAM_DAMPING || !strncmp(d->name, sq, sizeof sq - 1)) return true;
    }
    return false;
}

bool afm_runner_dither_moves_a0(const afm_config *cfg, const afm_cmd_dither *now,
                                const afm_cmd *c) {
    if (cfg->am.control != AFM_AM_CONTROL_INTERNAL || c->kind != AFM_CMD_DITHER) return false;
    const afm_cmd_dither *d = &c->u.dither;
    if (d->n_tones < 1 || !(d->amplitude_m[0] > 0)) return false; /* silent: no A0 to hold */
    return now->n_tones < 1 || d->frequency_hz[0] != now->frequency_hz[0] ||
           d->amplitude_m[0] != now->amplitude_m[0];
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
        } else if (e == AFM_PARAM_FORCE && t.am.control == AFM_AM_CONTROL_INTERNAL &&
                   param_moves_a0(&c->u.param)) {
            need = 1; /* only for its A0: the squeeze film's constants move A0 by ~10 % */
        }
    }
    if (new_chain) *new_chain = nc;
    return need;
}

/* ---- the sample under the tip (issue 18) ------------------------------------------- */

/* The integrator's separation for the stage Z z: the gap's Z - z_s under the tip, held at 0
 * where the surface rises past the stage (the simulator takes no negative Z). */
static double lat_gap(afm_runner *r, double z) {
    if (!r->surf) return z;
    double g = z - r->lat_h;
    if (g >= 0) return g;
    r->lat_clamps++;
    return 0.0;
}

/* Every material's force constants for config c on the running model, into out[]. No
 * allocation. 0, or -1 with err. */
static int lat_materials(const afm_runner *r, const afm_config *c, afm_force_params *out, char *err,
                         size_t errlen) {
    for (int k = 0; k <= c->sample.n_materials && k <= AFM_MAX_MATERIALS; k++) {
        afm_cfg_forces f;
        afm_surface_material_forces(&c->sample, &c->forces, k, &f);
        if (afm_twin_forces(c, afm_sim_model(r->sim), &f, &out[k], err, errlen)) return -1;
    }
    return 0;
}

/* The tip to (x, y): the simulator gets the material there (its forces; the chain follows,
 * IT_FORCES, when emit_forces) and the gap for the stage Z; the next samples' item carries
 * the gap. force: set the forces even when the material is the same (after a swap or a
 * force change). The caller keeps room for one change item. */
static void lat_place(afm_runner *r, double x, double y, bool emit_forces, bool force) {
    r->lat_x = x;
    r->lat_y = y;
    r->lat_h = afm_surface_height(r->surf, x, y);
    int m = afm_surface_material(r->surf, x, y);
    if (m < 0 || m > r->cfg.sample.n_materials) m = 0; /* not reached: the config is checked */
    if (m != r->lat_mat || force) {
        r->lat_mat = m;
        if (afm_sim_set_forces(r->sim, &r->mat[m]) == AFM_SIM_OK && emit_forces)
            emit(r, IT_FORCES, NULL);
    }
    double g = lat_gap(r, r->cfg.drive.separation_m);
    if (g != afm_sim_separation(r->sim) || force) afm_sim_set_separation(r->sim, g);
}

/* At an update boundary: where the motion in force puts the tip, at the middle of the LAT
 * samples that follow (afm_scan's convention), and there. */
static void lat_update(afm_runner *r) {
    double t = ((double)(r->samples - r->lat_s0) + 0.5 * LAT) * afm_sim_dt(r->sim);
    double x = r->lat_x, y = r->lat_y;
    const double P = AFM_CMD_SCAN_POS_MAX_M;
    switch (r->lat_mode) {
    case AFM_SCAN_MOVE: {
        double d = r->lat_speed * t;
        if (d >= r->lat_dist) {
            x = r->lat_tx;
            y = r->lat_ty;
            r->lat_mode = AFM_SCAN_HOLD;
        } else {
            x = r->lat_x0 + (r->lat_tx - r->lat_x0) * (d / r->lat_dist);
            y = r->lat_y0 + (r->lat_ty - r->lat_y0) * (d / r->lat_dist);
        }
        break;
    }
    case AFM_SCAN_VELOCITY:
        x = r->lat_x0 + r->lat_vx * t;
        y = r->lat_y0 + r->lat_vy * t;
        if (fabs(x) > P || fabs(y) > P) { /* the range's end: hold there */
            x = fmin(fmax(x, -P), P);
            y = fmin(fmax(y, -P), P);
            r->lat_mode = AFM_SCAN_HOLD;
        }
        break;
    case AFM_SCAN_RASTER: {
        int line, pixel;
        bool back;
        afm_scan_position(&r->lat_sc, t, &x, &y, &line, &pixel, &back);
        if (line >= r->lat_sc.lines) { /* done: hold where the last retrace ended */
            r->lat_mode = AFM_SCAN_HOLD;
            return;
        }
        r->lat_line = line;
        r->lat_pixel = pixel;
        r->lat_retrace = back;
        break;
    }
    default:
        return;
    }
    lat_place(r, x, y, true, false);
}

/* The sample's materials and the tip's place on r->sim again: after a model swap or a
 * force change (mat[] already holds the new constants). */
static void lat_refresh(afm_runner *r) {
    if (r->surf) lat_place(r, r->lat_x, r->lat_y, true, true);
}

static int apply_scan(afm_runner *r, const afm_cmd_lateral *c, char *err, size_t errlen) {
    if (!r->surf) {
        afm_err_set(err, errlen,
                    "the config has no sample group: nothing under the tip to scan "
                    "(config/README.md, sample)");
        return -1;
    }
    r->lat_s0 = r->samples;
    r->lat_x0 = r->lat_x;
    r->lat_y0 = r->lat_y;
    r->lat_line = r->lat_pixel = -1;
    r->lat_retrace = false;
    r->lat_mode = AFM_SCAN_HOLD;
    switch (c->mode) {
    case AFM_SCAN_MOVE:
        r->lat_tx = c->x_m;
        r->lat_ty = c->y_m;
        r->lat_speed = c->speed_m_s;
        r->lat_dist = hypot(c->x_m - r->lat_x, c->y_m - r->lat_y);
        if (c->speed_m_s > 0 && r->lat_dist > 0)
            r->lat_mode = AFM_SCAN_MOVE;
        else
            lat_place(r, c->x_m, c->y_m, true, false); /* at once */
        break;
    case AFM_SCAN_VELOCITY:
        r->lat_vx = c->vx_m_s;
        r->lat_vy = c->vy_m_s;
        if (c->vx_m_s != 0 || c->vy_m_s != 0) r->lat_mode = AFM_SCAN_VELOCITY;
        break;
    case AFM_SCAN_RASTER:
        r->lat_sc = (afm_scan_cfg){.x0_m = c->x_m,
                                   .y0_m = c->y_m,
                                   .size_x_m = c->size_x_m,
                                   .size_y_m = c->size_y_m,
                                   .pixels = c->pixels,
                                   .lines = c->lines,
                                   .line_rate_hz = c->line_rate_hz,
                                   .engage_s = 0.0,
                                   .update_samples = LAT};
        lat_place(r, c->x_m, c->y_m, true, false); /* to the first line's start */
        r->lat_mode = AFM_SCAN_RASTER;
        r->lat_line = r->lat_pixel = 0;
        break;
    default: /* HOLD */
        break;
    }
    return 0;
}

/* ---- commands ----------------------------------------------------------------------- */

/* Z now; the chain follows with the next samples (their item carries Z). With a sample the
 * integrator gets the gap Z - z_s under the tip; cfg.drive.separation_m is the stage Z. */
static void set_z(afm_runner *r, double z) {
    afm_sim_set_separation(r->sim, lat_gap(r, z)); /* z is validated */
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
            afm_err_set(err, errlen, "dither: tone %d rejected by the simulator", j);
            return -1;
        }
    }
    /* Tones the command leaves out stop: removed from the drive, so that the integrator no
     * longer pays for them (a silent tone cost as much as a loud one: +40 % per sample with
     * four tones in contact); a later command that names them starts them at its phase. */
    if (d->n_tones < n_run) afm_sim_drop_tones(s, d->n_tones);
    return 0;
}

static void apply_setpoint(afm_runner *r, const afm_cmd_setpoint *p) {
    double z = r->surf ? r->cfg.drive.separation_m : afm_sim_separation(r->sim); /* stage Z */
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

/* What afm_chain_attach will check of the new simulator (the chain is the back's). */
static int attach_ok(const afm_sim *s, char *err, size_t errlen) {
    const afm_force_params *f = afm_sim_forces(s);
    afm_cycle tmp;
    return afm_cycle_init(&tmp, afm_force_contact_x(f, afm_sim_separation(s)), f->cos_alpha, err,
                          errlen);
}

/* Swap model m in: time always continues; `what` as afm_sim_continue. m travels to the
 * back (ATTACH), which swaps its chain in (if any) and hands m back as trash holding the
 * objects swapped out (with take_surf, a reload's, the sample too: m's goes in). */
static int swap_in(afm_runner *r, afm_runner_model *m, unsigned what, bool take_surf, char *err,
                   size_t errlen) {
    if (afm_sim_continue(m->sim, r->sim, what) != AFM_SIM_OK) {
        afm_err_set(err, errlen,
                    "the new model has %d modes, the running one %d: cannot carry "
                    "the state over",
                    afm_sim_model(m->sim)->n, afm_sim_model(r->sim)->n);
        return -1;
    }
    if (attach_ok(m->sim, err, errlen)) return -1;
    front_events_detach(r); /* the open item is committed (emit) before m->sim runs */
    afm_sim *old_sim = r->sim;
    r->sim = m->sim;
    m->sim = old_sim;
    if (r->zc_on && m->a0_m > 0) /* a new model: its free amplitude is the reference */
        r->zc.a_set_m = r->zc.c.setpoint_ratio * m->a0_m;
    if (take_surf) {
        afm_surface *old_surf = r->surf;
        r->surf = m->surf;
        m->surf = old_surf;
    }
    emit(r, IT_ATTACH, m);
    r->swaps++;
    return 0;
}

static int apply_param(afm_runner *r, const afm_cmd_param *p, afm_runner_model **model, char *err,
                       size_t errlen) {
    afm_config t = r->cfg;
    afm_param_effect e;
    if (afm_param_apply(&t, p, &e, err, errlen)) return -1;
    bool has_z = false;
    for (int i = 0; i < p->n; i++)
        if (afm_param_table(NULL)[p->entry[i]].effect == AFM_PARAM_SEPARATION) has_z = true;
    if (e >= AFM_PARAM_DAMPING) {
        if (!model || !*model) {
            afm_err_set(err, errlen,
                        "param: a %s change needs a model built off the real-time "
                        "thread (afm_runner_model_build)",
                        e == AFM_PARAM_DAMPING ? "damping" : "geometry");
            return -1;
        }
        if (e == AFM_PARAM_GEOMETRY && !(*model)->chain) {
            afm_err_set(err, errlen, "param: a geometry change needs a model with a new chain");
            return -1;
        }
        if (e == AFM_PARAM_DAMPING && (*model)->chain) {
            afm_err_set(err, errlen, "param: a damping change keeps the chain; the model has one");
            return -1;
        }
        unsigned what = AFM_SIM_KEEP_DRIVE | (e == AFM_PARAM_DAMPING ? AFM_SIM_KEEP_STATE : 0);
        if (swap_in(r, *model, what, false, err, errlen)) return -1;
        *model = NULL; /* travelling to the back */
    } else if (e == AFM_PARAM_FORCE && r->surf) {
        /* every material follows the base sample's forces (afm_surface_material_forces) */
        if (lat_materials(r, &t, r->mat_tmp, err, errlen)) return -1;
        memcpy(r->mat, r->mat_tmp, sizeof r->mat);
    } else if (e == AFM_PARAM_FORCE) {
        afm_force_params f;
        if (afm_twin_forces(&t, afm_sim_model(r->sim), NULL, &f, err, errlen)) return -1;
        if (afm_sim_set_forces(r->sim, &f) != AFM_SIM_OK) {
            afm_err_set(err, errlen, "param: the simulator refused the new force constants");
            return -1;
        }
        emit(r, IT_FORCES, NULL);
    }
    /* The AM Z loop's reference follows the forces' A0 (the model, built for it off the
     * real-time thread, is not swapped in: it goes back to the caller). */
    if (e == AFM_PARAM_FORCE && r->zc_on && model && *model && (*model)->a0_m > 0)
        r->zc.a_set_m = r->zc.c.setpoint_ratio * (*model)->a0_m;
    r->cfg = t;
    if (r->surf && e >= AFM_PARAM_DAMPING) { /* the new model's plate: the materials again */
        char why[AFM_ERR_LEN];
        if (lat_materials(r, &r->cfg, r->mat_tmp, why, sizeof why) == 0)
            memcpy(r->mat, r->mat_tmp, sizeof r->mat);
    }
    if (r->surf && e >= AFM_PARAM_FORCE) lat_refresh(r); /* the material's forces, the gap */
    if (has_z) {
        r->ramping = false;
        set_z(r, t.drive.separation_m);
    } else if (!r->surf) {
        r->cfg.drive.separation_m = afm_sim_separation(r->sim);
    }
    return 0;
}

int afm_runner_apply(afm_runner *r, const afm_cmd *c, afm_runner_model **model, char *err,
                     size_t errlen) {
    afm_cmd_limits lim = {.sample_rate_hz = r->cfg.sim.sample_rate_hz,
                          .model = afm_sim_model(r->sim)};
    if (afm_cmd_validate(c, &lim, err, errlen)) return -1;
    commit_open(r);
    flush_pending(r);
    if (!front_room(r)) {
        afm_err_set(err, errlen, "%s: the output chain is %d changes behind; try again later",
                    afm_cmd_kind_name(c->kind), r->n_pending);
        return AFM_RUNNER_EBUSY;
    }
    bool sets_z = c->kind == AFM_CMD_SETPOINT;
    for (int i = 0; c->kind == AFM_CMD_PARAM && i < c->u.param.n; i++)
        if (afm_param_table(NULL)[c->u.param.entry[i]].effect == AFM_PARAM_SEPARATION)
            sets_z = true;
    if (sets_z && r->zc_on) {
        afm_err_set(err, errlen,
                    "%s: Z is under the daemon's AM control (am.control = \"internal\"); set "
                    "am.control = \"none\" to command Z",
                    afm_cmd_kind_name(c->kind));
        return -1;
    }
    if (c->kind == AFM_CMD_DITHER && r->fm_on) {
        afm_err_set(err, errlen,
                    "tone 0 is under the daemon's FM control (fm.control = \"internal\"); "
                    "set fm.control = \"none\" to command the drive");
        return -1;
    }
    switch (c->kind) {
    case AFM_CMD_DITHER:
        if (apply_dither(r, &c->u.dither, err, errlen)) return -1;
        /* A new tone 0 moves the free amplitude: the AM Z loop's reference follows, from
         * the A0 computed off the real-time thread (afm_runner_model_a0; the model goes
         * back to the caller). Without one the set-point stays. */
        if (r->zc_on && model && *model && (*model)->a0_m > 0)
            r->zc.a_set_m = r->zc.c.setpoint_ratio * (*model)->a0_m;
        break;
    case AFM_CMD_SETPOINT:
        apply_setpoint(r, &c->u.setpoint);
        break;
    case AFM_CMD_PARAM:
        if (apply_param(r, &c->u.param, model, err, errlen)) return -1;
        break;
    case AFM_CMD_CONTROL:
        switch (c->u.control.action) {
        case AFM_CTL_RUN:
            r->running = true;
            r->step_budget = 0;
            break;
        case AFM_CTL_PAUSE:
            r->running = false;
            break;
        case AFM_CTL_RESET:
            afm_sim_reset(r->sim);
            ctl_restart(r);
            if (r->zc_on) r->zc_hold_until = r->samples + zc_settle_samples(r);
            emit(r, IT_RESET, NULL);
            r->ramping = false;
            break;
        case AFM_CTL_STEP:
            r->running = false;
            r->step_seq = c->seq;
            if (r->step_budget > LLONG_MAX - c->u.control.n_samples)
                r->step_budget = LLONG_MAX;
            else
                r->step_budget += c->u.control.n_samples;
            break;
        }
        break;
    case AFM_CMD_SCAN:
        if (apply_scan(r, &c->u.scan, err, errlen)) return -1;
        break;
    case AFM_CMD_TICK:
        if (!r->lockstep) {
            afm_err_set(err, errlen, "tick: the twin is not in lockstep mode");
            return -1;
        }
        r->tick_seq = c->seq;
        if (r->tick_budget > LLONG_MAX - c->u.tick.n_samples)
            r->tick_budget = LLONG_MAX;
        else
            r->tick_budget += c->u.tick.n_samples;
        break;
    case AFM_CMD_RELOAD:
        if (!model || !*model || !(*model)->chain) {
            afm_err_set(err, errlen, "reload: needs a model with a chain (afm_runner_model_build)");
            return -1;
        }
        {
            afm_config next = (*model)->cfg;
            double a0_m = (*model)->a0_m;
            if (swap_in(r, *model, 0, true, err, errlen)) return -1;
            *model = NULL;
            r->cfg = next;
            /* the new file's sample (or none): the tip stays where it is, holding */
            r->lat_mode = AFM_SCAN_HOLD;
            r->lat_line = r->lat_pixel = -1;
            if (r->surf) {
                char why[AFM_ERR_LEN];
                (void)lat_materials(r, &r->cfg, r->mat, why, sizeof why); /* checked by the build */
                r->lat_mat = -1;
                lat_place(r, r->lat_x, r->lat_y, true, true);
            } else {
                r->lat_x = r->lat_y = r->lat_h = 0.0;
                r->lat_mat = 0;
            }
            /* the new config's FM (or none); a refusal leaves the drive of the file */
            char ferr[AFM_ERR_LEN];
            if (fm_setup(r, ferr, sizeof ferr)) r->fm_tone_refused++;
            (void)zc_setup(r, a0_m, ferr, sizeof ferr); /* the new config's AM Z loop (or none) */
        }
        r->ramping = false;
        break;
    }
    if (c->kind != AFM_CMD_RELOAD) r->seq_applied = c->seq; /* a reload is no sender's */
    r->applied++;
    r->blowup_streak = 0; /* something changed: a new streak must recur on its own */
    if (c->kind == AFM_CMD_CONTROL && c->u.control.action == AFM_CTL_RUN) r->auto_paused = false;
    /* Inline: what was swapped out is back already; hand it to the caller. */
    if (!r->pipelined && model && !*model) afm_runner_take_trash(r, model);
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
    bool was_running = r->running; /* the budget this run draws on (it may pause itself) */
    if (want > b) want = b;
    long long done = 0;
    bool flushed = flush_pending(r); /* also with n = 0: a completion waiting for ring space */
    if (want > 0 && !flushed) {
        r->stalls++;
        return 0;
    }
    while (done < want) {
        if (r->ramping && r->samples % AFM_RUNNER_RAMP_SAMPLES == 0) ramp_update(r);
        if (r->lat_mode != AFM_SCAN_HOLD && r->samples % LAT == 0) {
            /* the tip moves: a material change needs room for its change item */
            if (r->n_pending > 0 && !flush_pending(r)) {
                r->stalls++;
                break;
            }
            lat_update(r);
        }
        ring_item *it = open_item(r);
        if (!it) {
            r->stalls++; /* the chain stage is behind: the caller tries again later */
            break;
        }
        double z = afm_sim_separation(r->sim);
        double z_last = it->n_zc > 0 ? it->zc[it->n_zc - 1].z_m : it->z0_m;
        if (z != z_last) {
            if (it->n == 0) {
                it->z0_m = z;
            } else {
                it->zc[it->n_zc].at = it->n;
                it->zc[it->n_zc].z_m = z;
                it->n_zc++;
            }
        }
        if (r->surf) { /* the stage Z and the tip from this sample on, when they changed */
            lat_change now = {it->n,     r->cfg.drive.separation_m, r->lat_x, r->lat_y, r->lat_h,
                              r->lat_mat};
            lat_change *l = it->n_lc > 0 ? &it->lc[it->n_lc - 1] : NULL;
            if (!l || l->z_m != now.z_m || l->x_m != now.x_m || l->y_m != now.y_m ||
                l->h_m != now.h_m || l->mat != now.mat) {
                if (l && l->at == it->n)
                    *l = now;
                else
                    it->lc[it->n_lc++] = now;
            }
        }
        long long k = want - done;
        if (k > r->block_max) k = r->block_max;
        if (k > SLOT - it->n) k = SLOT - it->n;
        if (r->ramping) {
            long long to_edge = AFM_RUNNER_RAMP_SAMPLES - r->samples % AFM_RUNNER_RAMP_SAMPLES;
            if (k > to_edge) k = to_edge;
        }
        if (r->fm_on) {
            long long to_upd = r->fm.c.update_samples - r->samples % r->fm.c.update_samples;
            if (k > to_upd) k = to_upd;
        }
        if (r->lat_mode != AFM_SCAN_HOLD || r->zc_on) {
            long long to_edge = LAT - r->samples % LAT;
            if (k > to_edge) k = to_edge;
        }
        double t0 = afm_sim_time(r->sim);
        int rc = afm_sim_run(r->sim, (int)k, it->s + it->n);
        long long adv = k;
        if (rc == AFM_SIM_OK) {
            if (r->ev_on) front_events_note(r, it, (int)k);
            it->n += (int)k;
            item_lat(r, it);
        } else {
            ctl_restart(r);
            if (r->zc_on) r->zc_hold_until = r->samples + zc_settle_samples(r);
            /* The simulator reset itself to rest; its clock counts the steps it took. The
             * samples of this slice are dropped; the chain starts over. */
            adv = llround((afm_sim_time(r->sim) - t0) / afm_sim_dt(r->sim));
            if (adv > k) adv = k;
            double t_b = afm_sim_time(r->sim);
            r->blowup_streak =
                r->blowup_streak > 0 && t_b - r->last_blowup_t_s <= AFM_RUNNER_BLOWUP_WINDOW_S
                    ? r->blowup_streak + 1
                    : 1;
            r->blowups++;
            r->last_blowup_t_s = t_b;
            it->ev_broken = true; /* the blown-up steps' records may sit in its slots */
            if (it->n == 0) {     /* nothing in it: the slot stays free */
                front_events_detach(r);
                r->open = NULL;
            }
            emit(r, IT_RESET, NULL); /* may stay pending; run flushes it first next time */
            if (adv <= 0) break;     /* the integrator cannot even start: report, go no further */
        }
        r->samples += adv;
        done += adv;
        if (r->fm_on && rc == AFM_SIM_OK) fm_after(r, it->s + it->n - k, (int)k);
        if (r->zc_on && rc == AFM_SIM_OK) zc_after(r, it->s + it->n - k, (int)k);
        if (r->blowup_streak >= AFM_RUNNER_BLOWUP_PAUSE && r->running) {
            /* A blow-up that recurs: pause instead of spinning through resets. */
            r->running = false;
            r->step_budget = 0;
            r->auto_paused = true;
            r->auto_pauses++;
            break;
        }
    }
    commit_open(r);
    if (!was_running)
        r->step_budget -= done;
    else if (r->lockstep)
        r->tick_budget -= done;
    /* A tick or step budget used up: its completion follows the samples (the room for it was
     * kept by front_room when the command was applied; else it waits in pending). */
    if (done > 0 && afm_runner_budget(r) == 0 && r->n_pending < PENDING_MAX) emit(r, IT_DONE, NULL);
    return done;
}

int afm_runner_n_streams(const afm_runner *r) {
    return afm_chain_n_streams(r->chain);
}

int afm_runner_take_block(afm_runner *r, int stream, afm_chain_block *b, int max_n) {
    return afm_chain_take_block(r->chain, stream, b, max_n);
}

int afm_runner_take_periods_op(afm_runner *r, afm_chain_period *out, afm_runner_oppoint *ops,
                               int max) {
    int n = afm_chain_take_periods(r->chain, out, max);
    back_pop_take(r, n, ops);
    return n;
}

int afm_runner_take_periods_raw_op(afm_runner *r, afm_chain_period *out, afm_runner_oppoint *ops,
                                   int max) {
    int n = afm_chain_take_periods_raw(r->chain, out, max);
    back_pop_take(r, n, ops);
    return n;
}

int afm_runner_periods_waiting(const afm_runner *r) {
    return afm_chain_periods_waiting(r->chain);
}

int afm_runner_skip_periods(afm_runner *r, int n) {
    n = afm_chain_skip_periods(r->chain, n);
    back_pop_take(r, n, NULL);
    return n;
}

int afm_runner_take_periods(afm_runner *r, afm_chain_period *out, int max) {
    return afm_runner_take_periods_op(r, out, NULL, max);
}

int afm_runner_take_periods_raw(afm_runner *r, afm_chain_period *out, int max) {
    return afm_runner_take_periods_raw_op(r, out, NULL, max);
}

void afm_runner_period_finish(const afm_runner *r, afm_chain_period *p) {
    afm_chain_period_finish(r->chain, p);
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
    st->separation_m = r->surf ? r->cfg.drive.separation_m : afm_sim_separation(r->sim);
    st->separation_target_m = r->ramping ? r->z_target : st->separation_m;
    st->fe_hz = d->n > 0 ? d->omega_rad_s[0] / two_pi : 0.0;
    st->amplitude_m = d->n > 0 ? d->amp_m[0] : 0.0;
    st->blowups = r->blowups;
    st->last_blowup_t_s = r->last_blowup_t_s;
    st->auto_paused = r->auto_paused && !r->running;
    st->auto_pauses = r->auto_pauses;
    st->applied = r->applied;
    st->swaps = r->swaps;
    st->stalls = r->stalls;
    st->pending = (long long)afm_spsc_count((afm_spsc *)&r->ring) + r->n_pending;
    st->fm_on = r->fm_on;
    if (r->fm_on) {
        st->fm_lock = (int)r->fm.lock;
        st->fm_drive = (int)r->fm.c.drive;
        st->fm_frequency_hz = r->fm.freq_hz;
        st->fm_reference_hz = r->fm.f_center_hz;
        st->fm_phase_error_deg = r->fm.phase_error_deg;
        st->fm_drive_m = r->fm.drive_m;
        st->fm_amplitude_m = r->fm.amplitude_m;
        st->fm_amplitude_setpoint_m = r->fm.a_set_m;
    } else {
        st->fm_lock = st->fm_drive = 0;
        st->fm_frequency_hz = st->fm_reference_hz = st->fm_phase_error_deg = NAN;
        st->fm_drive_m = st->fm_amplitude_m = st->fm_amplitude_setpoint_m = NAN;
    }
    st->fm_tone_changes = r->fm_tone_changes;
    st->fm_tone_refused = r->fm_tone_refused;
    st->am_on = r->zc_on;
    st->am_z_m = r->zc_on ? r->zc.z_m : NAN;
    st->am_error_m = r->zc_on ? r->zc.e_m : NAN;
    st->am_setpoint_m = r->zc_on ? r->zc.a_set_m : NAN;
    st->am_amplitude_m = r->zc_on ? r->zc_a_m : NAN;
    st->am_updates = r->zc_updates;
    st->sample_on = r->surf != NULL;
    st->tip_x_m = r->lat_x;
    st->tip_y_m = r->lat_y;
    st->true_height_m = r->lat_h;
    st->material = r->lat_mat;
    st->scan_mode = r->lat_mode;
    st->scan_line = r->lat_mode == AFM_SCAN_RASTER ? r->lat_line : -1;
    st->scan_pixel = r->lat_mode == AFM_SCAN_RASTER ? r->lat_pixel : -1;
    st->scan_retrace = r->lat_mode == AFM_SCAN_RASTER && r->lat_retrace;
    st->gap_clamps = r->lat_clamps;
    if (r->pipelined)
        memset(&st->chain, 0, sizeof st->chain); /* the chain thread's: chain_status_get */
    else
        st->chain = afm_chain_stats_get(r->chain);
}

void afm_runner_pause_reason(const afm_runner_status *st, char *buf, size_t len) {
    if (!st->auto_paused) {
        snprintf(buf, len, "%s", "");
        return;
    }
    snprintf(buf, len,
             "paused by itself after %d numerical blow-ups, each within %g s of model time of "
             "the last (the last at t = %.6f s): the state runs away under this drive (tone 0: "
             "%.6g Hz, %.3g m) at Z = %.3g m; change the drive, Z or the model, then send "
             "control run",
             AFM_RUNNER_BLOWUP_PAUSE, AFM_RUNNER_BLOWUP_WINDOW_S, st->last_blowup_t_s, st->fe_hz,
             st->amplitude_m, st->separation_m);
}

const afm_config *afm_runner_config(const afm_runner *r) {
    return &r->cfg;
}
const afm_sim *afm_runner_sim(const afm_runner *r) {
    return r->sim;
}
int afm_runner_set_scheme(afm_runner *r, bool accurate) {
    return afm_sim_set_scheme(r->sim, accurate);
}
bool afm_runner_pipelined(const afm_runner *r) {
    return r->pipelined;
}
