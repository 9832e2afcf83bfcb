/* SPDX-License-Identifier: MIT */
/* afm_rt_coef.c -- exact per-mode step coefficients for the rt backend (see afm_rt_coef.h). */
#include "integrators/afm_rt_coef.h"

#include "forces/afm_force_inline.h"

#include <math.h>
#include <string.h>

#define EXPM_MAX 8

static void matmul(int n, const double *a, const double *b, double *c) {
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double acc = 0.0;
            for (int k = 0; k < n; k++)
                acc += a[i * n + k] * b[k * n + j];
            c[i * n + j] = acc;
        }
}

void afm_rt_coef_expm(int n, const double *a, double *e) {
    double norm = 0.0; /* 1-norm */
    for (int j = 0; j < n; j++) {
        double col = 0.0;
        for (int i = 0; i < n; i++)
            col += fabs(a[i * n + j]);
        if (col > norm) norm = col;
    }
    /* Scale to norm <= 1/8: 18 Taylor terms then leave < 1e-30 and the squarings of a
     * dissipative exponential lose little. */
    int sq = 0;
    while (norm > 0.125 && sq < 60) {
        norm *= 0.5;
        sq++;
    }
    double as[EXPM_MAX * EXPM_MAX], term[EXPM_MAX * EXPM_MAX], tmp[EXPM_MAX * EXPM_MAX];
    double scale = ldexp(1.0, -sq);
    for (int k = 0; k < n * n; k++)
        as[k] = a[k] * scale;
    memset(e, 0, sizeof(double) * (size_t)(n * n));
    memset(term, 0, sizeof term);
    for (int i = 0; i < n; i++)
        e[i * n + i] = term[i * n + i] = 1.0;
    for (int k = 1; k <= 18; k++) {
        matmul(n, term, as, tmp);
        for (int m = 0; m < n * n; m++) {
            term[m] = tmp[m] / k;
            e[m] += term[m];
        }
    }
    for (int k = 0; k < sq; k++) {
        matmul(n, e, e, tmp);
        memcpy(e, tmp, sizeof(double) * (size_t)(n * n));
    }
}

void afm_rt_coef_modes(afm_rt_prop *p, int n, int np, const double *w, const double *xi,
                       const double *tip, double tau_s) {
    double *c = p->c;
    for (int i = 0; i < AFM_RT_COEF_ROWS * np; i++)
        c[i] = 0.0;
    p->tau_s = tau_s;
    p->gx = p->gv = p->gx0 = p->gv0 = 0.0;
    p->gcx = p->gcv = p->gd0x = p->gd0v = p->gd1x = p->gd1v = 0.0;
    for (int i = 0; i < n; i++) {
        /* Scaled state u = (q, q'/w), scaled time sigma = s/tau in [0, 1]:
         *   du/dsigma = tau w [[0, 1], [-1, -2 xi]] u + [0; tau/w] F(sigma),
         *   F(sigma) = F0 + (F1 - F0) sigma -> augmented with (F0, F1 - F0). */
        double wt = w[i] * tau_s;
        double m[16] = {0}, e[16];
        m[0 * 4 + 1] = wt;
        m[1 * 4 + 0] = -wt;
        m[1 * 4 + 1] = -2.0 * xi[i] * wt;
        m[1 * 4 + 2] = tau_s / w[i];
        m[2 * 4 + 3] = 1.0;
        afm_rt_coef_expm(4, m, e);
        double g1u1 = e[3], g1u2 = e[7];               /* response to the ramp F1 - F0 */
        double g0u1 = e[2] - g1u1, g0u2 = e[6] - g1u2; /* to constant F0, minus the ramp */
        c[i] = e[0];
        c[np + i] = e[1] / w[i];
        c[2 * np + i] = e[4] * w[i];
        c[3 * np + i] = e[5];
        c[4 * np + i] = tip[i] * g0u1;
        c[5 * np + i] = tip[i] * w[i] * g0u2;
        c[6 * np + i] = tip[i] * g1u1;
        c[7 * np + i] = tip[i] * w[i] * g1u2;
        p->gx += tip[i] * c[6 * np + i];
        p->gv += tip[i] * c[7 * np + i];
        p->gx0 += tip[i] * c[4 * np + i];
        p->gv0 += tip[i] * c[5 * np + i];
        for (int r = 0; r < 4; r++)
            c[(8 + r) * np + i] = tip[i] * c[r * np + i];
    }
}

