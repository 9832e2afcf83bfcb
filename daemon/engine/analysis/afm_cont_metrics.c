/* SPDX-License-Identifier: MIT */
/* afm_cont_metrics.c -- per-orbit metrics at the roots of the flow (contract in
 * afm_cont_metrics.h). */
#include "analysis/afm_cont_metrics.h"

#include "analysis/afm_cont_flow_impl.h"
#include "estimators/afm_lockin.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

typedef struct {
    const afm_cont_flow *f;
    afm_cont_metrics *m;
    int ci;                 /* kink index of the contact line, -1 if none */
    double xc;              /* contact line */
    bool in;                /* in contact now */
    double tau_in;          /* phase time of the current contact's entry */
    afm_cont_contact *cur;  /* the contact being followed, NULL out of contact */
    afm_cont_contact head;  /* the part of a contact that the orbit starts in */
    afm_cont_contact spill; /* contacts past AFM_CONT_MAX_CONTACTS */
    bool head_open, head_done;
    double contact_tau; /* total phase time in contact */
} mctx;

static void follow(afm_cont_contact *c, double x, double F) {
    if (x < c->min_deflection_m) c->min_deflection_m = x;
    if (F > c->max_force_n) c->max_force_n = F;
}

static void on_root(void *ctx, double tau, const double *y, const int *info) {
    mctx *c = ctx;
    afm_cont_metrics *m = c->m;
    const afm_cont_inst *I = &c->f->at;
    double dy[AFM_CONT_MAX_N], x, v, sx, sv;
    double F = flow_vf(I, tau, y, dy, NULL, NULL, &x, &v);
    F -= flow_squeeze(I, x, v, &sx, &sv); /* the tip-sample force */
    if (x < m->min_deflection_m) m->min_deflection_m = x;
    if (x > m->max_deflection_m) m->max_deflection_m = x;
    if (F > m->max_force_n) m->max_force_n = F;
    if (F < m->min_force_n) m->min_force_n = F;
    if (c->ci < 0) return;
    int dir = info ? info[c->ci] : 0;
    if (!info) { /* the start */
        c->in = x < c->xc;
        if (c->in) {
            c->head_open = true;
            c->cur = &c->head;
            c->tau_in = 0.0;
            c->head = (afm_cont_contact){.min_deflection_m = x, .max_force_n = F};
        }
        return;
    }
    if (dir < 0 && !c->in) { /* the gap closes to a0: a contact starts */
        c->in = true;
        c->tau_in = tau;
        if (m->n_contacts < AFM_CONT_MAX_CONTACTS) {
            c->cur = &m->contacts[m->n_contacts++];
        } else {
            m->contacts_truncated = true;
            c->cur = &c->spill;
        }
        *c->cur = (afm_cont_contact){.t_in_s = tau / I->fe_hz,
                                     .pre_contact_velocity_m_s = v,
                                     .min_deflection_m = x,
                                     .max_force_n = F};
        return;
    }
    if (dir > 0 && c->in) { /* the contact ends */
        follow(c->cur, x, F);
        c->cur->duration_s = (tau - c->tau_in) / I->fe_hz;
        c->contact_tau += tau - c->tau_in;
        if (c->cur == &c->head) c->head_done = true;
        c->in = false;
        c->cur = NULL;
        return;
    }
    if (c->in && c->cur) follow(c->cur, x, F);
}

int afm_cont_metrics_of(afm_cont_flow *f, const double *y0, int p, afm_cont_metrics *out, char *err,
                        size_t errlen) {
    memset(out, 0, sizeof *out);
    if (!f->have_model || p < 1 || p > AFM_CONT_MAX_P) {
        snprintf(err, errlen, "metrics: no model or bad periods");
        return -1;
    }
    flow_engine *e = afm_cont_flow_engine(f, 0, true);
    if (!e) {
        snprintf(err, errlen, "%s", f->msg);
        return -1;
    }
    out->p = p;
    out->min_deflection_m = out->min_force_n = HUGE_VAL;
    out->max_deflection_m = out->max_force_n = -HUGE_VAL;
    double xc = afm_cont_inst_contact_x(&f->at);
    mctx c = {.f = f, .m = out, .ci = isfinite(xc) ? 0 : -1, .xc = xc};
    N_VConst(0.0, e->yQ);
    double y[AFM_CONT_MAX_N];
    memcpy(y, y0, sizeof(double) * (size_t)f->N);
    if (afm_cont_flow_integrate(f, e, y, p, NULL, on_root, &c, err, errlen) != 0) return -1;
    static const int none[FLOW_MAX_KINKS + FLOW_METRIC_ROOTS];
    on_root(&c, (double)p, y, none); /* the end point (= the start on the orbit) */
    const double fe = f->at.fe_hz;
    if (c.in) { /* the orbit ends in the contact it started in */
        c.contact_tau += (double)p - c.tau_in;
        if (c.cur && c.cur != &c.head) {
            c.cur->duration_s = ((double)p - c.tau_in) / fe + (c.head_done ? c.head.duration_s : 0);
            if (c.head_open) follow(c.cur, c.head.min_deflection_m, c.head.max_force_n);
        }
    }
    const double *q = N_VGetArrayPointer(e->yQ);
    double X = 2.0 * q[1] / p, Y = 2.0 * q[2] / p; /* 2 <x sin>, 2 <x cos> */
    afm_lockin_polar_of(X, Y, &out->amplitude_m, &out->phase_lag_deg);
    out->mean_deflection_m = q[0] / p;
    out->dissipated_energy_j = -q[3] / p;
    out->virial_j = q[4] * fe / p;
    out->squeeze_dissipated_energy_j = -q[5] / p;
    out->contact_time_s = c.contact_tau / fe / p;
    if (isfinite(xc) && out->min_deflection_m < xc)
        out->indentation_m = f->at.f.cos_alpha * (xc - out->min_deflection_m);
    return 0;
}
