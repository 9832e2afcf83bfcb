/* SPDX-License-Identifier: MIT */
/* afm_chain.c -- OBD, decimators, rings and estimators per sample (contract in afm_chain.h). */
#include "estimators/afm_chain.h"

#include "estimators/afm_decim.h"
#include "forces/afm_drive.h"
#include "forces/afm_force.h"
#include "estimators/afm_est_internal.h"
#include "estimators/afm_lockin.h"
#include "estimators/afm_phase_gen.h"
#include "config/afm_clones.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CHUNK 512         /* full-rate samples processed per inner pass */
#define RING_SECONDS 0.05 /* each stream's ring holds this much output... */
#define RING_MIN 1024     /* ...but at least this many samples... */
#define RING_MAX 131072   /* ...and at most this many */
#define PERIOD_RING AFM_CHAIN_PERIOD_RING
_Static_assert(CHUNK <= PERIOD_RING, "a push's records stay in the ring until its lock-in pass");

enum { CH_X, CH_OBD, CH_F, CH_BASE };

/* pack_frames reads (x, v, f, theta) and (v, f, theta, base) as two 4-double runs of a sample. */
_Static_assert(offsetof(afm_sample, v_m_s) == offsetof(afm_sample, x_m) + sizeof(double) &&
                   offsetof(afm_sample, f_n) == offsetof(afm_sample, x_m) + 2 * sizeof(double) &&
                   offsetof(afm_sample, theta_rad) ==
                       offsetof(afm_sample, x_m) + 3 * sizeof(double) &&
                   offsetof(afm_sample, base_m) == offsetof(afm_sample, x_m) + 4 * sizeof(double),
               "afm_sample: x, v, f, theta, base consecutive");
_Static_assert(CH_X == 0 && CH_OBD == 1 && CH_F == 2 && CH_BASE == 3 && AFM_DECIM_CH == 4,
               "frame = (x, obd, f, base)");

typedef struct {
    int factor; /* R from the input */
    int src;    /* stream it is decimated from, -1 = the input */
    int src_factor;
    double passband; /* the decimators' passband fraction (afm_chain_band) */
    afm_decim *dec;
    double delay_s; /* this decimator's group delay in seconds */
    double dt_src;  /* sample interval of its source */
    double *frames; /* (CHUNK + 1) frames of this pass's output */
    double *t;      /* their times (the model time of the sample completing each, minus the
                       delay) */
    int n_frames;
    /* ring (structure of arrays) */
    int cap, head, count;
    double *rt, *rx, *robd, *rcnt, *rf, *rbase;
} stream;

/* Tone 0's phase for the estimators: afm_phase_gen.h (from the sample index, so that how
 * the samples are cut into pushes changes no bit). */

struct afm_chain {
    afm_obd obd;
    int n_streams;
    stream st[AFM_MAX_OUTPUTS];
    int order[AFM_MAX_OUTPUTS]; /* streams by ascending factor */
    int primary;                /* the input-fed stream whose decimator input the frames are
                                   packed into (the other input-fed ones copy from there) */
    double fs;
    /* estimators */
    bool attached;
    const afm_drive *drive;
    afm_phase_gen phase;
    afm_harm harm;
    afm_cycle cycle;
    afm_lockin lockin;
    afm_chain_period *periods;
    int p_head, p_count;
    double cos_alpha;
    const afm_force_params *forces;
    afm_chain_stats stats;
    /* afm_chain_push_ev_ends: where the records of the push in progress ended (NULL: no one
     * asks), ends_base the index in the push of the pass's first sample */
    int *ends;
    int n_ends, max_ends, ends_base;
};

/* Write every page of [p, p + n) once, so that the first push does not take the page faults
 * (the kernel's allocation of calloc's and malloc's untouched pages; ~2 MB of rings and
 * records, ~1.5 ms on this VM) on the real-time path, when the daemon cannot lock its memory
 * or the chain is built later (a geometry change, a reload). */
static void touch(void *p, size_t n) {
    volatile unsigned char *q = p;
    for (size_t i = 0; i < n; i += 4096)
        q[i] = q[i];
    if (n) q[n - 1] = q[n - 1];
}

