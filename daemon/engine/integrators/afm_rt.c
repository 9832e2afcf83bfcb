/* SPDX-License-Identifier: MIT */
/* afm_rt.c -- the real-time fixed-step integrator backend (afm_rt_backend): its life cycle,
 * the choice between its two schemes, and the dispatch to their sample loops.
 *
 * Two schemes share the modal state, the phasors, the force law and the tables (cfg
 * rt_scheme; afm_sim_set_scheme hands over at any sample): accurate (the tip force cubic
 * Hermite in time: afm_rt_acc.h) and fast (linear in time: afm_rt_fast.h, described below).
 * The backend by job: afm_rt_impl.h (state, vectors, tones, sync and publish),
 * afm_rt_force.h (forces and the implicit solve), afm_rt_noise.h (thermal increments and
 * their bridge), afm_rt_cross.h (crossing location), afm_rt_evrec.h (the accurate scheme's
 * per-step record for afm_sim_set_events), the two schemes, and the coefficients
 * (afm_rt_coef.c). Each table set (rt_tables) is built for both at init.
 *
 * The fast scheme (docs/numerics.md has the reasons and the measurements):
 *  - Every mode's linear part and the sinusoidal base drive are integrated exactly
 *    (afm_rt_coef.h): the state is the homogeneous part qh = q - sum_j Im(c_j e^{i theta_j})
 *    (c_j the steady-state response to tone j), which the drive does not enter; the phasors
 *    e^{i theta_j} are rotated by a precomputed unit complex per step and resynchronised
 *    from afm_drive every RT_RESYNC steps and on every change. A change reloads qh from the
 *    full q, so tone changes are phase-continuous and q never jumps.
 *  - Thermal noise (afm_sim_set_thermal): each piece adds the exact Gaussian increment of
 *    the Langevin force to (qh, qh') (afm_rt_coef_thermal), drawn before the force solve so
 *    that the implicit force sees it. A redone piece is drawn given the increment already
 *    drawn for its interval (Brownian bridge: rt_noise, rt_bridge_draw), so that redoing a
 *    sample does not depend on the noise it discards.
 *  - The tip force enters through one channel. It is taken as linear over each step
 *    (exponential trapezoidal rule) and solved implicitly: the end force F1 satisfies
 *    F1 = f(x* + gx F1, v* + gv F1). Out of contact that is one linearly implicit step (one
 *    force evaluation at x* + gx F0 and one chord correction with the slope of the step
 *    before); a convergence estimate that is checked off the critical path sends the rare
 *    step that needs more to a safeguarded chord/Newton iteration of at most RT_NEWTON_MAX
 *    evaluations, which in contact takes 2-4.
 *  - Latency: x*, v* of the next full step are affine in this step's F1 (x*_next = A + hx
 *    F1, with A from the modal update before F1 is known), so the chain from one force to
 *    the next is one multiply-add, the force and the chord update. The modal update runs
 *    beside it.
 *  - Out of contact: one step per output sample. When the gap is below a0 at the start or
 *    the end of the sample, or on the cubic Hermite path between, the sample is redone in
 *    m = cfg.rt_substeps_contact substeps, and a substep in which the contact starts or
 *    ends is split at the crossing, located on its cubic Hermite path and rounded to a
 *    grid of RT_GRID cells per substep (every step length used is precomputed). A bound on
 *    the Hermite path (it stays above min(x0, x1) - 4/27 dt (|v0| + |v1|)) skips the
 *    crossing search on samples well clear of the sample.
 *  - Forces: the formulas of afm_force_inline.h, inlined. Starr's squeeze film (a pow per
 *    evaluation) is replaced near the rest gap h0 = Z + kappa l cos(alpha) by a quartic
 *    interpolant of c(h) on h0 (1 +- AFM_RT_STARR_WINDOW), rebuilt whenever Z changes; outside
 *    it the exact formula is used (afm_rt_coef.h).
 *  - Output: afm_sim_run calls rt_run (the backend's batch hook), one loop over the block
 *    of samples writing x, v, F, theta and the base displacement from the step; the full
 *    q is rebuilt for struct afm_sim once per call (rt_publish).
 * Cost per sample is bounded: at most 1 + 3m implicit pieces (a trial full step, then per
 * substep a trial and two split pieces), each of at most RT_NEWTON_MAX force evaluations.
 * No allocation after init. */
#include "config/afm_clones.h"

