/* SPDX-License-Identifier: MIT */
/* test_cycle_defer.c -- afm_cycle's deferred steps (afm_cycle_set_defer, issue 29) give the
 * eager path's metrics bit for bit once finished.
 *
 * The output chain keeps the continuous-path work of a period (local_peak in contact, the
 * force at the minimum, the contact steps' work) with the period's record and computes it
 * only for the records it publishes. What a reader sees must not change: on rt's settled
 * tapping orbits (default.conf at its Z 40 nm and at Z 15 nm, hard contact, where a period
 * has more near-contact steps; nchv.conf, chattering; and at 4x the sample rate, where a
 * period has more than the record holds and they are finished at once), the same
 * samples go through an eager afm_cycle and a deferred one, through afm_cycle_push_n in
 * blocks of random lengths (the chain's vector runs; the deferred one, as the chain, with the
 * squeeze film split off by afm_cycle_split_forces: afm_cycle_push_n_split) and afm_cycle_push_ev
 * (the integrator's records, the accurate scheme), with a change of Z in the middle of the run and
 * a change of the force law's values in place (as the runner's mirror changes them, before
 * afm_cycle_set_forces): every period's metrics, finished from a copy of the record taken at
 * the period's end and finished later, are memcmp-equal to the eager ones. The deferred
 * record must also defer (most periods hold entries; their energy is NaN until finished). */
#include "check.h"

#include "estimators/afm_cycle.h"
#include "forces/afm_drive.h"
#include "runner/afm_twin.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NB 4096
#define MAXP 4000

static afm_cycle eager, lazy;
static afm_cycle_metrics got_e[MAXP], got_l[MAXP];
static afm_cycle_deferred def_l[MAXP];