static void fail_msg(char *err, size_t errlen, const char *msg) {
    if (err && errlen) snprintf(err, errlen, "chain: %s", msg);
}

afm_chain *afm_chain_create(const afm_config *cfg, const afm_modal *m, char *err, size_t errlen) {
    if (!cfg || !m) {
        fail_msg(err, errlen, "NULL argument");
        return NULL;
    }
    if (afm_config_validate(cfg, err, errlen)) return NULL;
    afm_chain *c = calloc(1, sizeof *c);
    if (!c) goto oom;
    if (afm_obd_init(&c->obd, cfg, m, err, errlen)) goto fail;
    c->fs = cfg->sim.sample_rate_hz;
    const afm_cfg_output *o = &cfg->output;
    c->n_streams = o->n_outputs;
    for (int i = 0; i < o->n_outputs; i++)
        c->order[i] = i;
    for (int i = 1; i < o->n_outputs; i++) /* insertion sort by factor (stable) */
        for (int j = i; j > 0 && o->decimation[c->order[j]] < o->decimation[c->order[j - 1]]; j--) {
            int tmp = c->order[j];
            c->order[j] = c->order[j - 1];
            c->order[j - 1] = tmp;
        }
    for (int k = 0; k < c->n_streams; k++) {
        int i = c->order[k];
        stream *s = &c->st[i];
        s->factor = o->decimation[i];
        s->src = -1;
        s->src_factor = 1;
        for (int q = 0; q < k; q++) { /* largest earlier factor dividing this one */
            int j = c->order[q];
            if (s->factor % c->st[j].factor == 0 && c->st[j].factor > s->src_factor &&
                c->st[j].factor < s->factor) {
                s->src = j;
                s->src_factor = c->st[j].factor;
            }
        }
        s->dt_src = s->src_factor / c->fs;
        s->passband = o->passband_fraction;
        s->dec = afm_decim_create(s->factor / s->src_factor, o->passband_fraction, err, errlen);
        if (!s->dec) goto fail;
        s->delay_s = afm_decim_delay(s->dec) * s->dt_src;
        s->frames = malloc((CHUNK + 1) * AFM_DECIM_CH * sizeof *s->frames);
        s->t = malloc((CHUNK + 1) * sizeof *s->t);
        double want = RING_SECONDS * c->fs / s->factor;
        s->cap = want < RING_MIN ? RING_MIN : want > RING_MAX ? RING_MAX : (int)want;
        double **arrs[] = {&s->rt, &s->rx, &s->robd, &s->rcnt, &s->rf, &s->rbase};
        for (int a = 0; a < 6; a++)
            *arrs[a] = malloc((size_t)s->cap * sizeof(double));
        if (!s->frames || !s->t || !s->rt || !s->rx || !s->robd || !s->rcnt || !s->rf || !s->rbase)
            goto oom;
        touch(s->frames, (CHUNK + 1) * AFM_DECIM_CH * sizeof *s->frames);
        touch(s->t, (CHUNK + 1) * sizeof *s->t);
        for (int a = 0; a < 6; a++)
            touch(*arrs[a], (size_t)s->cap * sizeof(double));
    }
    c->primary = c->order[0]; /* the smallest factor is always decimated from the input */
    int room;
    afm_decim_in(c->st[c->primary].dec, &room);
    if (room < CHUNK) {
        fail_msg(err, errlen, "decimator input smaller than a pass");
        goto fail;
    }
    c->periods = calloc(PERIOD_RING, sizeof *c->periods);
    if (!c->periods) goto oom;
    touch(c->periods, PERIOD_RING * sizeof *c->periods);

    /* Estimators: initialised now, run once attached. */
    int ks[AFM_MAX_HARMONICS], nk = cfg->sim.n_harmonics;
    if (nk > 0)
        memcpy(ks, cfg->sim.harmonics, (size_t)nk * sizeof ks[0]);
    else
        nk = afm_harm_default_list(m, cfg->drive.tones[0].frequency_hz, ks);
    if (afm_harm_init(&c->harm, ks, nk, err, errlen) ||
        afm_lockin_init(&c->lockin, &cfg->lockin, 1.0 / c->fs, err, errlen))
        goto fail;
    afm_harm_set_deferred(&c->harm, true); /* polar form when a record is finished */
    touch(c, sizeof *c);
    return c;
oom:
    fail_msg(err, errlen, "out of memory");
fail:
    afm_chain_destroy(&c);
    return NULL;
}

