/* SPDX-License-Identifier: MIT */
/* afm_cycle.c -- streaming per-period tapping metrics (contract in afm_cycle.h). */
#include "afm_cycle.h"

#include <stdio.h>
#include <string.h>

int afm_cycle_init(afm_cycle *c, double x_contact_m, double cos_alpha, char *err, size_t errlen) {
    if (!c || isnan(x_contact_m) || x_contact_m == HUGE_VAL || !(cos_alpha > 0) ||
        !(cos_alpha <= 1)) {
        if (err && errlen)
            snprintf(err, errlen,
                     "cycle: contact line must be a number or -inf (got %g), cos(alpha) in (0, 1] "
                     "(got %g)",
                     x_contact_m, cos_alpha);
        return -1;
    }
    memset(c, 0, sizeof *c);
    c->x_contact_m = x_contact_m;
    c->cos_alpha = cos_alpha;
    afm_track_init(&c->trk, true);
    return 0;
}

int afm_cycle_set_contact(afm_cycle *c, double x_contact_m) {
    if (isnan(x_contact_m) || x_contact_m == HUGE_VAL) return -1;
    c->x_contact_m = x_contact_m;
    return 0;
}

void afm_cycle_reset(afm_cycle *c) {
    double xc = c->x_contact_m, ca = c->cos_alpha;
    memset(c, 0, sizeof *c);
    c->x_contact_m = xc;
    c->cos_alpha = ca;
    afm_track_init(&c->trk, true);
}

/* Start period accumulation at sample s (the whole period still ahead). */
static void begin(afm_cycle *c, const afm_sample *s, double t_start) {
    memset(&c->cur, 0, sizeof c->cur);
    c->cur.period = c->periods;
    c->cur.t_start_s = t_start;
    c->cur.peak_force_n = s->f_n;
    c->cur.min_deflection_m = s->x_m;
    c->cur.pre_contact_velocity_m_s = NAN;
    c->x_int = 0.0;
    c->active = true;
}

static void finish(afm_cycle *c) {
    afm_cycle_metrics *m = &c->cur;
    m->mean_deflection_m = m->duration_s > 0 ? c->x_int / m->duration_s : m->min_deflection_m;
    m->indentation_m = m->min_deflection_m < c->x_contact_m
                           ? c->cos_alpha * (c->x_contact_m - m->min_deflection_m)
                           : 0.0;
    c->out = *m;
    c->periods++;
}

/* Length of [a, b] inside [lo, hi]. */
static double overlap(double a, double b, double lo, double hi) {
    double l = a > lo ? a : lo, r = b < hi ? b : hi;
    return r > l ? r - l : 0.0;
}

/* The step from c->prev to s in general: clock event ev (frac for a crossing), Hermite
 * minima, contact crossings, the peak's parabola, the split at a boundary. */
