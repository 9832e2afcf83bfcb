/* SPDX-License-Identifier: MIT */
/* cmd_curve.c -- `afmtwin curve LOG`: an approach curve (or any curve over operating points)
 * from a log of the daemon's outputs, with no join: every harmonics record carries the Z,
 * the tones and the seq of the command in force, so the records of one operating point
 * are a run of records with the same (seq, Z, tones). Each run's last N records are
 * averaged and printed in the records of `afmtwin approach --json`, so that `afmtwin plot
 * approach` draws a daemon run and a test can compare the two.
 *
 * Averaging: harmonic k as the mean of A_k e^{i phi_k} over the N periods (equal periods
 * at a steady state: the DFT over the N periods), the lock-in of the run's last record, the
 * per-period metrics as means. Phases are the lag of the deflection behind the drive (90
 * deg free at resonance): lag_k = -(phi_k + 90) for x ~ A_k cos(k theta + phi_k). */
#include "afmtwin_cmds.h"
#include "opts.h"

#include "transport/afm_lcm_log.h"
#include "estimators/afm_orbit.h"
#include "transport/afm_lcm_wire.h"
#include "afmtwin_harmonics_t.h"
#include "json_out.h"
#include "lcm_tool.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CURVE_MAX_N 4096
#define CURVE_MAX_K 16
#define CURVE_DEG (360.0 / 6.283185307179586476925286766559)

typedef struct {
    const char *log;
    int analyse, min_records;
    bool json;
} curve_opts;

/* One harmonics record's numbers. */
typedef struct {
    int64_t seq;
    double z_m, fe_hz, ae_m, t_s;
    int n;
    int k[CURVE_MAX_K];
    double re[CURVE_MAX_K], im[CURVE_MAX_K]; /* A e^{i phi} */
    double lockin_amp_m, lockin_lag_deg, peak_force_n, min_defl_m, indentation_m, contact_s,
        ediss_j, mean_defl_m, esq_j;
    char tones_key[160]; /* the tone set, for the run's identity */
} curve_rec;

typedef struct {
    curve_rec ring[CURVE_MAX_N];
    long n;        /* records in the current run */
    double z_prev; /* Z of the last run printed (NAN: none) */
    bool retract;  /* Z increased from the run before */
    int runs;
} curve_state;

static void curve_usage(FILE *f) {
    fprintf(f, "usage: afmtwin curve LOG [--analyse N] [--min-records M] [--json]\n\n"
               "An approach (or any) curve from an LCM log of the daemon's outputs (afmtwin\n"
               "replay, lcm-logger on the output URL): the harmonics records of one operating\n"
               "point are a run of records with the same seq, Z (separation_m) and tones; each\n"
               "run's last N records (default 16) are averaged and printed as `afmtwin approach`\n"
               "prints a step (same keys with --json; `afmtwin plot approach` draws them). Runs\n"
               "with fewer than M records (default N) are skipped (a command that did not last\n"
               "long enough to be analysed; afmtwind and afmtwin replay keep at most 1000\n"
               "records a second by default: --harmonics-every 1 keeps every period's).\n"
               "direction is \"retract\" when Z grew from the run before. Phases: the lag of\n"
               "the deflection behind the drive (90 deg free at resonance). Exit status 0 ok,\n"
               "1 the log could not be read, 2 bad usage.\n");
}

static int parse_args(int argc, char **argv, curve_opts *o) {
    *o = (curve_opts){.analyse = 16, .min_records = -1};
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &o->json),
        AFMT_INT("--analyse", &o->analyse, 1, CURVE_MAX_N, NULL),
        AFMT_INT("--min-records", &o->min_records, 1, CURVE_MAX_N, NULL),
        AFMT_ARG("LOG", &o->log),
        AFMT_OPTS_END,
    };
    int rc = afmt_opts_parse("curve", opts, argc, argv, 1);
    if (rc) return rc == AFMT_OPTS_HELP ? 1 : -1;
    if (!o->log) {
        fprintf(stderr, "afmtwin curve: LOG is required\n");
        return -1;
    }
    if (o->min_records < 0) o->min_records = o->analyse;
    return 0;
}