static void defer_case(const char *config, double z_m, double oversample, bool events,
                       unsigned seed) {
    static afm_config cfg;
    char err[AFM_ERR_LEN], what[240];
    if (!check_true(afm_config_load(config, &cfg, err, sizeof err) == 0, config)) return;
    if (z_m > 0) cfg.drive.separation_m = z_m;
    cfg.sim.integrator = AFM_INTEGRATOR_RT;
    cfg.sim.sample_rate_hz *= oversample;
    cfg.sim.rt_scheme = events ? AFM_RT_SCHEME_ACCURATE : AFM_RT_SCHEME_FAST;
    afm_sim *s = afm_twin_create(&cfg, NULL, NULL, err, sizeof err);
    if (!check_true(s != NULL, "rt twin")) return;
    static afm_step_events ring[2 * NB];
    if (events) afm_sim_set_events(s, ring, 2 * NB);
    static afm_sample b[NB];
    const double fe = afm_sim_drive(s)->freq_hz[0], fs = cfg.sim.sample_rate_hz;
    for (long k = 0; k < (long)(300 * fs / fe); k += NB) /* settle */
        afm_sim_run(s, NB, b);
    /* the law both cycles read, changed in place as the runner's mirror does */
    static afm_force_params law;
    law = *afm_sim_forces(s);
    double z = afm_sim_separation(s);
    afm_cycle_init(&eager, afm_force_contact_x(&law, z), law.cos_alpha, NULL, 0);
    afm_cycle_init(&lazy, afm_force_contact_x(&law, z), law.cos_alpha, NULL, 0);
    afm_cycle_set_forces(&eager, &law, z);
    afm_cycle_set_forces(&lazy, &law, z);
    afm_cycle_set_defer(&lazy, true);
    const afm_drive *d = afm_sim_drive(s);
    int ne = 0, nl = 0, deferred = 0, nan_e = 0, blocks = 0;
    bool z_moved = false, law_moved = false;
    long long rej_e = 0, rej_l = 0;
    srand(seed);
    const int total = 1200; /* periods */
    while (ne < total && blocks < 4000) {
        if (afm_sim_run(s, NB, b) != AFM_SIM_OK) break;
        static double th[NB];
        for (int i = 0; i < NB; i++)
            th[i] = afm_drive_phase_mod(d, 0, b[i].t_s);
        /* Z moves in block 3 and the law's values in block 6, each right after a contact
         * (its deferred steps pending: flagged under the old Z or law) */
        int chg = -1;
        const double xc = afm_force_contact_x(&law, z);
        if (blocks == 3 || blocks == 6)
            for (int i = 8; i < NB && chg < 0; i++)
                if (b[i - 2].x_m < xc && b[i - 1].x_m < xc && !(b[i].x_m < xc)) chg = i;
        for (int i = 0; i < NB;) {
            int k = 1 + rand() % 700;
            if (k > NB - i) k = NB - i;
            if (i < chg && i + k > chg) k = chg - i;
            if (i == chg && blocks == 3) { /* both, as afm_chain_set_separation */
                z -= 0.5e-9;
                afm_cycle_set_forces(&eager, &law, z);
                afm_cycle_set_forces(&lazy, &law, z);
                z_moved = true;
            }
            if (i == chg && blocks == 6) { /* in place (the mirror), then set_forces */
                law.visco_coef *= 1.25;
                law.hertz_coef *= 0.9;
                afm_cycle_set_forces(&eager, &law, z);
                afm_cycle_set_forces(&lazy, &law, z);
                law_moved = true;
            }
            for (int j = 0; j < k;) {
                const int a = i + j;
                int de, dl, me, ml;
                if (events) { /* one by one with the records */
                    const afm_step_events *ev = afm_sim_events_at(s, b[a].t_s);
                    de = afm_cycle_push_ev(&eager, &b[a], th[a], ev) == 1;
                    dl = afm_cycle_push_ev(&lazy, &b[a], th[a], ev) == 1;
                    me = ml = 1;
                } else { /* the deferred one with the chain's split (afm_chain.c) */
                    static double fts[NB], psq[NB];
                    afm_cycle_split_forces(&lazy, b + a, k - j, fts, psq);
                    me = afm_cycle_push_n(&eager, b + a, th + a, k - j, &de, &rej_e);
                    ml = afm_cycle_push_n_split(&lazy, b + a, th + a, fts, psq, k - j, &dl, &rej_l);
                }
                if (me != ml || de != dl) {
                    check_true(false, "eager and deferred consume the same samples");
                    afm_sim_destroy(&s);
                    return;
                }
                if (de && ne < MAXP) got_e[ne++] = eager.out;
                if (dl && nl < MAXP) { /* a copy of the record, finished later */
                    got_l[nl] = lazy.out;
                    memcpy(&def_l[nl], &lazy.out_def, AFM_CYCLE_DEFERRED_SIZE(&lazy.out_def));
                    deferred += def_l[nl].n > 0;
                    nan_e += isnan(got_l[nl].dissipated_energy_j);
                    nl++;
                }
                j += me;
            }
            i += k;
        }
        blocks++;
    }
    for (int p = 0; p < nl; p++) /* after the run, the law changed since for some */
        afm_cycle_finish(&got_l[p], &def_l[p]);
    int first_diff = -1;
    for (int p = 0; p < ne && p < nl && first_diff < 0; p++)
        if (memcmp(&got_e[p], &got_l[p], sizeof got_e[p]) != 0) first_diff = p;
    printf("  %s Z %.1f nm (%s): %d periods, %d with deferred steps (%d energies waiting), %ld "
           "times the record was full; first difference: %d\n",
           config, z * 1e9, events ? "push_ev" : "push_n", ne, deferred, nan_e, lazy.def_overflows,
           first_diff);
    if (first_diff >= 0)
        printf("    period %d: peak %.17g / %.17g, E %.17g / %.17g\n", first_diff,
               got_e[first_diff].peak_force_n, got_l[first_diff].peak_force_n,
               got_e[first_diff].dissipated_energy_j, got_l[first_diff].dissipated_energy_j);
    snprintf(what, sizeof what,
             "%s Z %.0f nm %s: as many periods (>= %d), Z and law moved after a contact", config,
             z * 1e9, events ? "push_ev" : "push_n", total);
    check_true(ne == nl && ne >= total && rej_e == rej_l && z_moved && law_moved, what);
    snprintf(what, sizeof what, "%s Z %.0f nm %s: deferred = eager bit for bit, every period",
             config, z * 1e9, events ? "push_ev" : "push_n");
    check_true(first_diff < 0, what);
    snprintf(what, sizeof what, "%s Z %.0f nm %s: most periods deferred work", config, z * 1e9,
             events ? "push_ev" : "push_n");
    check_true(deferred > ne / 2, what);
    if (oversample > 1) {
        snprintf(what, sizeof what, "%s Z %.0f nm x%g: the record was full (finished at once)",
                 config, z * 1e9, oversample);
        check_true(lazy.def_overflows > 0, what);
    }
    afm_sim_destroy(&s);
}

int main(void) {
    defer_case("config/default.conf", 0, 1, false, 1);
    defer_case("config/default.conf", 0, 1, true, 2);
    defer_case("config/default.conf", 15e-9, 1, false, 3);
    defer_case("config/nchv.conf", 0, 1, false, 4);
    /* 4x the rate: more near-contact steps a period than the record holds (overflow) */
    defer_case("config/default.conf", 15e-9, 4, false, 5);
    return check_done();
}