/* A portable x86-64 build compiles this file twice (Makefile, AFM_RT_COPY): for the
 * baseline (afm_rt_backend_base) and for x86-64-v3 (afm_rt_backend_v3, the same code as an
 * x86-64-v3 build's, so the same bits), and afm_sim picks the copy the CPU runs. Inside a
 * copy nothing is cloned. */
#if defined(AFM_RT_COPY)
#undef AFM_CLONES
#undef AFM_CLONES_NOINLINE
#define AFM_CLONES
#define AFM_CLONES_NOINLINE __attribute__((noinline))
#if AFM_RT_COPY == 2
#define AFM_RT_BACKEND afm_rt_backend_v3
#else
#define AFM_RT_BACKEND afm_rt_backend_base
#endif
#else
#define AFM_RT_BACKEND afm_rt_backend
#endif

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* the backend by job (each file says what it holds; included once, here) */
#include "integrators/afm_rt_impl.h"
#include "integrators/afm_rt_force.h"
#include "integrators/afm_rt_noise.h"
#include "integrators/afm_rt_cross.h"
#include "integrators/afm_rt_fast.h"
#include "integrators/afm_rt_acc.h"

/* ---- backend: life cycle, scheme selection, dispatch ---- */

/* The accurate scheme with each step's record into s->ev_ring (afm_sim_set_events; without
 * noise): its own copies, so that the loop without a ring is the scheme's code alone. */
static AFM_CLONES_NOINLINE int rt_run_acc_ev(afm_sim *s, rt_state *r, int n, afm_sample *out) {
    if (r->ntones == 1 && r->np == 4) return rt_run_acc_t(s, r, n, out, 4, 1, false, true);
    if (r->ntones == 1 && r->np == 8) return rt_run_acc_t(s, r, n, out, 8, 1, false, true);
    return rt_run_acc_t(s, r, n, out, r->np, rt_tones_kind(r), false, true);
}

AFM_CLONES static int rt_run(afm_sim *s, int n, afm_sample *out) {
    rt_state *r = s->be_state;
    if (r->acc && !r->noise && s->ev_ring) return rt_run_acc_ev(s, r, n, out);
    r->ev_a_ok = false; /* the state moves on without the step record (rt_ev_start) */
    if (r->acc) {
        if (r->noise) return rt_run_acc_t(s, r, n, out, r->np, rt_tones_kind(r), true, false);
        if (r->ntones == 1 && r->np == 4) return rt_run_acc_t(s, r, n, out, 4, 1, false, false);
        if (r->ntones == 1 && r->np == 8) return rt_run_acc_t(s, r, n, out, 8, 1, false, false);
        if (r->ntones > 1 && r->np == 4)
            return rt_run_acc_t(s, r, n, out, 4, RT_TONES_V4, false, false);
        if (r->ntones > 1 && r->np == 8)
            return rt_run_acc_t(s, r, n, out, 8, RT_TONES_V4, false, false);
        return rt_run_acc_t(s, r, n, out, r->np, rt_tones_kind(r), false, false);
    }
    if (r->noise) return rt_run_t(s, r, n, out, r->np, rt_tones_kind(r), true);
    if (r->ntones == 1 && r->np == 4) return rt_run_t(s, r, n, out, 4, 1, false);
    if (r->ntones == 1 && r->np == 8) return rt_run_t(s, r, n, out, 8, 1, false);
    if (r->ntones > 1 && r->np == 4) return rt_run_t(s, r, n, out, 4, RT_TONES_V4, false);
    if (r->ntones > 1 && r->np == 8) return rt_run_t(s, r, n, out, 8, RT_TONES_V4, false);
    return rt_run_t(s, r, n, out, r->np, rt_tones_kind(r), false);
}

/* Make tab[acc] the tables in force (the fields of r that alias them, and the first
 * guess of a full step, which depends on them). */
static void rt_tables_use(rt_state *r, bool acc) {
    const rt_tables *t = &r->tab[acc];
    r->acc = acc;
    r->m = t->m;
    r->ncell = t->ncell;
    r->prop = t->prop;
    r->block = t->block;
    r->lth = t->lth;
    r->bridge = t->bridge;
    const afm_rt_prop *PF = &r->prop[r->ncell - 1];
    r->guess_x_per_n = PF->gx + PF->hx;
    r->guess_v_per_n = PF->gv + PF->hv;
    r->guess_gap_per_n = r->guess_x_per_n * r->cos_alpha;
}