AFM_EST_COLD static int step_general(afm_cycle *c, const afm_sample *s, bool had_prev, int ev,
                                     double frac) {
    int done = 0;
    bool cross = ev == AFM_CLOCK_CROSS;
    afm_cycle_metrics *m = &c->cur;

    if (!had_prev) {
        if (ev == AFM_CLOCK_START) begin(c, s, s->t_s);
    } else {
        const afm_sample *p = &c->prev;
        double h = s->t_s - p->t_s, sb = cross ? frac : 1.0; /* part of the step before */
        /* peak force: refine prev if it is a local maximum (it belongs to `cur`) */
        if (c->active && c->n_prev >= 2) {
            double pk = afm_parabola_peak(c->f_prev2, p->f_n, s->f_n);
            if (pk > m->peak_force_n) m->peak_force_n = pk;
        }
        /* minima of the Hermite cubic inside the step, before and after the boundary */
        afm_cubic q = afm_hermite(p, s, h);
        double r[2], xmin_b = HUGE_VAL, xmin_a = HUGE_VAL;
        int nr = afm_cubic_stationary(&q, r);
        for (int k = 0; k < nr; k++) {
            if (!(r[k] > 0.0 && r[k] < 1.0)) continue;
            double x = afm_cubic_at(&q, r[k]);
            if (r[k] < sb) {
                if (x < xmin_b) xmin_b = x;
            } else if (x < xmin_a) {
                xmin_a = x;
            }
        }
        /* contact part of the step [ca, cb] (fractions) and the inward crossing r_in */
        double xc = c->x_contact_m, ca = 0.0, cb = 0.0, r_in = -1.0, v_in = 0.0;
        bool in0 = p->x_m < xc, in1 = s->x_m < xc;
        if (in0 && in1) {
            cb = 1.0;
        } else if (!in0 && in1) {
            afm_hermite_crossing_newton(p, s, h, xc, &r_in, &v_in);
            ca = r_in;
            cb = 1.0;
        } else if (in0 && !in1) {
            double v_out;
            afm_hermite_crossing_newton(p, s, h, xc, &cb, &v_out);
        }
        /* integrals of -f v and x over each part */
        double wb[2] = {0.5, 0.5}, wa[2] = {0.0, 0.0};
        if (cross) afm_split_weights(frac, wb, wa);
        double e0 = -p->f_n * p->v_m_s, e1 = -s->f_n * s->v_m_s;
        if (c->active) {
            m->dissipated_energy_j += h * (wb[0] * e0 + wb[1] * e1);
            c->x_int += h * (wb[0] * p->x_m + wb[1] * s->x_m);
            m->duration_s += h * sb;
            m->contact_time_s += h * overlap(ca, cb, 0.0, sb);
            if (xmin_b < m->min_deflection_m) m->min_deflection_m = xmin_b;
            if (r_in >= 0.0 && r_in < sb) {
                if (m->n_contacts == 0) m->pre_contact_velocity_m_s = v_in;
                m->n_contacts++;
            }
            if (!cross || frac >= 1.0) { /* the sample lies in (or ends) this period */
                if (s->x_m < m->min_deflection_m) m->min_deflection_m = s->x_m;
                if (s->f_n > m->peak_force_n) m->peak_force_n = s->f_n;
            }
            if (cross) {
                finish(c);
                done = 1;
            }
        }
        if (cross) {
            /* a new period starts inside this step: it gets the rest of the step */
            begin(c, s, p->t_s + frac * h);
            m->duration_s = h * (1.0 - frac);
            m->dissipated_energy_j = h * (wa[0] * e0 + wa[1] * e1);
            c->x_int = h * (wa[0] * p->x_m + wa[1] * s->x_m);
            m->contact_time_s = h * overlap(ca, cb, frac, 1.0);
            if (xmin_a < m->min_deflection_m) m->min_deflection_m = xmin_a;
            if (r_in >= frac) {
                m->pre_contact_velocity_m_s = v_in;
                m->n_contacts = 1;
            }
        }
    }
    c->f_prev2 = c->prev.f_n;
    c->prev = *s;
    if (c->n_prev < 2) c->n_prev++;
    return done;
}

/* The sample by the exact clock (checked: the sample itself is valid). */
AFM_EST_COLD static int push_slow(afm_cycle *c, const afm_sample *s, double theta_rad) {
    double frac = 1.0, ph;
    bool rate_changed;
    if (afm_track_check(&c->trk, theta_rad, &ph) != AFM_CLOCK_NONE) return -1;
    bool had_prev = c->trk.started;
    int ev = afm_track_advance(&c->trk, theta_rad, ph, &frac, &rate_changed);
    return step_general(c, s, had_prev, ev, frac);
}

