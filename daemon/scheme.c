/* SPDX-License-Identifier: MIT */
/* scheme.c -- which scheme of the rt integrator the daemon runs (issue 28): chosen before
 * real time starts by measuring both schemes on this model on this machine (auto), and
 * handed over from the real-time thread to the fast scheme when the loop falls behind, and
 * back when the margin returns (with a growing hold-off, so it never flaps).
 *
 * Measurement (main thread, before the threads start): afm_scheme_cost_measure, both
 * schemes' worst state; the accurate scheme runs when its worst state fits
 * AFM_SCHEME_FIT_SHARE of the per-sample budget dt / speed. The accurate scheme is measured
 * with the integrator's per-step record when the runner will hand it to the chain
 * (sim.step_events; afm_runner_step_events): the record costs the integrator thread. With
 * sim.step_events = "auto", when only the accurate scheme without the record fits, it runs
 * without it (the per-period metrics from the samples, as before issue 28), which is
 * measured then; "on" keeps the record and falls to the fast scheme instead.
 *
 * Hand-over (rt thread, realtime mode, auto and adaptive only): the accurate scheme hands
 * over to the fast one when the lag passes LAG_SHARE of --max-lag-ms (before any resync);
 * after HOLD_S (doubled after each hand-over that came back too soon, up to HOLD_MAX_S) it
 * tries the accurate scheme again if the last second's busy fraction is below BACK_BUSY.
 * Both schemes share the modal state, so a hand-over is continuous (afm_sim_set_scheme). */
#include "twind.h"

#include "runner/afm_scheme_cost.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#define LAG_SHARE 0.25
#define HOLD_S 2.0
#define HOLD_MAX_S 64.0
#define BACK_BUSY 0.6

const char *twind_scheme_opt_name(twind_scheme s) {
    switch (s) {
    case TWIND_SCHEME_AUTO:
        return "auto";
    case TWIND_SCHEME_ADAPTIVE:
        return "adaptive";
    case TWIND_SCHEME_ACCURATE:
        return "accurate";
    case TWIND_SCHEME_FAST:
        return "fast";
    case TWIND_SCHEME_CONFIG:
        return "config";
    }
    return "?";
}

