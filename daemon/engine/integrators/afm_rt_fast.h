/* SPDX-License-Identifier: MIT */
/* afm_rt_fast.h -- the fast scheme: the tip force linear in time (exponential trapezoidal rule),
 * the free step with its latency-hiding predictor, contact samples in m substeps split at the
 * crossings, and its sample loop (rt_run_t).
 * Private to the rt backend: included once, by afm_rt.c (which is compiled once per CPU copy,
 * AFM_RT_COPY), so its static functions stay in that one translation unit. */
#ifndef AFM_RT_FAST_H
#define AFM_RT_FAST_H

#include "integrators/afm_rt_cross.h"
#include "integrators/afm_rt_force.h"
#include "integrators/afm_rt_noise.h"

/* x*, v* of a full step from st (the tip at the step's end without its F1 response), and
 * x, v, d at its first guess. */
static void rt_predict(const rt_state *r, rt_snap *st) {
    const afm_rt_prop *P = &r->prop[r->ncell - 1];
    const int np = r->np;
    const double *c = P->c;
    rt_v4 xs4 = rt_splat(0.0), vs4 = rt_splat(0.0);
    for (int i = 0; i < np; i += 4) {
        rt_v4 q = RT_V4(st->q + i), v = RT_V4(st->v + i);
        xs4 = rt_fma4(RT_V4(c + 8 * np + i), q, rt_fma4(RT_V4(c + 9 * np + i), v, xs4));
        vs4 = rt_fma4(RT_V4(c + 10 * np + i), q, rt_fma4(RT_V4(c + 11 * np + i), v, vs4));
    }
    double xs = P->gx0 * st->tip.f_n + rt_hsum(xs4), vs = P->gv0 * st->tip.f_n + rt_hsum(vs4);
    for (int j = 0; j < r->ntones; j++) {
        xs += P->dx_re[j] * st->z_im[j] + P->dx_im[j] * st->z_re[j];
        vs += P->dv_re[j] * st->z_im[j] + P->dv_im[j] * st->z_re[j];
    }
    st->tip.x_free_m = xs;
    st->tip.v_free_m_s = vs;
    st->tip.x_guess_m = fma(P->gx, st->tip.f_n, xs);
    st->tip.v_guess_m_s = fma(P->gv, st->tip.f_n, vs);
    st->tip.gap_guess_m = rt_gap(r, st->tip.x_guess_m);
    st->acc_free = false;
}

/* The reciprocal slope of a piece with coefficients P that starts where the force's partials
 * are fx, fv: 1 / max(1 - fx gx - fv gv, 1/4). */
static inline double rt_slope(const afm_rt_prop *P, double fx, double fv) {
    double jj = 1.0 - fx * P->gx - fv * P->gv; /* fmax(jj, 0.25), inlined */
    return 1.0 / (jj > 0.25 ? jj : 0.25);
}

/* rt_tip of st for a following full step. */
static inline rt_tip rt_tip_of(const rt_state *r, const rt_snap *st) {
    double rj = st->slope_cells == r->ncell
                    ? st->tip.inv_slope
                    : rt_slope(&r->prop[r->ncell - 1], st->dfdx_n_m, st->dfdv_n_s_m);
    rt_tip t = st->tip;
    t.inv_slope = rj;
    return t;
}

/* Which piece rt_piece_t advances. Every call passes constants, so that each kind becomes
 * its own straight-line code (rt_piece_t is always inlined). */
typedef struct {
    int np;         /* mode stride: n rounded up to 4 (coefficients are zero past n) */
    int ntones;     /* drive tones */
    bool free_step; /* the free step (k = ncell, predict): in's tip comes from *ti and o's
                     * goes to *to as well; one linearly implicit solve (rt_solve_fast) */
    bool thermal;   /* add the thermal increment (afm_sim_set_thermal) */
    bool predict;   /* leave the predictor of a following full step in o (the free step
                     * does; contact pieces leave it to one rt_predict after the sample) */
    /* A contact substep's first try (k = RT_GRID): return its crossing cell kc
     * (rt_crossing_xv, -1 when none) once the end force is known; when 0 < kc < RT_GRID the
     * substep is split there (rt_contact_t) and the modal update is skipped. */
    bool test_split;
} rt_piece_kind;