void afm_chain_destroy(afm_chain **cp) {
    if (!cp || !*cp) return;
    afm_chain *c = *cp;
    for (int i = 0; i < AFM_MAX_OUTPUTS; i++) {
        stream *s = &c->st[i];
        afm_decim_destroy(&s->dec);
        free(s->frames);
        free(s->t);
        free(s->rt);
        free(s->rx);
        free(s->robd);
        free(s->rcnt);
        free(s->rf);
        free(s->rbase);
    }
    free(c->periods);
    free(c);
    *cp = NULL;
}

/* Before the estimators are reset: their table rebuilds into the stats (which are kept). */
static void keep_rebuilds(afm_chain *c) {
    c->stats.estimator_rebuilds += c->harm.trk.rate_changes + c->lockin.trk.rate_changes;
}

int afm_chain_attach(afm_chain *c, const afm_sim *sim, char *err, size_t errlen) {
    if (!sim) {
        c->attached = false;
        c->drive = NULL;
        return 0;
    }
    const afm_force_params *f = afm_sim_forces(sim);
    double xc = afm_force_contact_x(f, afm_sim_separation(sim));
    /* the law numbers go on from the last attach's: the records keep the laws they hold */
    const unsigned long long law_id = c->cycle.law_id;
    if (afm_cycle_init(&c->cycle, xc, f->cos_alpha, err, errlen)) return -1;
    c->cycle.law_id = law_id;
    afm_cycle_set_forces(&c->cycle, f, afm_sim_separation(sim));
    afm_cycle_set_defer(&c->cycle, true); /* finished per record read (afm_chain.h) */
    c->forces = f;
    c->cos_alpha = f->cos_alpha;
    c->drive = afm_sim_drive(sim);
    afm_phase_gen_reset(&c->phase, c->fs);
    keep_rebuilds(c);
    afm_harm_reset(&c->harm);
    afm_lockin_reset(&c->lockin);
    c->attached = true;
    return 0;
}

int afm_chain_set_separation(afm_chain *c, double z_m) {
    if (!c->attached || !isfinite(z_m)) return -1;
    return afm_cycle_set_forces(&c->cycle, c->forces, z_m);
}

/* Append this pass's output of stream s to its ring (dropping the oldest when full). */
static void ring_put(afm_chain *c, int idx) {
    stream *s = &c->st[idx];
    const double inv_lsb = c->obd.adc_bits > 0 ? c->obd.inv_lsb : 0.0;
    const int cap = s->cap, nf = s->n_frames;
    const double *f = s->frames, *t = s->t;
    double *rt = s->rt, *rx = s->rx, *robd = s->robd, *rcnt = s->rcnt, *rf = s->rf,
           *rbase = s->rbase;
    int w = s->head;
    for (int k = 0; k < nf;) { /* in runs up to the end of the ring */
        int run = nf - k < cap - w ? nf - k : cap - w;
        double *t_ = rt + w, *x_ = rx + w, *o_ = robd + w, *c_ = rcnt + w, *f_ = rf + w,
               *b_ = rbase + w;
        for (int j = 0; j < run; j++, f += AFM_DECIM_CH) {
            double tj = t[k + j], x = f[CH_X], o = f[CH_OBD], fn = f[CH_F], b = f[CH_BASE];
            t_[j] = tj;
            x_[j] = x;
            o_[j] = o;
            c_[j] = o * inv_lsb;
            f_[j] = fn;
            b_[j] = b;
        }
        k += run;
        w = w + run == cap ? 0 : w + run;
    }
    s->head = w;
    if (nf > cap - s->count) { /* the oldest were overwritten */
        c->stats.dropped[idx] += nf - (cap - s->count);
        s->count = cap;
    } else {
        s->count += nf;
    }
}