static void rec_of(const afmtwin_harmonics_t *m, curve_rec *r) {
    memset(r, 0, sizeof *r);
    r->seq = m->seq_applied;
    r->z_m = m->separation_m;
    r->fe_hz = m->fe_hz;
    r->ae_m = m->n_tones > 0 ? m->tone_amplitude_m[0] : 0.0;
    r->t_s = m->t_s;
    r->n = m->n < CURVE_MAX_K ? m->n : CURVE_MAX_K;
    for (int i = 0; i < r->n; i++) {
        r->k[i] = m->k[i];
        r->re[i] = m->deflection_amplitude_m[i] * cos(m->deflection_phase_deg[i] / CURVE_DEG);
        r->im[i] = m->deflection_amplitude_m[i] * sin(m->deflection_phase_deg[i] / CURVE_DEG);
    }
    r->lockin_amp_m = m->lockin_amplitude_m;
    r->lockin_lag_deg = m->lockin_phase_deg;
    r->peak_force_n = m->peak_force_n;
    r->min_defl_m = m->min_deflection_m;
    r->indentation_m = m->indentation_m;
    r->contact_s = m->contact_time_s;
    r->ediss_j = m->dissipated_energy_j;
    r->esq_j = m->squeeze_dissipated_energy_j;
    r->mean_defl_m = m->mean_deflection_m;
    size_t off = 0;
    for (int j = 0; j < m->n_tones && off < sizeof r->tones_key - 40; j++)
        off += (size_t)snprintf(r->tones_key + off, sizeof r->tones_key - off, "%.17g/%.17g;",
                                m->tone_frequency_hz[j], m->tone_amplitude_m[j]);
}

static bool same_point(const curve_rec *a, const curve_rec *b) {
    return a->seq == b->seq && a->z_m == b->z_m && !strcmp(a->tones_key, b->tones_key);
}

/* The current run's averages, printed. */
static void flush_run(curve_state *c, const curve_opts *o) {
    if (c->n < o->min_records) {
        c->n = 0;
        return;
    }
    int n = (int)(c->n < o->analyse ? c->n : o->analyse);
    const curve_rec *last = &c->ring[(c->n - 1) % CURVE_MAX_N];
    double re[CURVE_MAX_K] = {0}, im[CURVE_MAX_K] = {0}, pk = 0, mind = 0, ind = 0, ct = 0, ed = 0,
           md = 0, eq = 0;
    for (int j = 0; j < n; j++) {
        const curve_rec *r = &c->ring[(c->n - 1 - j) % CURVE_MAX_N];
        for (int i = 0; i < last->n; i++) {
            re[i] += r->re[i] / n;
            im[i] += r->im[i] / n;
        }
        pk += r->peak_force_n / n;
        mind += r->min_defl_m / n;
        ind += r->indentation_m / n;
        ct += r->contact_s / n;
        ed += r->ediss_j / n;
        eq += r->esq_j / n;
        md += r->mean_defl_m / n;
    }
    if (!isnan(c->z_prev) && last->z_m != c->z_prev) c->retract = last->z_m > c->z_prev;
    c->z_prev = last->z_m;
    int i1 = -1;
    for (int i = 0; i < last->n; i++)
        if (last->k[i] == 1) i1 = i;
    double a1 = i1 >= 0 ? hypot(re[i1], im[i1]) : NAN;
    double l1 = i1 >= 0 ? afm_orbit_lag_deg(atan2(im[i1], re[i1]) * CURVE_DEG) : NAN;
    if (o->json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddNumberToObject(j, "z_m", last->z_m);
        cJSON_AddStringToObject(j, "direction", c->retract ? "retract" : "approach");
        cJSON_AddNumberToObject(j, "seq", (double)last->seq);
        cJSON_AddNumberToObject(j, "fe_hz", last->fe_hz);
        cJSON_AddNumberToObject(j, "ae_m", last->ae_m);
        cJSON_AddNumberToObject(j, "amplitude_m", a1);
        cJSON_AddNumberToObject(j, "phase_lag_deg", l1);
        cJSON *lk = cJSON_AddObjectToObject(j, "lockin");
        cJSON_AddNumberToObject(lk, "amplitude_m", last->lockin_amp_m);
        cJSON_AddNumberToObject(lk, "phase_lag_deg", last->lockin_lag_deg);
        cJSON *hs = cJSON_AddArrayToObject(j, "harmonics");
        for (int i = 0; i < last->n; i++) {
            cJSON *h = cJSON_CreateObject();
            cJSON_AddNumberToObject(h, "k", last->k[i]);
            cJSON_AddNumberToObject(h, "amplitude_m", hypot(re[i], im[i]));
            cJSON_AddNumberToObject(h, "phase_lag_deg",
                                    afm_orbit_lag_deg(atan2(im[i], re[i]) * CURVE_DEG));
            cJSON_AddItemToArray(hs, h);
        }
        cJSON_AddNumberToObject(j, "mean_deflection_m", md);
        cJSON_AddNumberToObject(j, "min_deflection_m", mind);
        cJSON_AddNumberToObject(j, "peak_force_n", pk);
        cJSON_AddNumberToObject(j, "indentation_m", ind);
        cJSON_AddNumberToObject(j, "contact_time_s", ct);
        cJSON_AddNumberToObject(j, "dissipated_energy_j", ed);
        cJSON_AddNumberToObject(j, "squeeze_dissipated_energy_j", eq);
        cJSON_AddNumberToObject(j, "analysed_periods", n);
        cJSON_AddNumberToObject(j, "records", (double)c->n);
        afmt_json_emit(j);
    } else {
        printf("%-8s %10.4f %12.6f %10.4f %12.6f %10.4f %10.4f %5d %6ld %lld\n",
               c->retract ? "retract" : "approach", last->z_m * 1e9, a1 * 1e9, l1,
               last->lockin_amp_m * 1e9, last->lockin_lag_deg, pk * 1e9, n, c->n,
               (long long)last->seq);
    }
    c->runs++;
    c->n = 0;
}