/* Advance in by k cells (tau = k dt / ncell) into o; o may be in. A full step
 * (k = ncell) takes x*, v* from in's predictor; a shorter piece from its own tip-weighted
 * rows. Returns 0, or with kind.test_split its crossing cell (the piece is then left untaken
 * where it is to be split: a result that would be discarded costs no modal update). */
static inline __attribute__((always_inline)) int rt_piece_t(const afm_sim *s, const rt_state *r,
                                                            const rt_snap *in, rt_snap *o, int k,
                                                            const rt_piece_kind kind,
                                                            const rt_tip *ti, rt_tip *to) {
    const int np = kind.np, nt = kind.ntones;
    /* (the free step's k is ncell: PF is P, without reloading r->ncell after the stores) */
    const afm_rt_prop *P = &r->prop[k - 1], *PF = kind.free_step ? P : &r->prop[r->ncell - 1];
    const double *c = P->c, *cf = PF->c;
    const double F0 = kind.free_step ? ti->f_n : in->tip.f_n;
    double xs, vs, rj;
    double nq[AFM_MAX_MODES] __attribute__((aligned(32)));
    double nv[AFM_MAX_MODES] __attribute__((aligned(32)));
    if (kind.free_step) {
        xs = ti->x_free_m;
        vs = ti->v_free_m_s;
    } else if (k == r->ncell) {
        xs = in->tip.x_free_m;
        vs = in->tip.v_free_m_s;
    } else {
        rt_v4 xs4 = rt_splat(0.0), vs4 = rt_splat(0.0);
        for (int i = 0; i < np; i += 4) {
            rt_v4 q = RT_V4(in->q + i), v = RT_V4(in->v + i);
            xs4 = rt_fma4(RT_V4(c + 8 * np + i), q, rt_fma4(RT_V4(c + 9 * np + i), v, xs4));
            vs4 = rt_fma4(RT_V4(c + 10 * np + i), q, rt_fma4(RT_V4(c + 11 * np + i), v, vs4));
        }
        rt_hsum2(xs4, vs4, &xs, &vs);
        xs = fma(P->gx0, F0, xs);
        vs = fma(P->gv0, F0, vs);
        xs += rt_tones_im(P->dx_re, P->dx_im, in->z_re, in->z_im, nt);
        vs += rt_tones_im(P->dv_re, P->dv_im, in->z_re, in->z_im, nt);
    }
    if (kind.thermal) {
        double xq, xv;
        rt_thermal_draw(r, k, nq, nv, &xq, &xv);
        xs += xq;
        vs += xv;
    }
    if (kind.free_step) {
        rj = ti->inv_slope;
    } else {
        rj = in->slope_cells == k ? in->tip.inv_slope : rt_slope(P, in->dfdx_n_m, in->dfdv_n_s_m);
    }
    /* The force first (the critical path); the modal update below does not wait for it
     * until its last multiply-add. */
    /* In contact the force changes fast: the iteration starts from the force extrapolated
     * along the last piece's slope (about one force evaluation fewer per piece). */
    double F1 = kind.free_step ? rt_solve_fast(s, r, xs, vs, P->gx, P->gv, F0, rj, ti->x_guess_m,
                                               ti->v_guess_m_s, ti->gap_guess_m, o)
                               : rt_solve_in(s, r, xs, vs, P->gx, P->gv,
                                             fma(in->df_per_cell_n, (double)k, F0), rj, o);
    const double x1 = fma(P->gx, F1, xs), v1 = fma(P->gv, F1, vs);
    int ret = 0;
    if (kind.test_split) {
        /* rt_crossing_xv's common answer inlined: no crossing (same side, no dip between) */
        const bool in0 = in->tip.x_m < r->xc, in1 = x1 < r->xc;
        ret = -1;
        if (in0 != in1 || (!in0 && in->tip.v_m_s < 0 && v1 > 0)) {
            ret = rt_crossing_xv(r, in->tip.x_m, in->tip.v_m_s, x1, v1, s->dt_s / r->m, true);
            if (ret > 0 && ret < RT_GRID) return ret;
        }
    }
    const double dfc = (F1 - F0) * r->inv_cells[k];
    double zr1[AFM_MAX_TONES], zi1[AFM_MAX_TONES];
    double xn = 0.0, vn = 0.0;
    rt_tones_rotate(in->z_re, in->z_im, P->rot_re, P->rot_im, zr1, zi1, nt);
    if (kind.predict) {
        xn = rt_tones_im(PF->dx_re, PF->dx_im, zr1, zi1, nt);
        vn = rt_tones_im(PF->dv_re, PF->dv_im, zr1, zi1, nt);
    }
    const rt_v4 f0 = rt_splat(F0), f1 = rt_splat(F1);
    rt_v4 xn4 = rt_splat(0.0), vn4 = rt_splat(0.0);
    for (int i = 0; i < np; i += 4) {
        rt_v4 q = RT_V4(in->q + i), v = RT_V4(in->v + i);
        rt_v4 a =
            rt_fma4(RT_V4(c + i), q, rt_fma4(RT_V4(c + np + i), v, RT_V4(c + 4 * np + i) * f0));
        rt_v4 w = rt_fma4(RT_V4(c + 2 * np + i), q,
                          rt_fma4(RT_V4(c + 3 * np + i), v, RT_V4(c + 5 * np + i) * f0));
        if (kind.thermal) {
            a += RT_V4(nq + i);
            w += RT_V4(nv + i);
        }
        /* next full step's x*, v* without this F1 (its F1 part is P->hx F1, P->hv F1) */
        if (kind.predict) {
            xn4 = rt_fma4(RT_V4(cf + 8 * np + i), a, rt_fma4(RT_V4(cf + 9 * np + i), w, xn4));
            vn4 = rt_fma4(RT_V4(cf + 10 * np + i), a, rt_fma4(RT_V4(cf + 11 * np + i), w, vn4));
        }
        RT_V4W(o->q + i) = rt_fma4(RT_V4(c + 6 * np + i), f1, a);
        RT_V4W(o->v + i) = rt_fma4(RT_V4(c + 7 * np + i), f1, w);
    }
    rt_tones_store(o->z_re, o->z_im, zr1, zi1, nt); /* after the loop: in == o is allowed */
    o->slope_cells = k;
    o->df_per_cell_n = dfc;
    if (kind.predict) {
        double xh, vh;
        rt_hsum2(xn4, vn4, &xh, &vh);
        const double xr = xn + xh, vr = vn + vh;
        /* The next guess straight from F1 (one multiply-add each, not two: the force chain
         * from one step to the next is shorter; the same point up to rounding). */
        const rt_tip t = {.x_m = x1,
                          .v_m_s = v1,
                          .f_n = F1,
                          .x_free_m = fma(P->hx, F1, xr),
                          .v_free_m_s = fma(P->hv, F1, vr),
                          .inv_slope = o->tip.inv_slope, /* the solve's */
                          .x_guess_m = fma(r->guess_x_per_n, F1, xr),
                          .v_guess_m_s = fma(r->guess_v_per_n, F1, vr),
                          .gap_guess_m = fma(r->guess_gap_per_n, F1, rt_gap(r, xr))};
        o->tip = t;
        o->acc_free = false;
        if (kind.free_step) *to = t;
    } else {
        o->tip.x_m = x1;
        o->tip.v_m_s = v1;
        o->tip.f_n = F1;
    }
    return ret;
}

