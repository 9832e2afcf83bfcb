/* SPDX-License-Identifier: MIT */
/* afm_chain.c -- OBD, decimators, rings and estimators per sample (contract in afm_chain.h). */
#include "afm_chain.h"

#include "afm_decim.h"
#include "afm_drive.h"
#include "afm_force.h"
#include "afm_lockin.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CHUNK 512         /* full-rate samples processed per inner pass */
#define RING_SECONDS 0.05 /* each stream's ring holds this much output... */
#define RING_MIN 1024     /* ...but at least this many samples... */
#define RING_MAX 131072   /* ...and at most this many */
#define PERIOD_RING 1024  /* period records */

enum { CH_X, CH_OBD, CH_F, CH_BASE };

typedef struct {
    int factor; /* R from the input */
    int src;    /* stream it is decimated from, -1 = the input */
    int src_factor;
    afm_decim *dec;
    double delay_s; /* this decimator's group delay in seconds */
    double dt_src;  /* sample interval of its source */
    double *frames; /* (CHUNK + 1) frames of this pass's output */
    double *t;      /* their times */
    int n_frames;
    /* ring (structure of arrays) */
    int cap, head, count;
    double *rt, *rx, *robd, *rcnt, *rf, *rbase;
} stream;

struct afm_chain {
    afm_obd obd;
    int n_streams;
    stream st[AFM_MAX_OUTPUTS];
    int order[AFM_MAX_OUTPUTS]; /* streams by ascending factor */
    double *in_frames;          /* CHUNK frames */
    double *in_t;
    double fs;
    /* estimators */
    bool attached;
    const afm_drive *drive;
    afm_harm harm;
    afm_cycle cycle;
    afm_lockin lockin;
    afm_chain_period *periods;
    int p_head, p_count;
    double cos_alpha;
    const afm_force_params *forces;
    afm_chain_stats stats;
};

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
    }
    c->in_frames = malloc(CHUNK * AFM_DECIM_CH * sizeof *c->in_frames);
    c->in_t = malloc(CHUNK * sizeof *c->in_t);
    c->periods = malloc(PERIOD_RING * sizeof *c->periods);
    if (!c->in_frames || !c->in_t || !c->periods) goto oom;

    /* Estimators: initialised now, run once attached. */
    int ks[AFM_MAX_HARMONICS], nk = cfg->sim.n_harmonics;
    if (nk > 0)
        memcpy(ks, cfg->sim.harmonics, (size_t)nk * sizeof ks[0]);
    else
        nk = afm_harm_default_list(m, cfg->drive.tones[0].frequency_hz, ks);
    if (afm_harm_init(&c->harm, ks, nk, err, errlen) ||
        afm_lockin_init(&c->lockin, &cfg->lockin, 1.0 / c->fs, err, errlen))
        goto fail;
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
    free(c->in_frames);
    free(c->in_t);
    free(c->periods);
    free(c);
    *cp = NULL;
}

int afm_chain_attach(afm_chain *c, const afm_sim *sim, char *err, size_t errlen) {
    if (!sim) {
        c->attached = false;
        c->drive = NULL;
        return 0;
    }
    const afm_force_params *f = afm_sim_forces(sim);
    double xc = afm_force_contact_x(f, afm_sim_separation(sim));
    if (afm_cycle_init(&c->cycle, xc, f->cos_alpha, err, errlen)) return -1;
    c->forces = f;
    c->cos_alpha = f->cos_alpha;
    c->drive = afm_sim_drive(sim);
    afm_harm_reset(&c->harm);
    afm_lockin_reset(&c->lockin);
    c->attached = true;
    return 0;
}

int afm_chain_set_separation(afm_chain *c, double z_m) {
    if (!c->attached || !isfinite(z_m)) return -1;
    return afm_cycle_set_contact(&c->cycle, afm_force_contact_x(c->forces, z_m));
}

/* Append this pass's output of stream s to its ring (dropping the oldest when full). */
static void ring_put(afm_chain *c, int idx) {
    stream *s = &c->st[idx];
    double inv_lsb = c->obd.adc_bits > 0 ? c->obd.inv_lsb : 0.0;
    for (int k = 0; k < s->n_frames; k++) {
        const double *f = s->frames + (size_t)k * AFM_DECIM_CH;
        int w = s->head;
        s->rt[w] = s->t[k];
        s->rx[w] = f[CH_X];
        s->robd[w] = f[CH_OBD];
        s->rcnt[w] = f[CH_OBD] * inv_lsb;
        s->rf[w] = f[CH_F];
        s->rbase[w] = f[CH_BASE];
        if (++s->head == s->cap) s->head = 0;
        if (s->count == s->cap)
            c->stats.dropped[idx]++;
        else
            s->count++;
    }
}

/* Decimate frames (n, times t) of the source into stream s's pass buffer. */
static void run_stream(stream *s, const double *frames, const double *t, int n) {
    int R = afm_decim_factor(s->dec), ph = afm_decim_phase(s->dec);
    s->n_frames = afm_decim_run(s->dec, frames, n, s->frames);
    /* output k is completed by source sample (R - ph - 1) + k R */
    for (int k = 0; k < s->n_frames; k++)
        s->t[k] = t[(R - ph - 1) + k * R] - s->delay_s;
}