/* Time stamps of stream s's n_frames new outputs: output k is completed by source sample
 * (R - ph - 1) + k R (ph: the decimator's phase before the pass), at time t_src(i) (the
 * input samples' own t_s, or the source stream's stamps). */
static void stamp_input(stream *s, const afm_sample *p, int ph) {
    int R = afm_decim_factor(s->dec);
    for (int k = 0; k < s->n_frames; k++)
        s->t[k] = p[(R - ph - 1) + k * R].t_s - s->delay_s;
}
static void stamp_cascade(stream *s, const double *t_src, int ph) {
    int R = afm_decim_factor(s->dec);
    for (int k = 0; k < s->n_frames; k++)
        s->t[k] = t_src[(R - ph - 1) + k * R] - s->delay_s;
}

/* Frames (x, obd, f, base) of n samples into dst (AFM_DECIM_CH doubles each, 32-byte
 * aligned), f the tip-sample force fts[i] (afm_cycle_split_forces). Returns 1 when every
 * channel of every frame is finite: the sum of all of them is then finite, or overflowed to
 * an infinity (0 then: afm_decim_commit looks for the first non-finite frame, finds none and
 * gives the same output), and an infinity or a NaN anywhere makes it inf or NaN (issue 12:
 * a sum, not the sum of x 0, saves an instruction a sample). */
AFM_CLONES static int pack_frames(double *dst, const afm_sample *p, const double *obd,
                                  const double *fts, int n) {
    enum { S = sizeof(afm_sample) / sizeof(double) };
    const double *x = (const double *)p + offsetof(afm_sample, x_m) / sizeof(double);
    afm_v4 z0 = AFM_V4_SET1(0.0), z1 = z0;
    /* (x, v, f, theta) and (v, f, theta, base) -> (x, obd, f, base) */
#define PACK(i, z)                                                                                 \
    do {                                                                                           \
        afm_v4 f_ =                                                                                \
            __builtin_shufflevector(AFM_V4_LD(x + (i)*S), AFM_V4_LD(x + (i)*S + 1), 0, 1, 2, 7);   \
        f_[1] = obd[i];                                                                            \
        f_[2] = fts[i];                                                                            \
        AFM_V4_ST(dst + (size_t)(i)*AFM_DECIM_CH, f_);                                             \
        z = z + f_;                                                                                \
    } while (0)
    int i = 0;
    /* 4 samples at a time (issue 12: 11 -> ~8 instructions a sample): (t, x) and (theta,
     * base) pairs of samples 0, 2 and 1, 3 side by side give x and base on 4 lanes, obd and
     * f are loaded as they are, and a 4 x 4 transpose makes the frames; the finite test on
     * the same values */
    typedef double v2 __attribute__((vector_size(16), aligned(8), may_alias));
    for (; i + 4 <= n; i += 4) {
        const double *xb = x + (size_t)i * S;
#define Q2(k, off) (*(const v2 *)(const void *)(xb + (k)*S + (off)))
        afm_v4 u0 = __builtin_shufflevector(Q2(0, -1), Q2(2, -1), 0, 1, 2, 3); /* (t, x) */
        afm_v4 u1 = __builtin_shufflevector(Q2(1, -1), Q2(3, -1), 0, 1, 2, 3);
        afm_v4 w0 = __builtin_shufflevector(Q2(0, 3), Q2(2, 3), 0, 1, 2, 3); /* (theta, base) */
        afm_v4 w1 = __builtin_shufflevector(Q2(1, 3), Q2(3, 3), 0, 1, 2, 3);
#undef Q2
        afm_v4 X = __builtin_shufflevector(u0, u1, 1, 5, 3, 7);
        afm_v4 B = __builtin_shufflevector(w0, w1, 1, 5, 3, 7);
        afm_v4 O = AFM_V4_LD(obd + i), F = AFM_V4_LD(fts + i);
        afm_v4 t0 = __builtin_shufflevector(X, O, 0, 4, 2, 6); /* (x0, o0, x2, o2) */
        afm_v4 t1 = __builtin_shufflevector(X, O, 1, 5, 3, 7); /* (x1, o1, x3, o3) */
        afm_v4 t2 = __builtin_shufflevector(F, B, 0, 4, 2, 6); /* (f0, b0, f2, b2) */
        afm_v4 t3 = __builtin_shufflevector(F, B, 1, 5, 3, 7);
        double *d = dst + (size_t)i * AFM_DECIM_CH;
        AFM_V4_ST(d, __builtin_shufflevector(t0, t2, 0, 1, 4, 5));
        AFM_V4_ST(d + AFM_DECIM_CH, __builtin_shufflevector(t1, t3, 0, 1, 4, 5));
        AFM_V4_ST(d + 2 * AFM_DECIM_CH, __builtin_shufflevector(t0, t2, 2, 3, 6, 7));
        AFM_V4_ST(d + 3 * AFM_DECIM_CH, __builtin_shufflevector(t1, t3, 2, 3, 6, 7));
        z0 = z0 + (X + O);
        z1 = z1 + (F + B);
    }
    for (; i < n; i++)
        PACK(i, z0);
#undef PACK
    z0 = z0 + z1;
    const double sum = (z0[0] + z0[1]) + (z0[2] + z0[3]);
    return sum - sum == 0.0;
}