/* One sample that touches contact, from a: m substeps of RT_GRID cells, each first tried
 * whole and split where its path crosses the contact line (at a located crossing cell
 * 0 < kc < RT_GRID: kc cells, then the rest), with the pieces' kind as constants (the
 * iterated solve, no predictor: one rt_predict after the sample's last piece). The result
 * is in *a or *b; returns which. redo: the sample's free step was taken (and its thermal
 * increment drawn: the substeps' are drawn given it, rt_noise). */
static inline __attribute__((always_inline)) rt_snap *rt_contact_t(const afm_sim *s,
                                                                   const rt_state *r, rt_snap *a,
                                                                   rt_snap *b, bool redo,
                                                                   const rt_piece_kind kind) {
    rt_noise *z = r->nz;
    rt_piece_kind trial = kind;
    trial.test_split = true;
    if (kind.thermal) rt_noise_sample_begin(r, redo);
    for (int k = 0; k < r->m; k++) {
        if (kind.thermal) rt_noise_substep(r);
        const int kc = rt_piece_t(s, r, a, b, RT_GRID, trial, NULL, NULL);
        if (kc > 0 && kc < RT_GRID) {
            if (kind.thermal) { /* both parts from the substep's increment, drawn above */
                memcpy(z->sq, z->lq, sizeof z->sq);
                memcpy(z->sv, z->lv, sizeof z->sv);
                rt_bridge_draw(r, kc, RT_GRID, z->sq, z->sv);
            }
            for (int part = 0; part < 2; part++) { /* a -> b (kc cells), then b -> b */
                if (part && kind.thermal) {
                    memcpy(z->gq, z->sq, sizeof z->gq);
                    memcpy(z->gv, z->sv, sizeof z->gv);
                    z->given_cells = RT_GRID - kc;
                }
                rt_piece_t(s, r, part ? b : a, b, part ? RT_GRID - kc : kc, kind, NULL, NULL);
            }
        }
        rt_snap *t = a;
        a = b;
        b = t;
    }
    rt_predict(r, a);
    return a;
}