int afm_cycle_push(afm_cycle *c, const afm_sample *s, double theta_rad) {
    if (!s || !isfinite(s->t_s) || !isfinite(s->x_m) || !isfinite(s->v_m_s) || !isfinite(s->f_n) ||
        (c->n_prev > 0 && !(s->t_s > c->prev.t_s)))
        return -1;
    if (!afm_track_fast(&c->trk, theta_rad)) return push_slow(c, s, theta_rad);
    /* No boundary in the step. The common case needs compares and adds only: the sample
     * history is full, the period active, both samples on the same side of the contact
     * line, and the Hermite cubic cannot dip below the running minimum inside the step (it
     * stays above its Bernstein control points x0, x0 + h v0 / 3, x1 - h v1 / 3, x1). */
    const afm_sample *p = &c->prev;
    afm_cycle_metrics *m = &c->cur;
    double h = s->t_s - p->t_s, h3 = h * (1.0 / 3.0);
    double xmin = s->x_m < m->min_deflection_m ? s->x_m : m->min_deflection_m;
    double b1 = p->x_m + h3 * p->v_m_s, b2 = s->x_m - h3 * s->v_m_s;
    bool in0 = p->x_m < c->x_contact_m, in1 = s->x_m < c->x_contact_m;
    if (!c->active || c->n_prev < 2 || in0 != in1 || b1 < xmin || b2 < xmin)
        return step_general(c, s, true, AFM_CLOCK_NONE, 1.0);
    /* the previous sample is a local maximum of f: refine it by the parabola */
    if (p->f_n >= c->f_prev2 && p->f_n >= s->f_n) {
        double pk = afm_parabola_peak(c->f_prev2, p->f_n, s->f_n);
        if (pk > m->peak_force_n) m->peak_force_n = pk;
    }
    double e0 = -p->f_n * p->v_m_s, e1 = -s->f_n * s->v_m_s;
    m->dissipated_energy_j += h * (0.5 * e0 + 0.5 * e1);
    c->x_int += h * (0.5 * p->x_m + 0.5 * s->x_m);
    m->duration_s += h;
    if (in0) m->contact_time_s += h;
    m->min_deflection_m = xmin;
    if (s->f_n > m->peak_force_n) m->peak_force_n = s->f_n;
    c->f_prev2 = p->f_n;
    c->prev = *s;
    return 0;
}

int afm_cycle_push_n(afm_cycle *c, const afm_sample *s, const double *th, int n, int *done,
                     long long *rejects) {
    *done = 0;
    int i = 0;
    while (i < n) {
        /* a run of fast-path steps (afm_cycle_push's conditions), state in locals */
        if (c->active && c->n_prev >= 2) {
            const afm_phase_track *t = &c->trk;
            afm_cycle_metrics *m = &c->cur;
            double nn = t->n, xc = c->x_contact_m, fp2 = c->f_prev2;
            double pk_max = m->peak_force_n, xmin = m->min_deflection_m;
            double en = m->dissipated_energy_j, xi = c->x_int, dur = m->duration_s,
                   ct = m->contact_time_s;
            const afm_sample *p = &c->prev;
            int j = i;
            for (; j < n; j++) {
                const afm_sample *q = &s[j];
                double nj = nn + 1.0;
                if (!(nj <= t->n_end && fabs((th[j] - t->th_ref) - nj * t->dphi) <= t->tol)) break;
                /* all finite: the products with 0 are all +-0 (NaN otherwise) */
                double z = (q->t_s * 0.0 + q->x_m * 0.0) + (q->v_m_s * 0.0 + q->f_n * 0.0);
                if (z != 0.0 || !(q->t_s > p->t_s)) break;
                double h = q->t_s - p->t_s, h3 = h * (1.0 / 3.0);
                double xm = q->x_m < xmin ? q->x_m : xmin;
                double b1 = p->x_m + h3 * p->v_m_s, b2 = q->x_m - h3 * q->v_m_s;
                bool in0 = p->x_m < xc, in1 = q->x_m < xc;
                if (in0 != in1 || b1 < xm || b2 < xm) break;
                if (p->f_n >= fp2 && p->f_n >= q->f_n) {
                    double pk = afm_parabola_peak(fp2, p->f_n, q->f_n);
                    if (pk > pk_max) pk_max = pk;
                }
                double e0 = -p->f_n * p->v_m_s, e1 = -q->f_n * q->v_m_s;
                en += h * (0.5 * e0 + 0.5 * e1);
                xi += h * (0.5 * p->x_m + 0.5 * q->x_m);
                dur += h;
                if (in0) ct += h;
                xmin = xm;
                if (q->f_n > pk_max) pk_max = q->f_n;
                fp2 = p->f_n;
                p = q;
                nn = nj;
            }
            if (j > i) {
                m->peak_force_n = pk_max;
                m->min_deflection_m = xmin;
                m->dissipated_energy_j = en;
                c->x_int = xi;
                m->duration_s = dur;
                m->contact_time_s = ct;
                c->f_prev2 = fp2;
                c->prev = *p;
                c->trk.n = nn;
                c->trk.th_prev = th[j - 1];
                i = j;
                continue;
            }
        }
        int rc = afm_cycle_push(c, &s[i], th[i]);
        i++;
        if (rc < 0) (*rejects)++;
        if (rc == 1) {
            *done = 1;
            break;
        }
    }
    return i;
}