/* t's drive rows for the tones in force (r->wd, cx: rt_changed), zeroing only the rows of
 * tones it held past them. */
static void rt_tables_drive(rt_tables *t, const rt_state *r) {
    afm_rt_coef_drive_cells(t->prop, t->ncell, r->ntones, t->drive_tones, r->wd, r->cx_re,
                            r->cx_im);
    t->drive_tones = r->ntones;
}

/* Recompute the drive tables and reload the state from s->q, s->qd at s->t_s. */
static void rt_changed(afm_sim *s) {
    rt_state *r = s->be_state;
    r->ev_a_ok = false;
    const afm_modal *m = &s->m;
    double *cx_re = r->cx_re, *cx_im = r->cx_im;
    r->ntones = s->drive.n;
    for (int j = 0; j < AFM_MAX_TONES; j++) { /* zero past ntones (RT_TONES_V4) */
        r->wd[j] = cx_re[j] = cx_im[j] = r->th_re[j] = r->th_im[j] = r->amp_m[j] = 0.0;
    }
    for (int j = 0; j < r->ntones; j++) {
        r->amp_m[j] = s->drive.amp_m[j];
        r->wd[j] = s->drive.omega_rad_s[j];
        cx_re[j] = cx_im[j] = 0.0;
        r->th_re[j] = m->rot_base * s->drive.amp_m[j];
        r->th_im[j] = 0.0;
        for (int i = 0; i < m->n; i++) {
            /* q_p = Im(A H e^{i theta}) for the base tone A sin(theta) */
            double hr, hi;
            afm_model_mode_response(m, i, r->wd[j], &hr, &hi);
            r->cq_re[j][i] = s->drive.amp_m[j] * hr;
            r->cq_im[j][i] = s->drive.amp_m[j] * hi;
            cx_re[j] += m->tip[i] * r->cq_re[j][i];
            cx_im[j] += m->tip[i] * r->cq_im[j][i];
            r->th_re[j] += m->rot[i] * r->cq_re[j][i];
            r->th_im[j] += m->rot[i] * r->cq_im[j][i];
        }
    }
    /* the tables in force now; the other set when a hand-over needs it (rt_set_scheme):
     * a drive change then costs one set's sincos, not both (bench-states' frequency steps) */
    rt_tables_drive(&r->tab[r->acc], r);
    r->drive_stale[r->acc] = false;
    r->drive_stale[!r->acc] = true;
    for (int j = 0; j < AFM_MAX_TONES; j++) { /* x_p'' = -wd^2 x_p */
        r->ax_re[j] = -r->wd[j] * r->wd[j] * cx_re[j];
        r->ax_im[j] = -r->wd[j] * r->wd[j] * cx_im[j];
    }
    r->xc = afm_force_contact_x(&s->f, s->z_m);
    r->cos_alpha = s->f.cos_alpha;
    r->z_m = s->z_m;
    rt_tables_use(r, r->acc);
    afm_rt_starr_build(&r->starr, &s->f, s->z_m);
    rt_snap *st = &r->buf[r->cur];
    rt_sync_phasors(s, r, st);
    st->tip.x_m = st->tip.v_m_s = 0.0;
    for (int i = 0; i < r->n; i++) {
        double q = s->q[i], v = s->qd[i];
        for (int j = 0; j < r->ntones; j++) {
            double cr = r->cq_re[j][i], ci = r->cq_im[j][i];
            q -= cr * st->z_im[j] + ci * st->z_re[j];
            v -= r->wd[j] * (cr * st->z_re[j] - ci * st->z_im[j]);
        }
        st->q[i] = q;
        st->v[i] = v;
        st->tip.x_m += m->tip[i] * s->q[i];
        st->tip.v_m_s += m->tip[i] * s->qd[i];
    }
    st->tip.f_n = rt_force(s, r, st->tip.x_m, st->tip.v_m_s, &st->dfdx_n_m, &st->dfdv_n_s_m);
    st->slope_cells = 0;
    st->df_per_cell_n = 0.0;
    st->fdot_n_s = rt_fdot(r, st, r->np, rt_tones_kind(r));
    rt_predict(r, st);
    s->be_fills_tip = true;
    rt_publish(s, r, st);
}

/* afm_sim_set_thermal: the Cholesky factors of every step length's increment (both
 * schemes' tables), and the generator seeded. */