void afm_rt_coef_hermite(afm_rt_prop *p, int n, int np, const double *w, const double *xi,
                         const double *tip) {
    double *c = p->c + AFM_RT_ROW_GC * np;
    const double tau_s = p->tau_s;
    p->gcx = p->gcv = p->gd0x = p->gd0v = p->gd1x = p->gd1v = 0.0;
    for (int i = 0; i < n; i++) {
        /* As afm_rt_coef_modes, augmented with a shift chain a3' = a4, a4' = a5, a5' = a6:
         * a3(sigma) = a3 + a4 sigma + a5 sigma^2 / 2 + a6 sigma^3 / 6, so the response of u to
         * sigma^k is k! times column 2 + k of the exponential. */
        double wt = w[i] * tau_s;
        double m[36] = {0}, e[36];
        m[0 * 6 + 1] = wt;
        m[1 * 6 + 0] = -wt;
        m[1 * 6 + 1] = -2.0 * xi[i] * wt;
        m[1 * 6 + 2] = tau_s / w[i];
        m[2 * 6 + 3] = 1.0;
        m[3 * 6 + 4] = 1.0;
        m[4 * 6 + 5] = 1.0;
        afm_rt_coef_expm(6, m, e);
        double r[2][4]; /* u1, u2 response to sigma^0 .. sigma^3 */
        for (int u = 0; u < 2; u++) {
            r[u][0] = e[u * 6 + 2];
            r[u][1] = e[u * 6 + 3];
            r[u][2] = 2.0 * e[u * 6 + 4];
            r[u][3] = 6.0 * e[u * 6 + 5];
        }
        double gc[2], gd0[2], gd1[2];
        for (int u = 0; u < 2; u++) {
            gc[u] = r[u][1] - 3.0 * r[u][2] + 2.0 * r[u][3];
            gd0[u] = r[u][1] - 2.0 * r[u][2] + r[u][3];
            gd1[u] = r[u][3] - r[u][2];
        }
        c[i] = tip[i] * gc[0];
        c[np + i] = tip[i] * w[i] * gc[1];
        c[2 * np + i] = tip[i] * gd0[0];
        c[3 * np + i] = tip[i] * w[i] * gd0[1];
        c[4 * np + i] = tip[i] * gd1[0];
        c[5 * np + i] = tip[i] * w[i] * gd1[1];
        p->gcx += tip[i] * c[i];
        p->gcv += tip[i] * c[np + i];
        p->gd0x += tip[i] * c[2 * np + i];
        p->gd0v += tip[i] * c[3 * np + i];
        p->gd1x += tip[i] * c[4 * np + i];
        p->gd1v += tip[i] * c[5 * np + i];
        c[(AFM_RT_ROW_GD01 - AFM_RT_ROW_GC) * np + i] = c[2 * np + i] + c[4 * np + i];
        c[(AFM_RT_ROW_GD01 - AFM_RT_ROW_GC + 1) * np + i] = c[3 * np + i] + c[5 * np + i];
        double *c0 = p->c;
        c0[AFM_RT_ROW_K0 * np + i] = c0[4 * np + i] + c[i];
        c0[(AFM_RT_ROW_K0 + 1) * np + i] = c0[5 * np + i] + c[np + i];
        c0[AFM_RT_ROW_K1 * np + i] = c0[6 * np + i] - c[i];
        c0[(AFM_RT_ROW_K1 + 1) * np + i] = c0[7 * np + i] - c[np + i];
    }
    p->hx0 = p->gx0 + p->gcx;
    p->hd0x = p->gd0x + p->gd1x;
    p->hv0 = p->gv0 + p->gcv;
    p->hd0v = p->gd0v + p->gd1v;
    p->hx1 = p->gx - p->gcx;
    p->hv1 = p->gv - p->gcv;
}

void afm_rt_coef_chain(afm_rt_prop *p, const afm_rt_prop *pf, int np) {
    const double *c = p->c, *cf = pf->c;
    double hx = pf->gx0, hv = pf->gv0;
    for (int i = 0; i < np; i++) {
        hx += cf[8 * np + i] * c[6 * np + i] + cf[9 * np + i] * c[7 * np + i];
        hv += cf[10 * np + i] * c[6 * np + i] + cf[11 * np + i] * c[7 * np + i];
    }
    p->hx = hx;
    p->hv = hv;
}

/* Cell p's drive rows for tone j from its rotation e^{i wd tau} = (rr, ri). */
static inline void drive_row(afm_rt_prop *p, int j, double rr, double ri, double wd, double cx_re,
                             double cx_im) {
    p->rot_re[j] = rr;
    p->rot_im[j] = ri;
    p->dx_re[j] = cx_re * rr - cx_im * ri;
    p->dx_im[j] = cx_re * ri + cx_im * rr;
    p->dv_re[j] = -wd * p->dx_im[j]; /* i wd dx */
    p->dv_im[j] = wd * p->dx_re[j];
}