/* The decimators and rings over n samples (their OBD readings obd): the frames go straight
 * into the primary stream's decimator; the other input-fed streams filter them from there
 * before the primary's commit (which moves its buffer), then the cascaded ones run in
 * ascending factor order (their sources come first). */
static void run_streams(afm_chain *c, const afm_sample *p, const double *obd, const double *fts,
                        int n) {
    stream *pr = &c->st[c->primary];
    double *in = afm_decim_in(pr->dec, NULL);
    int finite = pack_frames(in, p, obd, fts, n);
    for (int q = 1; q < c->n_streams; q++) {
        stream *st = &c->st[c->order[q]];
        if (st->src >= 0) continue;
        int ph = afm_decim_phase(st->dec);
        st->n_frames = afm_decim_run(st->dec, in, n, st->frames);
        stamp_input(st, p, ph);
    }
    int ph = afm_decim_phase(pr->dec);
    pr->n_frames = afm_decim_commit(pr->dec, n, finite, pr->frames);
    stamp_input(pr, p, ph);
    for (int q = 1; q < c->n_streams; q++) {
        stream *st = &c->st[c->order[q]];
        if (st->src < 0) continue;
        const stream *src = &c->st[st->src];
        ph = afm_decim_phase(st->dec);
        st->n_frames = afm_decim_run(st->dec, src->frames, src->n_frames, st->frames);
        stamp_cascade(st, src->t, ph);
    }
    for (int q = 0; q < c->n_streams; q++)
        ring_put(c, c->order[q]);
}

/* Append the current estimates as a period record (its lock-in X and Y are the caller's:
 * estimators reads them at the period's end in its one lock-in pass). */
static afm_chain_period *put_period(afm_chain *c) {
    _Static_assert((PERIOD_RING & (PERIOD_RING - 1)) == 0, "PERIOD_RING: a power of 2");
    const unsigned mask = PERIOD_RING - 1; /* indices >= 0: a mask, not a signed % */
    int w = (int)((unsigned)(c->p_head + c->p_count) & mask);
    if (c->p_count == PERIOD_RING) {
        c->p_head = (int)((unsigned)(c->p_head + 1) & mask);
        c->stats.periods_dropped++;
    } else {
        c->p_count++;
    }
    afm_chain_period *p = &c->periods[w];
    /* The header and the sums of the lanes in use (afm_harm is deferred: h[] is filled by
     * afm_chain_period_finish). */
    const afm_harm_result *hr = c->harm.out_at ? c->harm.out_at : &c->harm.out;
    if (hr != &p->harm) /* else written there already (see below) */
        memcpy(&p->harm, hr,
               offsetof(afm_harm_result, raw) + (size_t)(4 * c->harm.nl) * sizeof p->harm.raw[0]);
    if (c->cycle.periods > 0) {
        p->cycle = c->cycle.out;
        /* the cycle wrote its deferred steps here already (see below), unless its last
         * period went elsewhere (the ring was full, a reset, no period since the last record) */
        const afm_cycle_deferred *d = c->cycle.out_def_at ? c->cycle.out_def_at : &c->cycle.out_def;
        if (d != &p->cycle_def) memcpy(&p->cycle_def, d, AFM_CYCLE_DEFERRED_SIZE(d));
    } else {
        memset(&p->cycle, 0, sizeof p->cycle);
        p->cycle_def.n = p->cycle_def.n_energy = 0;
    }
    /* the next period's cycle steps and harmonic sums straight into the next record (one
     * copy, not two: issue 12); not while the ring is full, whose next record is the oldest,
     * still to be taken */
    afm_chain_period *next =
        c->p_count < PERIOD_RING ? &c->periods[(unsigned)(w + 1) & mask] : NULL;
    c->cycle.out_def_to = next ? &next->cycle_def : NULL;
    c->harm.out_to = next ? &next->harm : NULL;
    c->stats.periods++;
    return p;
}