int twind_scheme_choose(twind *d, afm_config *cfg, char *err, size_t errlen) {
    twind_scheme_state *sc = &d->scheme;
    twind_scheme want = d->opt.scheme;
    sc->handover = false;
    sc->rt = cfg->sim.integrator == AFM_INTEGRATOR_RT;
    if (want == TWIND_SCHEME_CONFIG)
        snprintf(sc->from, sizeof sc->from, "--scheme config: sim.rt_scheme %s",
                 cfg->sim.rt_scheme == AFM_RT_SCHEME_ACCURATE ? "accurate"
                 : cfg->sim.rt_scheme == AFM_RT_SCHEME_FAST   ? "fast"
                                                              : "auto");
    else
        snprintf(sc->from, sizeof sc->from, "--scheme %s", twind_scheme_opt_name(want));
    if (!sc->rt) {
        sc->accurate = false;
        snprintf(sc->reason, sizeof sc->reason, "-: the %s integrator has no schemes",
                 cfg->sim.integrator == AFM_INTEGRATOR_REFERENCE ? "reference" : "arkode-erk");
        return 0;
    }
    if (want == TWIND_SCHEME_CONFIG) /* no --scheme: the config's sim.rt_scheme */
        want = cfg->sim.rt_scheme == AFM_RT_SCHEME_ACCURATE ? TWIND_SCHEME_ACCURATE
               : cfg->sim.rt_scheme == AFM_RT_SCHEME_FAST   ? TWIND_SCHEME_FAST
                                                            : TWIND_SCHEME_AUTO;
    const bool realtime = d->opt.mode == TWIND_REALTIME;
    switch (want) {
    case TWIND_SCHEME_ACCURATE:
    case TWIND_SCHEME_FAST:
        sc->accurate = want == TWIND_SCHEME_ACCURATE;
        snprintf(sc->reason, sizeof sc->reason, "forced (%s)",
                 d->opt.scheme == TWIND_SCHEME_CONFIG ? "config sim.rt_scheme" : "--scheme");
        break;
    case TWIND_SCHEME_ADAPTIVE:
        sc->accurate = true;
        sc->handover = realtime;
        snprintf(sc->reason, sizeof sc->reason, "adaptive: accurate, fast while behind");
        break;
    default: {
        if (!realtime) { /* no deadline: the accurate scheme costs time, not truth */
            sc->accurate = true;
            snprintf(sc->reason, sizeof sc->reason, "auto: accurate (%s mode has no deadline)",
                     twind_mode_name(d->opt.mode));
            break;
        }
        double budget = cfg->sim.sample_rate_hz > 0 ? 1e9 / cfg->sim.sample_rate_hz : 0;
        if (d->opt.speed > 0) budget /= d->opt.speed;
        afm_scheme_cost ca, cf;
        if (afm_scheme_cost_measure(cfg, AFM_RT_SCHEME_ACCURATE, &ca, err, errlen) ||
            afm_scheme_cost_measure(cfg, AFM_RT_SCHEME_FAST, &cf, err, errlen))
            return -1;
        const double fit_ns = AFM_SCHEME_FIT_SHARE * budget;
        sc->ns_accurate = ca.worst_ns;
        sc->ns_fast = cf.worst_ns;
        sc->accurate = sc->ns_accurate <= fit_ns;
        double ns_rec = -1; /* the accurate scheme with the record, when it did not fit */
        if (!sc->accurate && ca.step_events && cfg->sim.step_events == AFM_STEP_EVENTS_AUTO) {
            static afm_config c; /* large; start-up only */
            c = *cfg;
            c.sim.step_events = AFM_STEP_EVENTS_OFF;
            afm_scheme_cost cn;
            if (afm_scheme_cost_measure(&c, AFM_RT_SCHEME_ACCURATE, &cn, err, errlen)) return -1;
            ns_rec = sc->ns_accurate;
            sc->ns_accurate = cn.worst_ns;
            sc->accurate = sc->ns_accurate <= fit_ns;
            if (sc->accurate) cfg->sim.step_events = AFM_STEP_EVENTS_OFF; /* the runner's */
        }
        sc->handover = sc->accurate;
        char rec[64] = "";
        if (ns_rec >= 0)
            snprintf(rec, sizeof rec, " without the step record (%.0f ns with it)", ns_rec);
        else if (ca.step_events)
            snprintf(rec, sizeof rec, " with the step record");
        snprintf(sc->reason, sizeof sc->reason,
                 "auto: accurate %.0f ns/sample in its worst state %s %.0f ns (%.0f%% of %.1f "
                 "ns)%s; fast %.0f ns",
                 sc->ns_accurate, sc->accurate ? "<=" : ">", fit_ns, 100.0 * AFM_SCHEME_FIT_SHARE,
                 budget, rec, sc->ns_fast);
    }
    }
    cfg->sim.rt_scheme = sc->accurate ? AFM_RT_SCHEME_ACCURATE : AFM_RT_SCHEME_FAST;
    sc->hold_s = HOLD_S;
    return 0;
}

void twind_scheme_turn(twind *d, afm_runner *r, twind_snapshot *snap, double late_s, double model_s,
                       double now_s) {
    twind_scheme_state *sc = &d->scheme;
    if (snap->scheme_accurate)
        snap->model_s_accurate += model_s;
    else
        snap->model_s_fast += model_s;
    if (sc->handover) {
        if (sc->accurate && late_s > LAG_SHARE * d->opt.max_lag_s) {
            /* behind: to the fast scheme before the lag becomes a resync; a hand-over that
             * follows a return within two hold-offs doubles the next hold-off */
            sc->accurate = false;
            if (now_s - sc->t_switch_s < 2.0 * sc->hold_s)
                sc->hold_s = fmin(2.0 * sc->hold_s, HOLD_MAX_S);
            sc->t_switch_s = now_s;
            snap->scheme_handovers++;
            snprintf(snap->scheme_reason, sizeof snap->scheme_reason,
                     "overload: lag %.0f ms, fast until the margin returns (in %.0f s or later)",
                     late_s * 1e3, sc->hold_s);
        } else if (!sc->accurate && now_s - sc->t_switch_s > sc->hold_s && late_s <= 0 &&
                   snap->busy_fraction > 0 && snap->busy_fraction < BACK_BUSY) {
            sc->accurate = true;
            sc->t_switch_s = now_s;
            snap->scheme_handovers++;
            snprintf(snap->scheme_reason, sizeof snap->scheme_reason,
                     "margin back: busy %.0f%% on the fast scheme, accurate again",
                     100.0 * snap->busy_fraction);
        }
    }
    /* every turn: a model swapped in starts in its config's scheme */
    bool was = sc->rt && !strcmp(afm_sim_scheme_name(afm_runner_sim(r)), "accurate");
    if (sc->rt && afm_runner_set_scheme(r, sc->accurate) == 0) {
        snap->scheme_accurate = sc->accurate;
        if (was != sc->accurate) twind_applied_scheme(d, sc->accurate, snap->st.samples);
    }
}