/* Append the current estimates as a period record. */
static void put_period(afm_chain *c) {
    int w = (c->p_head + c->p_count) % PERIOD_RING;
    if (c->p_count == PERIOD_RING) {
        c->p_head = (c->p_head + 1) % PERIOD_RING;
        c->stats.periods_dropped++;
    } else {
        c->p_count++;
    }
    afm_chain_period *p = &c->periods[w];
    p->harm = c->harm.out;
    if (c->cycle.periods > 0)
        p->cycle = c->cycle.out;
    else
        memset(&p->cycle, 0, sizeof p->cycle);
    p->lockin_amplitude_m = afm_lockin_amplitude(&c->lockin);
    p->lockin_phase_deg = afm_lockin_phase_deg(&c->lockin);
    c->stats.periods++;
}

/* The estimators over n samples. Tone 0's phase is computed here for the whole block, by
 * afm_drive_phase's own expression (the same values, without a call per sample). harm and
 * cycle share the period clock: each run ends at a sample where harm completed a period,
 * and cycle and lockin are brought to the same sample before the record is written.
 * estimator_rejects counts, per run, the most samples any one estimator refused. */
static void estimators(afm_chain *c, const afm_sample *s, const double *obd, int n) {
    double th[CHUNK], f[CHUNK];
    const afm_drive *d = c->drive;
    double ph = d->phase_rad[0], w = d->omega_rad_s[0], t0 = d->t0_s[0];
    for (int i = 0; i < n; i++) {
        th[i] = ph + w * (s[i].t_s - t0);
        f[i] = s[i].f_n;
    }
    for (int i = 0; i < n;) {
        long long rh = 0, rc = 0, rl;
        int done, dc;
        int k = afm_harm_push_n(&c->harm, obd + i, f + i, th + i, n - i, &done, &rh);
        for (int j = 0; j < k;) {
            j += afm_cycle_push_n(&c->cycle, s + i + j, th + i + j, k - j, &dc, &rc);
        }
        rl = afm_lockin_push_n(&c->lockin, obd + i, th + i, k);
        long long r = rh > rc ? rh : rc;
        c->stats.estimator_rejects += r > rl ? r : rl;
        if (done) put_period(c);
        i += k;
    }
}

int afm_chain_push(afm_chain *c, const afm_sample *s, int n) {
    double obd_buf[CHUNK];
    for (int done = 0; done < n;) {
        int k = n - done < CHUNK ? n - done : CHUNK;
        const afm_sample *p = s + done;
        long long sat0 = c->obd.n_saturated;
        for (int i = 0; i < k; i++) {
            int32_t cnt;
            double *f = c->in_frames + (size_t)i * AFM_DECIM_CH;
            obd_buf[i] = afm_obd_read(&c->obd, &p[i], &cnt);
            f[CH_X] = p[i].x_m;
            f[CH_OBD] = obd_buf[i];
            f[CH_F] = p[i].f_n;
            f[CH_BASE] = p[i].base_m;
            c->in_t[i] = p[i].t_s;
        }
        c->stats.obd_saturated += c->obd.n_saturated - sat0;
        c->obd.n_saturated = sat0;
        if (c->attached) estimators(c, p, obd_buf, k);
        for (int q = 0; q < c->n_streams; q++) {
            stream *st = &c->st[c->order[q]];
            if (st->src < 0) {
                run_stream(st, c->in_frames, c->in_t, k);
            } else {
                const stream *src = &c->st[st->src];
                run_stream(st, src->frames, src->t, src->n_frames);
            }
            ring_put(c, c->order[q]);
        }
        c->stats.pushed += k;
        done += k;
    }
    return 0;
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

int afm_chain_available(const afm_chain *c, int i) {
    return (i < 0 || i >= c->n_streams) ? 0 : c->st[i].count;
}

int afm_chain_take_periods(afm_chain *c, afm_chain_period *out, int max) {
    int n = 0;
    while (n < max && c->p_count > 0) {
        out[n++] = c->periods[c->p_head];
        c->p_head = (c->p_head + 1) % PERIOD_RING;
        c->p_count--;
    }
    return n;
}

void afm_chain_reset(afm_chain *c) {
    for (int i = 0; i < c->n_streams; i++) {
        afm_decim_reset(c->st[i].dec);
        c->st[i].head = c->st[i].count = 0;
    }
    afm_harm_reset(&c->harm);
    afm_lockin_reset(&c->lockin);
    if (c->attached) afm_cycle_reset(&c->cycle);
    c->p_head = c->p_count = 0;
}

int afm_chain_n_streams(const afm_chain *c) {
    return c->n_streams;
}
afm_chain_stats afm_chain_stats_get(const afm_chain *c) {
    afm_chain_stats s = c->stats;
    for (int i = 0; i < c->n_streams; i++)
        s.nonfinite += afm_decim_nonfinite(c->st[i].dec);
    return s;
}
const afm_obd *afm_chain_obd(const afm_chain *c) {
    return &c->obd;
}
