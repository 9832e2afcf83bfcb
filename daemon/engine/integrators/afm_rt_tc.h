/* SPDX-License-Identifier: MIT */
/* afm_rt_tc.h -- the tip-channel (Toeplitz) form of the accurate scheme's graded sample (issue
 * 29, ninth round; RT_ACC_TC, docs/numerics.md).
 *
 * A graded sample is RT_TC_NODES Hermite pieces of one length tau on a fixed grid (the nodes).
 * Over it the tip is its free response from the state the nodes start from (the origin) plus
 * the response to each node's force F and slope D = tau dF/dt; both are linear, so at node p the
 * tip's x, v and acceleration are table rows on the origin's modal state (Phi(l tau) seen through
 * the tip, fr) plus one short dot product over the earlier nodes' F and D (weights per lag,
 * rt_tc_tab.w, per model). Each node is then that dot product and the scalar solve of
 * rt_piece_acc_t (its end force with D held at the last node's, then D from dF/dt at the end),
 * and the modal state is formed from the node forces (rt_tc_tab.m) only where it is needed: at
 * the sample's end, and before a piece that is redone in substeps (a crossing, or an end in
 * contact close to the line, as rt_graded_acc decides; the substeps' end is then the new
 * origin). The same pieces as rt_graded_acc without its merges out of contact; other rounding.
 * Private to the rt backend: included once, by afm_rt_acc.h (afm_rt.c). */
#ifndef AFM_RT_TC_H
#define AFM_RT_TC_H

#include "integrators/afm_rt_cross.h"
#include "integrators/afm_rt_evrec.h"
#include "integrators/afm_rt_force.h"

/* The tables of r->tc from tab[1] (build time, after its Hermite rows). Off (tc.on false) when
 * its m is no multiple of RT_TC_NODES (the graded samples are not taken then). */
static void rt_tc_build(rt_state *r) {
    rt_tc_tab *T = &r->tc;
    const rt_tables *t = &r->tab[1];
    memset(T, 0, sizeof *T);
    if (t->m % RT_TC_NODES != 0) return;
    const int np = r->np, k = t->ncell / RT_TC_NODES;
    T->k = k;
    const double *c1 = t->prop[k - 1].c;
    const double *src[2][2] = {/* [F, D][end of own piece, start of the next] */
                               {c1 + AFM_RT_ROW_K1 * np, c1 + AFM_RT_ROW_K0 * np},
                               {c1 + (AFM_RT_ROW_GC + 4) * np, c1 + (AFM_RT_ROW_GC + 2) * np}};
    double ph[RT_TC_NODES + 1][4][AFM_MAX_MODES]; /* Phi(l tau) per mode: p11, p12, p21, p22 */
    for (int l = 0; l <= RT_TC_NODES; l++)
        for (int i = 0; i < np; i++)
            for (int e = 0; e < 4; e++)
                ph[l][e][i] =
                    l == 0 ? (e == 0 || e == 3 ? 1.0 : 0.0) : t->prop[l * k - 1].c[e * np + i];
    for (int l = 0; l <= RT_TC_NODES; l++) {
        for (int i = 0; i < np; i++) {
            T->fr[l][0][i] = r->tip[i] * ph[l][0][i];
            T->fr[l][1][i] = r->tip[i] * ph[l][1][i];
            T->fr[l][2][i] = r->tip[i] * ph[l][2][i];
            T->fr[l][3][i] = r->tip[i] * ph[l][3][i];
            T->fr[l][4][i] = r->aq[i] * ph[l][0][i] + r->av[i] * ph[l][2][i];
            T->fr[l][5][i] = r->aq[i] * ph[l][1][i] + r->av[i] * ph[l][3][i];
        }
        for (int o = 0; o < 2; o++)
            for (int fd = 0; fd < 2; fd++) {
                const double *e = src[fd][0], *nx = src[fd][1];
                double wx = 0.0, wv = 0.0, wa = (o == 0 && l == 0 && fd == 0) ? r->tip2 : 0.0;
                for (int i = 0; i < np; i++) {
                    double mq = 0.0, mv = 0.0;
                    if (o == 0) { /* Phi(l tau) on its own piece's end rows */
                        mq = ph[l][0][i] * e[i] + ph[l][1][i] * e[np + i];
                        mv = ph[l][2][i] * e[i] + ph[l][3][i] * e[np + i];
                    }
                    if (l >= 1) { /* Phi((l - 1) tau) on the next piece's start rows */
                        mq += ph[l - 1][0][i] * nx[i] + ph[l - 1][1][i] * nx[np + i];
                        mv += ph[l - 1][2][i] * nx[i] + ph[l - 1][3][i] * nx[np + i];
                    }
                    T->m[o][l][fd][0][i] = mq;
                    T->m[o][l][fd][1][i] = mv;
                    wx += r->tip[i] * mq;
                    wv += r->tip[i] * mv;
                    wa += r->aq[i] * mq + r->av[i] * mv;
                }
                T->w[o][l][fd][0] = wx;
                T->w[o][l][fd][1] = wv;
                T->w[o][l][fd][2] = wa;
            }
    }
    T->on = true;
}