/* Tone 0 changed (an NCO step of the FM loops, a dither command) right before s[0]: when the
 * new frame's theta continues the last sample's (a phase-continuous change on the grid:
 * afm_drive_set_tone at that sample's time, s[0] the next sample), the estimators take the
 * new rate at once, each O(1) (afm_track_rebase, afm_harm_rebase, afm_lockin_rebase: no
 * rebuild per sample, no learning of the rate from increments that a small change of
 * frequency could not tell from noise). Otherwise (a jump, a reset, a gap in the samples, a
 * drive off the grid) they meet the new theta on their slow paths, as before. The cycle
 * estimator keeps nothing that depends on the rate but its tracker. */
static void retune(afm_chain *c, const double *th) {
    const double th_prev = th[0] - c->phase.wdt; /* the last sample in the new frame */
    afm_harm_rebase(&c->harm, th_prev, c->phase.wdt);
    afm_lockin_rebase(&c->lockin, th_prev, c->phase.wdt);
    if (c->cycle.trk.locked) afm_track_rebase(&c->cycle.trk, th_prev, c->phase.wdt);
}

/* e (the record of s[a]'s step, or NULL) when afm_cycle_push_ev would use it, else NULL: a
 * step with no crossing, no minimum of its own (one free piece) and both ends above the
 * cycle's near-contact gap (with the force law) leaves afm_cycle's sample path as it is
 * (afm_cycle.c: step_plain, step_boundary), so such samples go through afm_cycle_push_n's
 * vector runs, with the same bits (afm_cycle_push_ev on every sample costs the chain thread
 * ~2.5x on a lumped probe). The step's start is s[a - 1], or the cycle's last sample for
 * a = 0; a non-finite end keeps the record (afm_cycle_push rejects the sample). */
static inline const afm_step_events *ev_used(const afm_chain *c, const afm_sample *s, int a,
                                             const afm_step_events *e) {
    if (!e || !isnan(e->x_min_m) || e->n_in + e->n_out != 0) return e;
    const afm_cycle *y = &c->cycle;
    const double xp = a > 0 ? s[a - 1].x_m : y->n_prev > 0 ? y->prev.x_m : NAN;
    if (y->forces && !(xp >= y->x_near_m && s[a].x_m >= y->x_near_m)) return e;
    return NULL;
}

/* The estimators over n samples (f their tip-sample forces), with tone 0's phase from
 * afm_phase_gen. harm and cycle share the period clock: each run ends at a sample where harm
 * completed a period, and cycle is brought to the same sample before the record is written;
 * the lock-in then runs over all n samples, its X and Y read at the same ends. ev (NULL: none) the
 * integrator's records of the samples (afm_chain_push_ev): a sample with one goes through
 * afm_cycle_push_ev, a run without through afm_cycle_push_n (the same bits as afm_cycle_push).
 * estimator_rejects counts, per run, the most samples any one estimator refused. */
