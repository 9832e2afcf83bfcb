/* SPDX-License-Identifier: MIT */
/* afm_phase_gen.c -- tone 0's phase from the sample index (afm_phase_gen.h): one generator
 * for the chain's estimators and the runner's control lock-in. */
#include "estimators/afm_phase_gen.h"

#include "config/afm_clones.h"
#include "estimators/afm_est_internal.h"

#include <math.h>

void afm_phase_gen_reset(afm_phase_gen *g, double fs_hz) {
    g->fs = fs_hz;
    g->set = false;
    g->t_last = NAN;
}

/* th[j] = p + wdt (k + j) for j < m: four at a time (one rounding each, fma: the same bits
 * as the scalar loop). The four indices go through memory and the fmas are a loop of 4: so
 * gcc makes them one vfmadd in the x86-64-v3 copy (AFM_V4_FMA on the broadcasts was 4 scalar
 * vfmadds and their shuffles: 17 instructions for 4 samples, now 7; issue 12). */
AFM_CLONES static void phase_run(double *th, int m, double wdt, double k, double p) {
    int j = 0;
    afm_v4 vk = AFM_V4_SET1(k) + (afm_v4){0.0, 1.0, 2.0, 3.0};
    double kk[4] __attribute__((aligned(32)));
    for (; j + 4 <= m; j += 4) {
        AFM_V4_ST(kk, vk);
        for (int l = 0; l < 4; l++)
            th[j + l] = fma(wdt, kk[l], p);
        vk = vk + 4.0;
    }
    for (; j < m; j++)
        th[j] = fma(wdt, k + (double)j, p);
}

static afm_phase_change thetas(afm_phase_gen *g, const afm_drive *d, const afm_sample *s, int n,
                               double *th) {
    afm_phase_change ch = AFM_PHASE_SAME;
    if (!g->set || g->ph != d->phase_rad[0] || g->w != d->omega_rad_s[0] || g->t0 != d->t0_s[0]) {
        if (g->set) ch = AFM_PHASE_JUMP; /* a change, not the first frame (STEP: see run) */
        g->ph = d->phase_rad[0];
        g->w = d->omega_rad_s[0];
        g->t0 = d->t0_s[0];
        g->wdt = g->w * (1.0 / g->fs);
        g->set = false; /* origin from the first sample below */
    }
    double kd = (s[0].t_s - g->t0) * g->fs, k = nearbyint(kd);
    if (!(fabs(kd - k) < 0.25 && k >= 0 && k < 0x1p52)) {
        for (int i = 0; i < n; i++)
            th[i] = g->ph + g->w * (s[i].t_s - g->t0);
        return ch;
    }
    if (!g->set || k < g->k_org) { /* the segment of the first sample */
        g->k_org = afm_floor(k / AFM_PHASE_GEN_REBASE) * AFM_PHASE_GEN_REBASE;
        g->p_org = g->k_org > 0 ? afm_clock_wrap(fma(g->wdt, g->k_org, g->ph)) : g->ph;
        if (g->k_org > 0 && d->on_grid[0])
            g->p_org = afm_drive_phase_mod(d, 0, g->t0 + g->k_org / g->fs);
        g->set = true;
    }
    for (int i = 0; i < n;) {
        while (k + i >= g->k_org + AFM_PHASE_GEN_REBASE) { /* into the next segment */
            g->p_org = afm_clock_wrap(fma(g->wdt, AFM_PHASE_GEN_REBASE, g->p_org));
            g->k_org += AFM_PHASE_GEN_REBASE;
            if (d->on_grid[0]) /* no accumulated rounding (afm_drive.h) */
                g->p_org = afm_drive_phase_mod(d, 0, g->t0 + g->k_org / g->fs);
        }
        double left = g->k_org + AFM_PHASE_GEN_REBASE - (k + i);
        int m = left < (double)(n - i) ? (int)left : n - i;
        phase_run(th + i, m, g->wdt, k + i - g->k_org, g->p_org);
        i += m;
    }
    return ch;
}

afm_phase_change afm_phase_gen_run(afm_phase_gen *g, const afm_drive *d, const afm_sample *s, int n,
                                   double *th) {
    afm_phase_change ch = thetas(g, d, s, n, th);
    /* on the grid, and s[0] the sample right after the last one given: a step */
    if (ch == AFM_PHASE_JUMP && g->set && fabs((s[0].t_s - g->t_last) * g->fs - 1.0) < 0.25)
        ch = AFM_PHASE_STEP;
    g->t_last = s[n - 1].t_s;
    return ch;
}