static int rt_thermal(afm_sim *s, const afm_cfg_thermal *t, char *err, size_t errlen) {
    rt_state *r = s->be_state;
    r->ev_a_ok = false;
    if (!t->enabled) {
        r->noise = false;
        return 0;
    }
    const size_t np = (size_t)r->np;
    if (!r->rng) {
        afm_rng *g = calloc(1, sizeof *g);
        rt_noise *z = calloc(1, sizeof *z);
        if (!g || !z) {
            free(g);
            free(z);
            snprintf(err, errlen, "rt integrator: out of memory");
            return -1;
        }
        r->rng = g;
        r->nz = z;
    }
    for (int a = 0; a < 2; a++) {
        rt_tables *tb = &r->tab[a];
        const size_t n_bridge = (size_t)(RT_GRID - 1 + tb->m - 1);
        if (!tb->lth) {
            tb->lth = calloc(3 * np * (size_t)tb->ncell, sizeof *tb->lth);
            tb->bridge = calloc(4 * np * n_bridge, sizeof *tb->bridge);
            if (!tb->lth || !tb->bridge) {
                snprintf(err, errlen, "rt integrator: out of memory");
                return -1; /* what was allocated is freed by rt_destroy */
            }
        }
    }
    const bool acc = r->acc;
    const double kt = RT_KB_J_K * t->temperature_k;
    for (int a = 0; a < 2; a++) {
        rt_tables_use(r, a);
        const size_t n_bridge = (size_t)(RT_GRID - 1 + r->m - 1);
        for (int k = 0; k < r->ncell; k++) {
            double *l = r->lth + 3 * np * (size_t)k;
            afm_rt_coef_thermal(&r->prop[k], r->n, r->np, s->m.omega_rad_s, s->m.xi, kt, l, l + np,
                                l + 2 * np);
        }
        /* the bridges: (kc, RT_GRID) for a crossing, (RT_GRID, j RT_GRID) for a substep */
        for (size_t b = 0; b < n_bridge; b++) {
            int k1 = b < RT_GRID - 1 ? (int)b + 1 : RT_GRID;
            int len = b < RT_GRID - 1 ? RT_GRID : (int)(b - (RT_GRID - 1) + 2) * RT_GRID;
            const double *l = r->lth;
            afm_rt_coef_bridge(r->n, r->np, r->prop[k1 - 1].tau_s, l + 3 * np * (size_t)(k1 - 1),
                               l + 3 * np * (size_t)(len - 1), r->prop[len - k1 - 1].c,
                               (double *)rt_bridge_gain(r, k1, len));
        }
    }
    rt_tables_use(r, acc);
    memset(r->nz, 0, sizeof *r->nz);
    afm_rng_seed(r->rng, (uint64_t)t->seed);
    r->noise = true;
    return 0;
}

/* afm_sim_set_scheme: hand the state over to the other scheme at this sample. Both share
 * the modal state, the phasors and the force; what each keeps of its own (the fast one's
 * predictor, the accurate one's dF/dt) is recomputed here. No allocation. */
static void rt_set_scheme(afm_sim *s, bool accurate) {
    rt_state *r = s->be_state;
    if (r->acc == accurate) return;
    r->ev_a_ok = false;
    if (r->drive_stale[accurate]) { /* bounded: one table set's drive rows */
        rt_tables_drive(&r->tab[accurate], r);
        r->drive_stale[accurate] = false;
    }
    rt_tables_use(r, accurate);
    rt_snap *st = &r->buf[r->cur];
    st->slope_cells = 0;
    st->fdot_n_s = rt_fdot(r, st, r->np, rt_tones_kind(r));
    rt_predict(r, st);
}

/* The scheme in force: "accurate" or "fast". */
static const char *rt_scheme_name(const afm_sim *s) {
    const rt_state *r = s->be_state;
    return r && r->acc ? "accurate" : "fast";
}

static void rt_destroy(afm_sim *s) {
    rt_state *r = s->be_state;
    if (!r) return;
    for (int a = 0; a < 2; a++) {
        free(r->tab[a].block);
        free(r->tab[a].prop);
        free(r->tab[a].lth);
        free(r->tab[a].bridge);
    }
    free(r->rng);
    free(r->nz);
    free(r);
    s->be_state = NULL;
}

