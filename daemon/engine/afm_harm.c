/* SPDX-License-Identifier: MIT */
/* afm_harm.c -- streaming per-period harmonics (contract in afm_harm.h). */
#include "afm_harm.h"

#include <stdio.h>
#include <string.h>

int afm_harm_init(afm_harm *h, const int *ks, int nk, char *err, size_t errlen) {
    if (!h || !ks || nk < 1 || nk > AFM_MAX_HARMONICS) {
        if (err && errlen)
            snprintf(err, errlen, "harmonics: need 1..%d harmonic numbers", AFM_MAX_HARMONICS);
        return -1;
    }
    for (int j = 0; j < nk; j++)
        if (ks[j] < 1 || ks[j] > AFM_HARM_MAX_K) {
            if (err && errlen)
                snprintf(err, errlen, "harmonics: harmonic number %d not in 1..%d", ks[j],
                         AFM_HARM_MAX_K);
            return -1;
        }
    memset(h, 0, sizeof *h);
    h->nk = nk;
    h->ks[0] = 1;
    memcpy(h->ks + 1, ks, (size_t)nk * sizeof *ks);
    h->out.n_harmonics = nk;
    return 0;
}

void afm_harm_reset(afm_harm *h) {
    int nk = h->nk, ks[AFM_MAX_HARMONICS + 1];
    memcpy(ks, h->ks, sizeof ks);
    memset(h, 0, sizeof *h);
    h->nk = nk;
    memcpy(h->ks, ks, sizeof ks);
    h->out.n_harmonics = nk;
}

/* e^{-i k phi} from c + i s = e^{-i phi} by binary powering. */
static void rot_pow(double c, double s, int k, double *re, double *im) {
    double rr = 1.0, ri = 0.0;
    while (k) {
        if (k & 1) {
            double t = rr * c - ri * s;
            ri = rr * s + ri * c;
            rr = t;
        }
        k >>= 1;
        if (k) {
            double t = c * c - s * s;
            s = 2.0 * c * s;
            c = t;
        }
    }
    *re = rr;
    *im = ri;
}

static void finish_period(afm_harm *h) {
    double scale = 2.0 / h->wsum;
    double phi1 = atan2(h->xi[0], h->xr[0]);
    h->out.period = h->periods;
    h->out.samples = h->wsum;
    h->out.n_harmonics = h->nk;
    for (int j = 1; j <= h->nk; j++) {
        afm_orbit_harmonic *o = &h->out.h[j - 1];
        double phk = atan2(h->xi[j], h->xr[j]);
        o->k = h->ks[j];
        o->x_amp_m = scale * hypot(h->xr[j], h->xi[j]);
        o->x_phase_deg = phk * AFM_EST_RAD2DEG;
        o->f_amp_n = scale * hypot(h->fr[j], h->fi[j]);
        o->f_phase_deg = atan2(h->fi[j], h->fr[j]) * AFM_EST_RAD2DEG;
        o->phase_diff_deg = afm_phase_diff_deg(o->k, phi1, phk);
    }
    h->periods++;
}

int afm_harm_push(afm_harm *h, double x, double f, double theta_rad) {
    if (!isfinite(x) || !isfinite(f) || afm_clock_check(&h->clk, theta_rad) != AFM_CLOCK_NONE)
        return -1;
    bool had_prev = h->clk.started;
    double frac = 1.0;
    /* phi: phase since the last boundary; at a boundary e^{-ik phi} is the same for both
     * periods since k is an integer */
    double phi;
    int ev = afm_clock_advance(&h->clk, theta_rad, &frac, &phi);
    double c1 = cos(phi), s1 = -sin(phi);
    int n = h->nk + 1, done = 0;
    double er[AFM_MAX_HARMONICS + 1], ei[AFM_MAX_HARMONICS + 1];
    for (int j = 0; j < n; j++)
        rot_pow(c1, s1, h->ks[j], &er[j], &ei[j]);

    if (had_prev && h->active) {
        double wb[2] = {0.5, 0.5}, wa[2];
        if (ev == AFM_CLOCK_CROSS) afm_split_weights(frac, wb, wa);
        for (int j = 0; j < n; j++) {
            h->xr[j] += wb[0] * h->x_prev * h->er_prev[j] + wb[1] * x * er[j];
            h->xi[j] += wb[0] * h->x_prev * h->ei_prev[j] + wb[1] * x * ei[j];
            h->fr[j] += wb[0] * h->f_prev * h->er_prev[j] + wb[1] * f * er[j];
            h->fi[j] += wb[0] * h->f_prev * h->ei_prev[j] + wb[1] * f * ei[j];
        }
        h->wsum += ev == AFM_CLOCK_CROSS ? frac : 1.0;
        if (ev == AFM_CLOCK_CROSS) {
            finish_period(h);
            done = 1;
        }
    }
    if (ev == AFM_CLOCK_START || (ev == AFM_CLOCK_CROSS && had_prev)) {
        /* a new period starts: at this sample, or inside the step just taken */
        double wb[2], wa[2] = {0.0, 0.0};
        if (ev == AFM_CLOCK_CROSS) afm_split_weights(frac, wb, wa);
        for (int j = 0; j < n; j++) {
            h->xr[j] = wa[0] * h->x_prev * h->er_prev[j] + wa[1] * x * er[j];
            h->xi[j] = wa[0] * h->x_prev * h->ei_prev[j] + wa[1] * x * ei[j];
            h->fr[j] = wa[0] * h->f_prev * h->er_prev[j] + wa[1] * f * er[j];
            h->fi[j] = wa[0] * h->f_prev * h->ei_prev[j] + wa[1] * f * ei[j];
        }
        h->wsum = ev == AFM_CLOCK_CROSS ? 1.0 - frac : 0.0;
        h->active = true;
    }
    h->x_prev = x;
    h->f_prev = f;
    memcpy(h->er_prev, er, (size_t)n * sizeof er[0]);
    memcpy(h->ei_prev, ei, (size_t)n * sizeof ei[0]);
    return done;
}

int afm_harm_default_list(const afm_modal *m, double fe_hz, int *ks) {
    if (!(fe_hz > 0) || !ks) return 0;
    int cand[5] = {1, 2, 3, 0, 0}, nc = 3;
    for (int i = 1; m && i <= 2 && i < m->n; i++) {
        double r = m->omega_rad_s[i] / (AFM_EST_TWO_PI * fe_hz);
        if (r >= 0.5 && r < (double)AFM_HARM_MAX_K) cand[nc++] = (int)floor(r + 0.5);
    }
    /* insertion sort, then drop repeats */
    for (int i = 1; i < nc; i++)
        for (int j = i; j > 0 && cand[j - 1] > cand[j]; j--) {
            int t = cand[j];
            cand[j] = cand[j - 1];
            cand[j - 1] = t;
        }
    int n = 0;
    for (int i = 0; i < nc; i++)
        if (n == 0 || cand[i] != ks[n - 1]) ks[n++] = cand[i];
    return n;
}