void afm_rt_coef_drive_cells(afm_rt_prop *prop, int ncell, int ntones, int nheld, const double *wd,
                             const double *cx_re, const double *cx_im) {
    enum { A = AFM_RT_DRIVE_ANCHOR };
    for (int j = 0; j < ntones; j++) {
        double pw_re[A], pw_im[A]; /* e^{i wd r tau_0}, r = 0..A-1 */
        pw_re[0] = 1.0;
        pw_im[0] = 0.0;
        pw_re[1] = cos(wd[j] * prop[0].tau_s);
        pw_im[1] = sin(wd[j] * prop[0].tau_s);
        for (int r = 2; r < A; r++) {
            pw_re[r] = pw_re[r - 1] * pw_re[1] - pw_im[r - 1] * pw_im[1];
            pw_im[r] = pw_re[r - 1] * pw_im[1] + pw_im[r - 1] * pw_re[1];
        }
        double an_re = 1.0, an_im = 0.0; /* the anchor: cell k0 - 1's rotation (1 before 0) */
        for (int k0 = 0; k0 < ncell; k0 += A) {
            /* cells k0 .. k0 + A - 2 from the anchor, the block's last (and the full step,
             * the table's last) by sincos */
            const int last = k0 + A - 1 < ncell - 1 ? k0 + A - 1 : ncell - 1;
            for (int k = k0; k < last; k++) {
                const int r = k - k0 + 1;
                drive_row(&prop[k], j, an_re * pw_re[r] - an_im * pw_im[r],
                          an_re * pw_im[r] + an_im * pw_re[r], wd[j], cx_re[j], cx_im[j]);
            }
            an_re = cos(wd[j] * prop[last].tau_s);
            an_im = sin(wd[j] * prop[last].tau_s);
            drive_row(&prop[last], j, an_re, an_im, wd[j], cx_re[j], cx_im[j]);
        }
    }
    for (int k = 0; k < ncell; k++) /* zeros past ntones: afm_rt.c's tone vector */
        for (int j = ntones; j < nheld; j++)
            drive_row(&prop[k], j, 0.0, 0.0, 0.0, 0.0, 0.0);
}

void afm_rt_coef_thermal(const afm_rt_prop *p, int n, int np, const double *w, const double *xi,
                         double kt_j, double *l11, double *l21, double *l22) {
    for (int i = 0; i < np; i++)
        l11[i] = l21[i] = l22[i] = 0.0;
    const double *c = p->c;
    for (int i = 0; i < n; i++) {
        /* Scaled coordinates u = (q, q'/w), time sigma = s/tau, variances in units of
         * kB T / w^2: du/dsigma = M u + noise of intensity Qs = diag(0, 4 xi w tau),
         * M = w tau [0, 1; -1, -2 xi], stationary covariance I. */
        double wt = w[i] * p->tau_s, s11, s12, s22;
        if (2.0 * xi[i] * wt > 0.5) {
            /* Strong decay over the step: I - Phi_s Phi_s^T loses under one digit. */
            double a = c[i], b = w[i] * c[np + i], cc = c[2 * np + i] / w[i], d = c[3 * np + i];
            s11 = 1.0 - (a * a + b * b);
            s12 = -(a * cc + b * d);
            s22 = 1.0 - (cc * cc + d * d);
        } else {
            /* Weak decay: that difference would cancel to the damping per step. Van Loan:
             * exp([-M, Qs; 0, M^T]) = [., E12; 0, Phi_s^T], Sigma_s = Phi_s E12, with E12 =
             * O(Qs) accurate to ~1e-16 absolute (exp(-M) grows at most e^0.25 here). */
            double m[16] = {0}, e[16];
            m[0 * 4 + 1] = -wt; /* -M */
            m[1 * 4 + 0] = wt;
            m[1 * 4 + 1] = 2.0 * xi[i] * wt;
            m[1 * 4 + 3] = 4.0 * xi[i] * wt; /* Qs */
            m[2 * 4 + 3] = -wt;              /* M^T */
            m[3 * 4 + 2] = wt;
            m[3 * 4 + 3] = -2.0 * xi[i] * wt;
            afm_rt_coef_expm(4, m, e);
            double f11 = e[10], f12 = e[14], f21 = e[11], f22 = e[15]; /* Phi_s = E22^T */
            double g11 = e[2], g12 = e[3], g21 = e[6], g22 = e[7];
            s11 = f11 * g11 + f12 * g21;
            s22 = f21 * g12 + f22 * g22;
            s12 = 0.5 * ((f11 * g12 + f12 * g22) + (f21 * g11 + f22 * g21));
        }
        double var = kt_j / (w[i] * w[i]);
        if (!(s11 > 0.0)) continue; /* no damping: no noise */
        double q11 = var * s11, q12 = var * w[i] * s12, q22 = var * w[i] * w[i] * s22;
        l11[i] = sqrt(q11);
        l21[i] = q12 / l11[i];
        double r = q22 - l21[i] * l21[i];
        l22[i] = r > 0.0 ? sqrt(r) : 0.0;
    }
}