/* rt_contact_t for r's kind of pieces: one dispatch per contact sample. */
static AFM_CLONES_NOINLINE rt_snap *rt_contact(const afm_sim *s, const rt_state *r, rt_snap *a,
                                               rt_snap *b, bool redo) {
    if (r->noise)
        return rt_contact_t(
            s, r, a, b, redo,
            (rt_piece_kind){.np = r->np, .ntones = rt_tones_kind(r), .thermal = true});
    if (r->ntones == 1 && r->np == 4)
        return rt_contact_t(s, r, a, b, redo, (rt_piece_kind){.np = 4, .ntones = 1});
    if (r->ntones == 1 && r->np == 8)
        return rt_contact_t(s, r, a, b, redo, (rt_piece_kind){.np = 8, .ntones = 1});
    if (r->ntones > 1 && r->np == 4)
        return rt_contact_t(s, r, a, b, redo, (rt_piece_kind){.np = 4, .ntones = RT_TONES_V4});
    if (r->ntones > 1 && r->np == 8)
        return rt_contact_t(s, r, a, b, redo, (rt_piece_kind){.np = 8, .ntones = RT_TONES_V4});
    return rt_contact_t(s, r, a, b, redo, (rt_piece_kind){.np = r->np, .ntones = rt_tones_kind(r)});
}

/* n output steps (afm_sim_backend.run), with the common sizes (up to 8 modes, one tone)
 * and the thermal switch as constants so that the full step's loops unroll and the
 * phasors stay in registers. */