/* The full state at node n into o from the origin org at node po < n and the node forces and
 * slopes F, D (po .. n); the tip's fields from tp (the node's own, as the solve left them). */
static inline __attribute__((always_inline)) void
rt_tc_state(const rt_state *r, const rt_snap *org, int po, int n, const double *F, const double *D,
            const rt_snap *tp, rt_snap *o, const int np, const int nt) {
    const rt_tc_tab *T = &r->tc;
    const int l = n - po;
    const afm_rt_prop *PL = &r->prop[l * T->k - 1];
    const double *c = PL->c;
    for (int i = 0; i < np; i += 4) {
        rt_v4 q = RT_V4(org->q + i), v = RT_V4(org->v + i);
        const rt_v4 fo = rt_splat(F[po]), dO = rt_splat(D[po]);
        rt_v4 a = rt_fma4(
            RT_V4(c + i), q,
            rt_fma4(RT_V4(c + np + i), v,
                    rt_fma4(RT_V4(T->m[1][l][0][0] + i), fo, RT_V4(T->m[1][l][1][0] + i) * dO)));
        rt_v4 w = rt_fma4(
            RT_V4(c + 2 * np + i), q,
            rt_fma4(RT_V4(c + 3 * np + i), v,
                    rt_fma4(RT_V4(T->m[1][l][0][1] + i), fo, RT_V4(T->m[1][l][1][1] + i) * dO)));
        for (int j = po + 1; j <= n; j++) {
            const rt_v4 fj = rt_splat(F[j]), dj = rt_splat(D[j]);
            const int lj = n - j;
            a = rt_fma4(RT_V4(T->m[0][lj][0][0] + i), fj,
                        rt_fma4(RT_V4(T->m[0][lj][1][0] + i), dj, a));
            w = rt_fma4(RT_V4(T->m[0][lj][0][1] + i), fj,
                        rt_fma4(RT_V4(T->m[0][lj][1][1] + i), dj, w));
        }
        RT_V4W(o->q + i) = a;
        RT_V4W(o->v + i) = w;
    }
    double zr[AFM_MAX_TONES], zi[AFM_MAX_TONES];
    rt_tones_rotate(org->z_re, org->z_im, PL->rot_re, PL->rot_im, zr, zi, nt);
    rt_tones_store(o->z_re, o->z_im, zr, zi, nt);
    if (o != tp) {
        o->tip = tp->tip;
        o->dfdx_n_m = tp->dfdx_n_m;
        o->dfdv_n_s_m = tp->dfdv_n_s_m;
        o->df_per_cell_n = tp->df_per_cell_n;
        o->fdot_n_s = tp->fdot_n_s;
        o->acc_m_s2 = tp->acc_m_s2;
    }
    o->slope_cells = 0;
    o->acc_free = false;
}