static int rt_init(afm_sim *s, char *err, size_t errlen) {
    const afm_modal *m = &s->m;
    const bool acc = s->cfg.rt_scheme != AFM_RT_SCHEME_FAST;
    /* substeps in contact: the config's for both schemes, else each scheme's default */
    int sub = s->cfg.rt_substeps_contact;
    if (sub < 0 || sub > RT_MAX_SUBSTEPS) {
        snprintf(err, errlen, "rt integrator: rt_substeps_contact %d not in 1..%d", sub,
                 RT_MAX_SUBSTEPS);
        return -1;
    }
    if (!(s->dt_s > 0) || !isfinite(s->dt_s)) {
        snprintf(err, errlen, "rt integrator: bad output step %g s", s->dt_s);
        return -1;
    }
    for (int i = 0; i < m->n; i++) {
        if (!(m->omega_rad_s[i] > 0) || !isfinite(m->omega_rad_s[i]) || !(m->xi[i] >= 0) ||
            !isfinite(m->xi[i]) || !isfinite(m->tip[i]) || !isfinite(m->base_k[i]) ||
            !isfinite(m->base_m[i])) {
            snprintf(err, errlen, "rt integrator: mode %d has a bad frequency, damping or coupling",
                     i + 1);
            return -1;
        }
    }
    /* rt_state holds 32-byte aligned tables (the tip-channel form's), so the compiler may
     * store into any of it with aligned vector moves: calloc's 16 bytes are not enough */
    const size_t al = _Alignof(rt_state), sz = (sizeof(rt_state) + al - 1) / al * al;
    rt_state *r = aligned_alloc(al, sz);
    if (!r) {
        snprintf(err, errlen, "rt integrator: out of memory");
        return -1;
    }
    memset(r, 0, sizeof *r);
    r->n = m->n;
    r->np = (m->n + 3) & ~3;
    for (int i = 0; i < r->n; i++) {
        r->tip[i] = m->tip[i];
        r->rot[i] = m->rot[i];
        r->aq[i] = -m->tip[i] * m->omega_rad_s[i] * m->omega_rad_s[i];
        r->av[i] = -2.0 * m->tip[i] * m->xi[i] * m->omega_rad_s[i];
        r->tip2 += m->tip[i] * m->tip[i];
    }
    for (int k = 1; k <= RT_MAX_SUBSTEPS * RT_GRID; k++)
        r->inv_cells[k] = 1.0 / k;
    const size_t per = (size_t)AFM_RT_COEF_ROWS * (size_t)r->np;
    _Static_assert(AFM_MAX_MODES % 4 == 0, "rt_piece works in blocks of 4 modes");
    for (int a = 0; a < 2; a++) {
        rt_tables *t = &r->tab[a];
        t->m = sub > 0 ? sub : a ? RT_ACC_DEFAULT_SUBSTEPS : RT_DEFAULT_SUBSTEPS;
        t->ncell = t->m * RT_GRID;
        t->prop = calloc((size_t)t->ncell, sizeof *t->prop);
        t->block = calloc((size_t)t->ncell * per, sizeof(double));
        if (!t->prop || !t->block) {
            s->be_state = r;
            rt_destroy(s);
            snprintf(err, errlen, "rt integrator: out of memory");
            return -1;
        }
        for (int k = 0; k < t->ncell; k++) {
            afm_rt_prop *P = &t->prop[k];
            P->c = t->block + (size_t)k * per;
            afm_rt_coef_modes(P, r->n, r->np, m->omega_rad_s, m->xi, m->tip,
                              s->dt_s * (double)(k + 1) / (double)t->ncell);
            if (a) {
                afm_rt_coef_hermite(P, r->n, r->np, m->omega_rad_s, m->xi, m->tip);
                /* rt_piece_acc_t's Hermite piece: the tip acceleration per unit F1 through its
                 * K1 rows (with sum tip^2) and per unit D1 through its Gd1 rows */
                const int np = r->np;
                const double *k1 = P->c + AFM_RT_ROW_K1 * np;
                const double *d1 = P->c + (AFM_RT_ROW_GC + 4) * np;
                P->acc_k1 = r->tip2;
                P->acc_gd1 = 0.0;
                for (int i = 0; i < np; i++) {
                    P->acc_k1 += r->aq[i] * k1[i] + r->av[i] * k1[np + i];
                    P->acc_gd1 += r->aq[i] * d1[i] + r->av[i] * d1[np + i];
                }
            }
        }
        for (int k = 0; k < t->ncell; k++)
            afm_rt_coef_chain(&t->prop[k], &t->prop[t->ncell - 1], r->np);
    }
    { /* rt_free_acc_t's chain: the full step's tip rows and acceleration on its K1, Gd1 rows */
        const afm_rt_prop *PF = &r->tab[1].prop[r->tab[1].ncell - 1];
        const int np = r->np;
        const double *c = PF->c, *k1 = c + AFM_RT_ROW_K1 * np, *d1 = c + (AFM_RT_ROW_GC + 4) * np;
        r->fa_xf = PF->hx0;
        r->fa_xd = PF->hd0x;
        r->fa_vf = PF->hv0;
        r->fa_vd = PF->hd0v;
        r->fa_af = r->tip2;
        r->fa_ad = 0.0;
        for (int i = 0; i < np; i++) {
            r->fa_xf += c[8 * np + i] * k1[i] + c[9 * np + i] * k1[np + i];
            r->fa_xd += c[8 * np + i] * d1[i] + c[9 * np + i] * d1[np + i];
            r->fa_vf += c[10 * np + i] * k1[i] + c[11 * np + i] * k1[np + i];
            r->fa_vd += c[10 * np + i] * d1[i] + c[11 * np + i] * d1[np + i];
            r->fa_af += r->aq[i] * k1[i] + r->av[i] * k1[np + i];
            r->fa_ad += r->aq[i] * d1[i] + r->av[i] * d1[np + i];
        }
    }
    if (RT_ACC_TC) rt_tc_build(r); /* the tip-channel form's tables (off: never read) */
    r->cos_alpha = s->f.cos_alpha;
    rt_tables_use(r, acc);
    r->kinked = s->f.vdw_contact || s->f.capillary || s->f.electrostatic;
    r->clear_k = 4.0 / 27.0 * s->dt_s;
    r->sure_k = RT_ACC_SURE * (r->clear_k + RT_ACC_NEAR_TRAVELS * s->dt_s);
    /* F tolerance on the estimated next Newton correction: 1e-3 of the force that bends the
     * cantilever by 1 nm (1 pm of deflection). Measured (tests/test_rt_accuracy.c): error_rel
     * against CVODE is the same as with 1e-5 on all four models, while contact pieces take
     * 1.33 force evaluations on average instead of 1.95 (nchv.conf, docs/numerics.md). */
    double k_st = m->static_stiffness_n_m > 0 ? m->static_stiffness_n_m : 1.0;
    r->ftol = 1e-3 * k_st * 1e-9;
    s->be_state = r;
    rt_changed(s);
    return 0;
}