static inline __attribute__((always_inline)) int rt_run_t(afm_sim *s, rt_state *r, int n,
                                                          afm_sample *out, const int np,
                                                          const int nt, const bool noise) {
    int rc = AFM_SIM_OK;
    /* The clock, the buffer index and the resync count live in registers over the block; the
     * block is cut into segments that end before the next phasor resync, so the inner loop
     * tests neither. Blow-up: |x| is tested every sample (a non-finite q_i, v or F reaches x
     * within one step: x is a sum over every mode, affine in the last force); x', F once per
     * segment, after its last sample. */
    long step = s->step, since = r->since_sync;
    double stepd = (double)step; /* the step count as a double (exact below 2^53) */
    const double t0 = s->t_start_s, dt = s->dt_s;
    int cur = r->cur;
    const double gx_full = r->prop[r->ncell - 1].gx;
    /* loop invariants as locals: the modal stores (may_alias vectors) would reload them */
    const int ncell = r->ncell;
    const bool kinked = r->kinked;
    rt_tip ta = rt_tip_of(r, &r->buf[cur]), tb; /* the tip at a and at bb, in registers */
    for (int k = 0; k < n && rc == AFM_SIM_OK;) {
        if (__builtin_expect(++since >= RT_RESYNC, 0)) {
            s->step = step;
            s->t_s = t0 + stepd * dt;
            rt_sync_phasors(s, r, &r->buf[cur]);
            since = r->since_sync;
            rt_predict(r, &r->buf[cur]);
            ta = rt_tip_of(r, &r->buf[cur]);
        }
        /* this step and the next m - 1 keep ++since below RT_RESYNC */
        int m = n - k < RT_RESYNC - since ? n - k : (int)(RT_RESYNC - since);
        int j = 0;
        rt_snap *a = &r->buf[cur], *const b0 = &r->buf[0], *const b1 = &r->buf[1];
        const rt_snap *b = a;
        afm_sample *o = out ? out + k : NULL;
        for (; j < m; j++) {
            rt_snap *bb = a == b0 ? b1 : b0;
            /* in contact at the start, or predicted to end there (the end's x with F held at
             * F0: a free step would be redone in substeps anyway) */
            const bool at_once =
                kinked && (ta.x_m < r->xc || fma(gx_full, ta.f_n, ta.x_free_m) < r->xc);
            bool contact = at_once;
            if (!contact) {
                const rt_piece_kind free_step = {
                    .np = np, .ntones = nt, .free_step = true, .thermal = noise, .predict = true};
                rt_piece_t(s, r, a, bb, ncell, free_step, &ta, &tb);
                if (kinked) {
                    double low = (ta.x_m < tb.x_m ? ta.x_m : tb.x_m) -
                                 r->clear_k * (fabs(ta.v_m_s) + fabs(tb.v_m_s));
                    contact = low < r->xc && rt_crossing_cell(r, a, bb, dt, false) >= 0;
                }
            }
            if (contact) {
                bb = rt_contact(s, r, a, bb, noise && !at_once);
                tb = rt_tip_of(r, bb);
            }
            a = bb;
            b = bb;
            ta = tb;
            stepd += 1.0;
            /* A tip excursion of a millimetre is no cantilever any more. */
            if (!(fabs(ta.x_m) < 1e-3)) {
                rc = AFM_SIM_EBLOWUP;
                j++;
                break;
            }
            if (o) {
                rt_v4 th4 = rt_splat(0.0);
                for (int i = 0; i < np; i += 4)
                    th4 = rt_fma4(RT_V4(r->rot + i), RT_V4(b->q + i), th4);
                double th = rt_hsum(th4), u = 0.0;
                th += rt_tones_im(r->th_re, r->th_im, b->z_re, b->z_im, nt);
                if (nt == RT_TONES_V4)
                    u = rt_hsum(RT_V4(r->amp_m) * RT_V4(b->z_im));
                else
                    for (int jt = 0; jt < nt; jt++)
                        u += r->amp_m[jt] * b->z_im[jt];
                o->t_s = t0 + stepd * dt;
                o->x_m = ta.x_m;
                o->v_m_s = ta.v_m_s;
                o->f_n = ta.f_n;
                o->theta_rad = th;
                o->base_m = u;
                o++;
            }
        }
        cur = a == b0 ? 0 : 1;
        if (rc == AFM_SIM_OK && !(fabs(b->tip.v_m_s) < HUGE_VAL && fabs(b->tip.f_n) < HUGE_VAL))
            rc = AFM_SIM_EBLOWUP;
        step += j;
        since += j - 1;
        k += j;
    }
    s->step = step;
    s->t_s = t0 + (double)step * dt;
    r->cur = cur;
    r->since_sync = since;
    rt_publish(s, r, &r->buf[r->cur]);
    return rc;
}

#endif