/* rt_graded_acc in the tip-channel form (the same decisions per piece; no merges). */
static inline __attribute__((always_inline)) void
rt_graded_tc_t(const afm_sim *s, const rt_state *r, const rt_snap *a, rt_snap *b, const int np,
               const int nt, const bool evs, rt_evacc *ea) {
    const rt_tc_tab *T = &r->tc;
    const int K = RT_TC_NODES, k = T->k, sub = r->m / K;
    const double tau = r->prop[k - 1].tau_s, taus = s->dt_s / r->m, xc = r->xc;
    const double close = RT_ACC_CLOSE_TRAVELS * tau;
    const double gx = T->w[0][0][0][0], gv = T->w[0][0][0][1], ga = T->w[0][0][0][2];
    const double gdx = T->w[0][0][1][0], gdv = T->w[0][0][1][1], gda = T->w[0][0][1][2];
    double F[RT_TC_NODES + 1], D[RT_TC_NODES + 1];
    rt_snap nd[2], ob[3], mat, w[2];
    const double far2 = RT_ACC_MERGE_TRAVELS * 2.0 * tau;
    const rt_snap *org = a, *in = a;
    int po = 0;
    F[0] = a->tip.f_n;
    D[0] = tau * a->fdot_n_s;
    for (int p = 1; p <= K; p++) {
        rt_snap *o = p == K ? b : in == &nd[0] ? &nd[1] : &nd[0];
        /* out of contact, far from the line at both ends: two pieces in one, as rt_graded_acc
         * (RT_ACC_TC_MERGE), taken by rt_piece_acc_t from the state at this node; kept, its
         * end is the new origin */
        if (RT_ACC_TC_MERGE && RT_ACC_MERGE_TRAVELS > 0 && ((p - 1) & 1) == 0 &&
            rt_merge_clear(r, in, far2, 2.0 * tau)) {
            const rt_snap *st = in;
            rt_snap *sm = org == &ob[0] ? &ob[1] : &ob[0];
            if (p - 1 > po) {
                rt_tc_state(r, org, po, p - 1, F, D, in, sm, np, nt);
                st = sm;
            }
            rt_snap *o2 = p + 1 == K                        ? b
                          : (org != &ob[2] && sm != &ob[2]) ? &ob[2]
                          : (org != &ob[1] && sm != &ob[1]) ? &ob[1]
                                                            : &ob[0];
            if (rt_graded_merge_t(s, r, st, o2, 2 * k, 2.0 * tau, far2, (double)(p + 1) / K, np, nt,
                                  evs, ea)) {
                org = in = o2;
                po = p + 1;
                F[po] = o2->tip.f_n;
                D[po] = tau * o2->fdot_n_s;
                p++;
                continue;
            }
            if (st == sm) { /* the state formed: the origin from here */
                org = in = sm;
                po = p - 1;
            }
            o = p == K ? b : &nd[0];
        }
        /* a start in contact close to the line: redone whatever its end (rt_graded_acc) */
        bool redo = in->tip.x_m < xc && xc - in->tip.x_m < close * fabs(in->tip.v_m_s);
        if (!redo) {
            const int l = p - po;
            const afm_rt_prop *PL = &r->prop[l * k - 1];
            const double(*fr)[AFM_MAX_MODES] = T->fr[l];
            rt_v4 x4 = rt_splat(0.0), v4 = rt_splat(0.0), a4 = rt_splat(0.0);
            for (int i = 0; i < np; i += 4) {
                rt_v4 q = RT_V4(org->q + i), v = RT_V4(org->v + i);
                x4 = rt_fma4(RT_V4(fr[0] + i), q, rt_fma4(RT_V4(fr[1] + i), v, x4));
                v4 = rt_fma4(RT_V4(fr[2] + i), q, rt_fma4(RT_V4(fr[3] + i), v, v4));
                a4 = rt_fma4(RT_V4(fr[4] + i), q, rt_fma4(RT_V4(fr[5] + i), v, a4));
            }
            double xs, vs;
            rt_hsum2(x4, v4, &xs, &vs);
            double as = rt_hsum(a4);
            double zr[AFM_MAX_TONES], zi[AFM_MAX_TONES];
            rt_tones_rotate(org->z_re, org->z_im, PL->rot_re, PL->rot_im, zr, zi, nt);
            xs += rt_tones_im(PL->dx_re, PL->dx_im, org->z_re, org->z_im, nt);
            vs += rt_tones_im(PL->dv_re, PL->dv_im, org->z_re, org->z_im, nt);
            as += rt_tones_im(r->ax_re, r->ax_im, zr, zi, nt);
            /* the origin's force and slope, then the nodes between, then D held at the last */
            const double *wf = T->w[1][l][0], *wd = T->w[1][l][1];
            xs = fma(wf[0], F[po], fma(wd[0], D[po], xs));
            vs = fma(wf[1], F[po], fma(wd[1], D[po], vs));
            as = fma(wf[2], F[po], fma(wd[2], D[po], as));
            for (int j = po + 1; j < p; j++) {
                wf = T->w[0][p - j][0];
                wd = T->w[0][p - j][1];
                xs = fma(wf[0], F[j], fma(wd[0], D[j], xs));
                vs = fma(wf[1], F[j], fma(wd[1], D[j], vs));
                as = fma(wf[2], F[j], fma(wd[2], D[j], as));
            }
            const double F0 = F[p - 1], Dh = D[p - 1];
            xs = fma(gdx, Dh, xs);
            vs = fma(gdv, Dh, vs);
            as = fma(gda, Dh, as);
            /* the end force (rt_piece_acc_t's solve), then D from dF/dt at the end */
            double jj = 1.0 - in->dfdx_n_m * gx - in->dfdv_n_s_m * gv;
            const double rj = 1.0 / (jj > 0.25 ? jj : 0.25);
            const double F1 = rt_solve_in_t(s, r, xs, vs, gx, gv,
                                            fma(in->df_per_cell_n, (double)k, F0), rj, o, true);
            double x1 = fma(gx, F1, xs), v1 = fma(gv, F1, vs);
            const double acc = fma(ga, F1, as);
            const double fdot = fma(o->dfdx_n_m, v1, o->dfdv_n_s_m * acc);
            const double dd = fma(tau, fdot, -Dh);
            x1 = fma(gdx, dd, x1);
            v1 = fma(gdv, dd, v1);
            if (evs) o->acc_m_s2 = fma(gda, dd, acc);
            rt_piece_end(r, o, k, F0, F1, x1, v1, fdot);
            F[p] = F1;
            D[p] = tau * fdot;
            redo = (x1 < xc && xc - x1 < close * fabs(v1)) || rt_crosses(r, in, o, tau);
        }
        if (redo) { /* the state at node p - 1, then its substeps; their end the new origin */
            const rt_snap *st = in;
            if (p - 1 > po) {
                rt_tc_state(r, org, po, p - 1, F, D, in, &mat, np, nt);
                st = &mat;
            }
            rt_snap *dst = p == K ? b : org == &ob[0] ? &ob[1] : &ob[0];
            rt_substeps_acc(s, r, st, dst, w, (p - 1) * sub, sub, taus, ea);
            org = in = dst;
            po = p;
            F[p] = dst->tip.f_n;
            D[p] = tau * dst->fdot_n_s;
            continue;
        }
        if (ea) rt_ev_herm(ea, s, r, o, (double)p / K);
        in = o;
    }
    if (po < K) rt_tc_state(r, org, po, K, F, D, b, b, np, nt); /* b's tip is the last node's */
}

#endif