/* Sigma of a piece from its Cholesky factor (l11, l21, l22 of mode i, stride np), in the
 * coordinates (q, q' sv). */
static void bridge_sigma(const double *l, int np, int i, long double sv, long double sg[3]) {
    long double a = l[i], b = l[np + i] * sv, c = l[2 * np + i] * sv;
    sg[0] = a * a;
    sg[1] = a * b;
    sg[2] = b * b + c * c;
}

void afm_rt_coef_bridge(int n, int np, double tau1_s, const double *l1, const double *ll,
                        const double *phi2, double *k) {
    for (int i = 0; i < 4 * np; i++)
        k[i] = 0.0;
    const long double sv = tau1_s; /* q' tau1: the scaled covariances are O(1) relative */
    for (int i = 0; i < n; i++) {
        long double s1[3], sl[3];
        bridge_sigma(l1, np, i, sv, s1);
        bridge_sigma(ll, np, i, sv, sl);
        long double det = sl[0] * sl[2] - sl[1] * sl[1];
        if (!(det > 0)) continue; /* a mode without noise */
        /* Phi2 in the scaled coordinates, then A = Sigma1 Phi2^T, K = A Sigma(L)^-1 */
        long double p11 = phi2[i], p12 = phi2[np + i] / sv, p21 = phi2[2 * np + i] * sv,
                    p22 = phi2[3 * np + i];
        long double a11 = s1[0] * p11 + s1[1] * p12, a12 = s1[0] * p21 + s1[1] * p22;
        long double a21 = s1[1] * p11 + s1[2] * p12, a22 = s1[1] * p21 + s1[2] * p22;
        long double i11 = sl[2] / det, i12 = -sl[1] / det, i22 = sl[0] / det;
        long double k11 = a11 * i11 + a12 * i12, k12 = a11 * i12 + a12 * i22;
        long double k21 = a21 * i11 + a22 * i12, k22 = a21 * i12 + a22 * i22;
        /* back to (q, q'): K = S^-1 Ky S with S = diag(1, sv) */
        k[i] = (double)k11;
        k[np + i] = (double)(k12 * sv);
        k[2 * np + i] = (double)(k21 / sv);
        k[3 * np + i] = (double)k22;
    }
}

void afm_rt_starr_build(afm_rt_starr *st, const afm_force_params *p, double z_m) {
    const int nn = 5;
    const double pi = 3.14159265358979323846;
    st->on = false;
    if (p->squeeze != AFM_SQUEEZE_STARR) return;
    double h0 = afm_force_starr_h(p, z_m, 0.0), hw = AFM_RT_STARR_WINDOW * h0;
    if (!isfinite(h0) || !(h0 - hw > p->a0_m)) return;
    double val[5], ch[5];
    for (int k = 0; k < nn; k++) {
        double dcdh;
        val[k] = afm_force_starr_c(p, h0 + hw * cos(pi * (k + 0.5) / nn), &dcdh);
    }
    for (int j = 0; j < nn; j++) { /* Chebyshev coefficients */
        double acc = 0.0;
        for (int k = 0; k < nn; k++)
            acc += val[k] * cos(pi * j * (k + 0.5) / nn);
        ch[j] = (j == 0 ? 1.0 : 2.0) * acc / nn;
    }
    /* T0 = 1, T1 = s, T2 = 2s^2 - 1, T3 = 4s^3 - 3s, T4 = 8s^4 - 8s^2 + 1 */
    st->a[0] = ch[0] - ch[2] + ch[4];
    st->a[1] = ch[1] - 3.0 * ch[3];
    st->a[2] = 2.0 * ch[2] - 8.0 * ch[4];
    st->a[3] = 4.0 * ch[3];
    st->a[4] = 8.0 * ch[4];
    st->h0 = h0;
    st->hw = hw;
    st->ihw = 1.0 / hw;
    for (int k = 0; k < nn; k++)
        if (!isfinite(st->a[k])) return;
    st->on = true;
}
