/* SPDX-License-Identifier: MIT */
/* afm_lcm_encode.c -- output records to generated LCM messages (contract in
 * afm_lcm_encode.h). */
#include "afm_lcm_encode.h"

#include <string.h>

void afm_lcm_samples_msg(const afm_io_samples *s, afmtwin_samples_t *m) {
    *m = (afmtwin_samples_t){
        .utime = s->utime,
        .seq_applied = s->seq_applied,
        .stream = (int8_t)s->stream,
        .t0_s = s->t0_s,
        .rate_hz = s->rate_hz,
        .n = s->n,
        .deflection_m = (float *)s->deflection_m,
        .obd_m = (float *)s->obd_m,
        .obd_counts = (int32_t *)s->obd_counts,
        .force_n = (float *)s->force_n,
    };
}

void afm_lcm_harmonics_msg(const afm_io_harmonics *h, afm_lcm_harm_buf *b, afmtwin_harmonics_t *m) {
    const afm_harm_result *r = &h->p.harm;
    const afm_cycle_metrics *c = &h->p.cycle;
    int n = r->n_harmonics;
    if (n < 0) n = 0;
    if (n > AFM_MAX_HARMONICS) n = AFM_MAX_HARMONICS;
    for (int i = 0; i < n; i++) {
        b->k[i] = (int16_t)r->h[i].k;
        b->xa[i] = r->h[i].x_amp_m;
        b->xp[i] = r->h[i].x_phase_deg;
        b->fa[i] = r->h[i].f_amp_n;
        b->fp[i] = r->h[i].f_phase_deg;
        b->pd[i] = r->h[i].phase_diff_deg;
    }
    *m = (afmtwin_harmonics_t){
        .utime = h->utime,
        .seq_applied = h->seq_applied,
        .t_s = c->t_start_s,
        .fe_hz = h->fe_hz,
        .n = (int8_t)n,
        .k = b->k,
        .deflection_amplitude_m = b->xa,
        .deflection_phase_deg = b->xp,
        .force_amplitude_n = b->fa,
        .force_phase_deg = b->fp,
        .phase_diff_deg = b->pd,
        .lockin_amplitude_m = h->p.lockin_amplitude_m,
        .lockin_phase_deg = h->p.lockin_phase_deg,
        .peak_force_n = c->peak_force_n,
        .min_deflection_m = c->min_deflection_m,
        .indentation_m = c->indentation_m,
        .contact_time_s = c->contact_time_s,
        .pre_contact_velocity_m_s = c->pre_contact_velocity_m_s,
        .dissipated_energy_j = c->dissipated_energy_j,
        .mean_deflection_m = c->mean_deflection_m,
    };
}

void afm_lcm_status_msg(const afm_io_status *s, afmtwin_status_t *m) {
    *m = (afmtwin_status_t){
        .utime = s->utime,
        .seq_applied = s->seq_applied,
        .model_time_s = s->model_time_s,
        .realtime_factor = s->realtime_factor,
        .overruns = s->overruns,
        .lag_s = s->lag_s,
        .received = s->received,
        .rejected = s->rejected,
        .last_reject = (char *)s->last_reject,
        .blowups = s->blowups,
        .mode = (char *)(s->mode ? s->mode : ""),
        .running = (int8_t)s->running,
        .separation_m = s->separation_m,
        .fe_hz = s->fe_hz,
        .amplitude_m = s->amplitude_m,
        .applied = s->applied,
        .resyncs = s->resyncs,
        .chain_stalls = s->chain_stalls,
        .chain_lag_s = s->chain_lag_s,
        .can_state = (char *)(s->can_state[0] ? s->can_state : "off"), /* issue 6 */
        .can_frames = s->can_frames,
        .can_rejected = s->can_rejected,
        .can_errors = s->can_errors,
        .can_reconnects = s->can_reconnects,
        .can_last_reject = (char *)s->can_last_reject,
        .heartbeat_ok = (int8_t)s->heartbeat_ok,
        .refused = s->refused, /* issue 13 */
        .last_refusal = (char *)s->last_refusal,
        .dropped = s->dropped,
        .last_drop = (char *)s->last_drop,
        .auto_paused = (int8_t)s->auto_paused,
        .pause_reason = (char *)s->pause_reason,
    };
}