/* Only Z changed (afm_sim_set_separation; a ramp calls it every 64 samples): the contact
 * line, the force and the next step's guess at the current state, and the Starr interpolant
 * only when the rest gap left AFM_RT_STARR_KEEP of its window. The drive tables, the
 * phasors and the homogeneous state are untouched (rt_changed recomputes all of them). */
static void rt_changed_z(afm_sim *s) {
    rt_state *r = s->be_state;
    r->ev_a_ok = false;
    r->xc = afm_force_contact_x(&s->f, s->z_m);
    r->z_m = s->z_m;
    if (s->f.squeeze == AFM_SQUEEZE_STARR &&
        !(r->starr.on && fabs(afm_force_starr_h(&s->f, s->z_m, 0.0) - r->starr.h0) <=
                             AFM_RT_STARR_KEEP * r->starr.hw))
        afm_rt_starr_build(&r->starr, &s->f, s->z_m);
    rt_snap *st = &r->buf[r->cur];
    st->tip.f_n = rt_force(s, r, st->tip.x_m, st->tip.v_m_s, &st->dfdx_n_m, &st->dfdv_n_s_m);
    st->slope_cells = 0;
    st->df_per_cell_n = 0.0;
    st->fdot_n_s = rt_fdot(r, st, r->np, rt_tones_kind(r));
    rt_predict(r, st);
    s->f_last_n = st->tip.f_n;
}

const afm_sim_backend AFM_RT_BACKEND = {
    .name = "rt",
    .scheme = rt_scheme_name,
    .set_scheme = rt_set_scheme,
    .init = rt_init,
    .run = rt_run,
    .changed = rt_changed,
    .changed_z = rt_changed_z,
    .thermal = rt_thermal,
    .destroy = rt_destroy,
};