AFM_CLONES static void estimators(afm_chain *c, const afm_sample *s, const double *obd,
                                  const double *f, const double *q,
                                  const afm_step_events *const *ev, int n) {
    double th[CHUNK];
    afm_lockin_mark mk[CHUNK]; /* the ends of harm's runs, the records' X and Y */
    long long rhc[CHUNK];      /* rejects of harm and cycle per run */
    int nm = 0;
    if (afm_phase_gen_run(&c->phase, c->drive, s, n, th) == AFM_PHASE_STEP) retune(c, th);
    for (int i = 0; i < n;) {
        long long rh = 0, rc = 0;
        int done, dc;
        int k = afm_harm_push_n(&c->harm, obd + i, f + i, th + i, n - i, &done, &rh);
        for (int j = 0; j < k;) {
            const int a = i + j;
            const afm_step_events *e = ev ? ev_used(c, s, a, ev[a]) : NULL;
            if (e) {
                if (afm_cycle_push_ev(&c->cycle, s + a, th[a], e) < 0) rc++;
                j++;
                continue;
            }
            int m = 1; /* the run of samples whose record is not used */
            while (ev && j + m < k && !ev_used(c, s, a + m, ev[a + m]))
                m++;
            if (!ev) m = k - j;
            j += afm_cycle_push_n_split(&c->cycle, s + a, th + a, f + a, q + a, m, &dc, &rc);
        }
        rhc[nm] = rh > rc ? rh : rc;
        mk[nm].x_m = mk[nm].y_m = NULL;
        if (done) {
            afm_chain_period *p = put_period(c);
            mk[nm].x_m = &p->lockin_x_m;
            mk[nm].y_m = &p->lockin_y_m;
        }
        i += k;
        mk[nm++].end = i;
    }
    /* The lock-in over the whole push in one pass, X and Y read at the periods' ends (the
     * records of this push are still in the ring: at most CHUNK < PERIOD_RING of them) */
    afm_lockin_push_marks(&c->lockin, obd, th, n, mk, nm);
    for (int u = 0; u < nm; u++) {
        long long rl = mk[u].rejects;
        c->stats.estimator_rejects += rhc[u] > rl ? rhc[u] : rl;
    }
    if (c->ends) /* afm_chain_push_ev_ends: a record's period ended on its run's last sample */
        for (int u = 0; u < nm && c->n_ends < c->max_ends; u++)
            if (mk[u].x_m) c->ends[c->n_ends++] = c->ends_base + mk[u].end - 1;
}

int afm_chain_push_ev_ends(afm_chain *c, const afm_sample *s, const afm_step_events *const *ev,
                           int n, int *ends, int max_ends) {
    const long long p0 = c->stats.periods;
    c->ends = ends;
    c->n_ends = 0;
    c->max_ends = ends ? max_ends : 0;
    afm_chain_push_ev(c, s, ev, n);
    c->ends = NULL;
    return (int)(c->stats.periods - p0);
}

int afm_chain_push_ev(afm_chain *c, const afm_sample *s, const afm_step_events *const *ev, int n) {
    double obd_buf[CHUNK], f_buf[CHUNK], q_buf[CHUNK];
    for (int done = 0; done < n;) {
        int k = n - done < CHUNK ? n - done : CHUNK;
        const afm_sample *p = s + done;
        long long sat0 = c->obd.n_saturated;
        afm_obd_read_block(&c->obd, p, k, obd_buf);
        c->stats.obd_saturated += c->obd.n_saturated - sat0;
        c->obd.n_saturated = sat0;
        /* Forces by origin: the squeeze film on the beam is not the tip-sample force (its
           share is the cycle metrics' squeeze_dissipated_energy_j). Detached, the cycle's
           force law may be gone: the samples' force as it is. */
        if (c->attached) {
            afm_cycle_split_forces(&c->cycle, p, k, f_buf, q_buf); /* and F_sq v */
        } else {
            for (int i = 0; i < k; i++)
                f_buf[i] = p[i].f_n;
        }
        c->ends_base = done;
        if (c->attached) estimators(c, p, obd_buf, f_buf, q_buf, ev ? ev + done : NULL, k);
        run_streams(c, p, obd_buf, f_buf, k);
        c->stats.pushed += k;
        done += k;
    }
    return 0;
}

int afm_chain_push(afm_chain *c, const afm_sample *s, int n) {
    return afm_chain_push_ev(c, s, NULL, n);
}