int afm_cmd_curve(int argc, char **argv) {
    curve_opts o;
    int rc = afmt_opts_done("curve", parse_args(argc, argv, &o), curve_usage);
    if (rc >= 0) return rc;
    char err[256];
    afm_lcm_log *l = afm_lcm_log_open(o.log, 0, err, sizeof err);
    if (!l) {
        fprintf(stderr, "afmtwin curve: cannot read the log: %s\n", err);
        return 1;
    }
    static curve_state c;
    c.z_prev = NAN;
    if (!o.json)
        printf("%-8s %10s %12s %10s %12s %10s %10s %5s %6s %s\n", "# dir", "Z_nm", "A1_nm",
               "lag_deg", "lockin_nm", "li_lag", "Fpeak_nN", "N", "recs", "seq");
    afm_lcm_log_event ev;
    long bad = 0;
    while ((rc = afm_lcm_log_next(l, &ev, err, sizeof err)) > 0) {
        if (!afm_lcm_log_channel_is(ev.channel, AFMT_CHAN_HARMONICS)) continue;
        afmtwin_harmonics_t m;
        char why[256];
        if (afm_wire_decode(&afm_wire_harmonics_t, ev.data, (int)ev.datalen, &m, why, sizeof why)) {
            bad++;
            continue;
        }
        curve_rec r;
        rec_of(&m, &r);
        afm_wire_free(&afm_wire_harmonics_t, &m);
        if (c.n > 0 && !same_point(&c.ring[(c.n - 1) % CURVE_MAX_N], &r)) flush_run(&c, &o);
        c.ring[c.n++ % CURVE_MAX_N] = r;
    }
    if (c.n > 0) flush_run(&c, &o);
    long long skipped = afm_lcm_log_skipped(l);
    afm_lcm_log_close(&l);
    if (skipped > 0)
        fprintf(stderr, "afmtwin curve: %s: skipped %lld bytes that are no LCM event\n", o.log,
                skipped);
    if (bad) fprintf(stderr, "afmtwin curve: %ld harmonics records did not decode\n", bad);
    if (rc < 0) {
        fprintf(stderr, "afmtwin curve: %s: %s\n", o.log, err);
        return 1;
    }
    if (c.runs == 0) {
        fprintf(stderr,
                "afmtwin curve: %s: no operating point with %d harmonics records (the daemon "
                "and replay keep at most 1000 a second: dwell longer, log with "
                "--harmonics-every 1, or lower --min-records)\n",
                o.log, o.min_records);
        return 1;
    }
    return 0;
}