int afm_chain_take_block(afm_chain *c, int i, afm_chain_block *b, int max_n) {
    if (i < 0 || i >= c->n_streams) return -1;
    stream *s = &c->st[i];
    int tail = (s->head - s->count + s->cap) % s->cap;
    int n = s->count < s->cap - tail ? s->count : s->cap - tail;
    if (max_n > 0 && n > max_n) n = max_n;
    b->stream = i;
    b->decimation = s->factor;
    b->rate_hz = c->fs / s->factor;
    afm_chain_band(b->rate_hz, s->factor, s->passband, &b->passband_hz, &b->stopband_hz);
    b->n = n;
    b->t_s = s->rt + tail;
    b->x_m = s->rx + tail;
    b->obd_m = s->robd + tail;
    b->obd_counts = c->obd.enabled && c->obd.adc_bits > 0 ? s->rcnt + tail : NULL;
    b->f_n = s->rf + tail;
    b->base_m = s->rbase + tail;
    s->count -= n;
    return n;
}

void afm_chain_band(double rate_hz, int factor, double passband_fraction, double *pass_hz,
                    double *stop_hz) {
    *pass_hz = factor > 1 ? 0.5 * passband_fraction * rate_hz : 0;
    *stop_hz = factor > 1 ? rate_hz - *pass_hz : 0;
}

int afm_chain_available(const afm_chain *c, int i) {
    return (i < 0 || i >= c->n_streams) ? 0 : c->st[i].count;
}

void afm_chain_period_finish(const afm_chain *c, afm_chain_period *p) {
    afm_harm_polar(&c->harm, &p->harm);
    afm_lockin_polar_of(p->lockin_x_m, p->lockin_y_m, &p->lockin_amplitude_m, &p->lockin_phase_deg);
    afm_cycle_finish(&p->cycle, &p->cycle_def);
}

int afm_chain_take_periods(afm_chain *c, afm_chain_period *out, int max) {
    int n = afm_chain_take_periods_raw(c, out, max);
    for (int i = 0; i < n; i++)
        afm_chain_period_finish(c, &out[i]);
    return n;
}

int afm_chain_take_periods_raw(afm_chain *c, afm_chain_period *out, int max) {
    int n = 0;
    while (n < max && c->p_count > 0) {
        const afm_chain_period *p = &c->periods[c->p_head];
        /* the used part of the deferred steps only */
        memcpy(&out[n++], p,
               offsetof(afm_chain_period, cycle_def) + AFM_CYCLE_DEFERRED_SIZE(&p->cycle_def));
        c->p_head = (c->p_head + 1) % PERIOD_RING;
        c->p_count--;
    }
    return n;
}

int afm_chain_periods_waiting(const afm_chain *c) {
    return c->p_count;
}

int afm_chain_skip_periods(afm_chain *c, int n) {
    if (n > c->p_count) n = c->p_count;
    if (n <= 0) return 0;
    c->p_head = (c->p_head + n) % PERIOD_RING;
    c->p_count -= n;
    return n;
}

void afm_chain_reset(afm_chain *c) {
    for (int i = 0; i < c->n_streams; i++) {
        afm_decim_reset(c->st[i].dec);
        c->st[i].head = c->st[i].count = 0;
    }
    keep_rebuilds(c);
    afm_harm_reset(&c->harm);
    afm_lockin_reset(&c->lockin);
    if (c->attached) afm_cycle_reset(&c->cycle);
    c->p_head = c->p_count = 0;
}

int afm_chain_n_streams(const afm_chain *c) {
    return c->n_streams;
}
long long afm_chain_periods(const afm_chain *c) {
    return c->stats.periods;
}
afm_chain_stats afm_chain_stats_get(const afm_chain *c) {
    afm_chain_stats s = c->stats;
    s.estimator_rebuilds += c->harm.trk.rate_changes + c->lockin.trk.rate_changes;
    for (int i = 0; i < c->n_streams; i++)
        s.nonfinite += afm_decim_nonfinite(c->st[i].dec);
    return s;
}
const afm_obd *afm_chain_obd(const afm_chain *c) {
    return &c->obd;
}
