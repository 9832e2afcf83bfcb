/* SPDX-License-Identifier: MIT */
/* afm_model.c -- from config to modal form: FEM + Rubin CMS + clamped base (eq. D.32-D.33),
 * then the reduced model's own eigenmodes; plus the `modes` report (Tables 2.1, 3.1, 3.2). */
#include "beam/afm_model.h"

#include "beam/afm_cms.h"
#include "beam/afm_fem.h"
#include "beam/afm_linalg.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double two_pi = 6.283185307179586476925286766559;

/* The reduced beam with the base prescribed: Mr, Kr (nr x nr, z = [up, pr, pk]) and the
 * base couplings kR(2:nz,1), mR(2:nz,1); then the eigenmodes of (Kr, Mr). */
typedef struct {
    afm_fem fem;
    afm_cms cms;
    int nr;
    double *Mr, *Kr, *kb, *mb; /* nr x nr, nr, nr */
    double *lam, *Phi;         /* nr, nr x nr (columns mass-normalised) */
} reduced_beam;

static void reduced_destroy(reduced_beam *r) {
    afm_fem_destroy(&r->fem);
    afm_cms_destroy(&r->cms);
    free(r->Mr);
    free(r->Kr);
    free(r->kb);
    free(r->mb);
    free(r->lam);
    free(r->Phi);
    memset(r, 0, sizeof *r);
}

static int reduced_build(const afm_cfg_beam *b, reduced_beam *r, char *err, size_t errlen) {
    memset(r, 0, sizeof *r);
    if (afm_fem_assemble(b, &r->fem, err, errlen) != 0) return -1;
    if (afm_cms_reduce(&r->fem, b->n_kept, &r->cms, err, errlen) != 0) goto fail;
    int nz = r->cms.nz, nr = nz - 1;
    r->nr = nr;
    r->Mr = malloc(sizeof(double) * (size_t)(nr * nr));
    r->Kr = malloc(sizeof(double) * (size_t)(nr * nr));
    r->kb = malloc(sizeof(double) * (size_t)nr);
    r->mb = malloc(sizeof(double) * (size_t)nr);
    r->lam = malloc(sizeof(double) * (size_t)nr);
    r->Phi = malloc(sizeof(double) * (size_t)(nr * nr));
    if (!r->Mr || !r->Kr || !r->kb || !r->mb || !r->lam || !r->Phi) {
        snprintf(err, errlen, "model: out of memory");
        goto fail;
    }
    /* eq. D.31-D.32: drop the prescribed u1 (row/column 0); its column becomes the drive. */
    for (int i = 0; i < nr; i++) {
        for (int j = 0; j < nr; j++) {
            r->Mr[i * nr + j] = r->cms.MR[(i + 1) * nz + (j + 1)];
            r->Kr[i * nr + j] = r->cms.KR[(i + 1) * nz + (j + 1)];
        }
        r->kb[i] = r->cms.KR[(i + 1) * nz];
        r->mb[i] = r->cms.MR[(i + 1) * nz];
    }
    if (afm_la_eig(nr, r->Kr, r->Mr, r->lam, r->Phi, err, errlen) != 0) goto fail;
    return 0;
fail:
    reduced_destroy(r);
    return -1;
}

static double xi_of_mode(const afm_cfg_model *cfg, int i) {
    if (cfg->n_damping <= 0) return 0.0;
    return cfg->damping_ratio[i < cfg->n_damping ? i : cfg->n_damping - 1];
}

static int build_lumped(const afm_cfg_model *cfg, afm_modal *m, char *err, size_t errlen) {
    const afm_cfg_lumped *l = &cfg->lumped;
    if (!(l->stiffness_n_m > 0) || !(l->resonance_hz > 0)) {
        snprintf(err, errlen, "lumped model: stiffness and resonance must be positive");
        return -1;
    }
    double w = two_pi * l->resonance_hz, me = l->stiffness_n_m / (w * w);
    m->n = 1;
    m->omega_rad_s[0] = w;
    m->xi[0] = xi_of_mode(cfg, 0);
    m->tip[0] = 1.0 / sqrt(me);
    /* k (x - x_dit): the base enters through the spring, i.e. the thesis's Fe = k Ae. */
    m->base_k[0] = -l->stiffness_n_m / sqrt(me);
    m->base_m[0] = 0.0;
    m->rot[0] = 0.0; /* a lumped model has no slope; the OBD chain calibrates on x */
    m->rot_base = 0.0;
    m->static_stiffness_n_m = l->stiffness_n_m;
    return 0;
}

void afm_model_mode_response(const afm_modal *m, int i, double w_rad_s, double *re, double *im) {
    double w = m->omega_rad_s[i], wd = w_rad_s;
    double num = -m->base_k[i] + m->base_m[i] * wd * wd; /* base acceleration is -wd^2 u */
    double dr = w * w - wd * wd, di = 2.0 * m->xi[i] * w * wd, den = dr * dr + di * di;
    *re = num * dr / den;
    *im = -num * di / den;
}

void afm_model_tip_response(const afm_modal *m, double w_rad_s, double *re, double *im) {
    double gr = 0.0, gi = 0.0;
    for (int i = 0; i < m->n; i++) {
        double hr, hi;
        afm_model_mode_response(m, i, w_rad_s, &hr, &hi);
        gr += m->tip[i] * hr;
        gi += m->tip[i] * hi;
    }
    *re = gr;
    *im = gi;
}

int afm_model_build(const afm_cfg_model *cfg, afm_modal *m, char *err, size_t errlen) {
    memset(m, 0, sizeof *m);
    if (cfg->kind == AFM_MODEL_LUMPED) return build_lumped(cfg, m, err, errlen);
    const afm_cfg_beam *b = &cfg->beam;
    if (b->n_kept + 2 > AFM_MAX_MODES) {
        snprintf(err, errlen, "model: %d kept modes exceed the limit of %d", b->n_kept,
                 AFM_MAX_MODES - 2);
        return -1;
    }
    reduced_beam r;
    if (reduced_build(b, &r, err, errlen) != 0) return -1;
    int nr = r.nr, ny = r.cms.ny, nz = r.cms.nz;
    const double *trot = &r.cms.T[(ny - 1) * nz]; /* row of the tip rotation thp */
    m->n = nr;
    for (int i = 0; i < nr; i++) {
        m->omega_rad_s[i] = sqrt(fmax(r.lam[i], 0.0));
        m->xi[i] = xi_of_mode(cfg, i);
        m->tip[i] = r.Phi[0 * nr + i]; /* up is the first reduced coordinate */
        double kb = 0, mb = 0, rot = 0;
        for (int j = 0; j < nr; j++) {
            kb += r.Phi[j * nr + i] * r.kb[j];
            mb += r.Phi[j * nr + i] * r.mb[j];
            rot += trot[1 + j] * r.Phi[j * nr + i];
        }
        m->base_k[i] = kb;
        m->base_m[i] = mb;
        m->rot[i] = rot;
    }
    m->rot_base = trot[0];
    double comp = 0.0; /* static tip compliance: sum tip_i^2 / w_i^2 (exact: residual modes) */
    for (int i = 0; i < nr; i++)
        comp += m->tip[i] * m->tip[i] / r.lam[i];
    m->static_stiffness_n_m = 1.0 / comp;
    m->beam_length_m = b->length_m;
    m->beam_mean_width_m = 0.5 * (b->width_m[0] + b->width_m[1]);
    reduced_destroy(&r);
    return 0;
}

/* Roots of cos(bL) cosh(bL) + 1 = 0 (eq. 2.7): exactly one in ((n-1) pi, n pi); bisection. */
static double clamped_free_root(int n) {
    const double pi = 3.14159265358979323846;
    double lo = (n - 1) * pi + 1e-12, hi = n * pi;
    double flo = cos(lo) * cosh(lo) + 1;
    for (int it = 0; it < 200; it++) {
        double mid = 0.5 * (lo + hi), fm = cos(mid) * cosh(mid) + 1;
        if ((flo < 0) == (fm < 0))
            lo = mid, flo = fm;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

static int report_beam(const afm_cfg_model *cfg, afm_modes_report *rep, char *err, size_t errlen) {
    const afm_cfg_beam *b = &cfg->beam;
    reduced_beam r;
    if (reduced_build(b, &r, err, errlen) != 0) return -1;
    int n = r.fem.n, nc = n - 2, nr = r.nr, ny = r.cms.ny, nz = r.cms.nz, rc = -1;
    double *Kc = malloc(sizeof(double) * (size_t)(nc * nc));
    double *Mc = malloc(sizeof(double) * (size_t)(nc * nc));
    double *Vc = malloc(sizeof(double) * (size_t)(nc * nc));
    double *lc = malloc(sizeof(double) * (size_t)nc);
    double *ex = malloc(sizeof(double) * (size_t)nc);
    if (!Kc || !Mc || !Vc || !lc || !ex) {
        snprintf(err, errlen, "modes: out of memory");
        goto done;
    }
    /* Unreduced clamped-free model: drop u1 and th1. */
    for (int i = 0; i < nc; i++)
        for (int j = 0; j < nc; j++) {
            Kc[i * nc + j] = r.fem.K[(i + 2) * n + (j + 2)];
            Mc[i * nc + j] = r.fem.M[(i + 2) * n + (j + 2)];
        }
    if (afm_la_eig(nc, Kc, Mc, lc, Vc, err, errlen) != 0) goto done;
    rep->n_reduced = nr;
    rep->n_unreduced = nc < nr ? nc : nr;
    for (int i = 0; i < nr; i++)
        rep->reduced_hz[i] = sqrt(fmax(r.lam[i], 0)) / two_pi;
    for (int j = 0; j < rep->n_unreduced; j++)
        rep->unreduced_hz[j] = sqrt(fmax(lc[j], 0)) / two_pi;
    /* MAC (eq. 3.8, 3.10): reduced mode expanded with T (rows u2..thp, columns up, pr, pk),
     * guided-free row r >= 1 is clamped-free index r - 1. */
    for (int i = 0; i < nr; i++) {
        for (int r1 = 1; r1 < ny; r1++) {
            double s = 0;
            for (int j = 0; j < nr; j++)
                s += r.cms.T[r1 * nz + 1 + j] * r.Phi[j * nr + i];
            ex[r1 - 1] = s;
        }
        for (int j = 0; j < rep->n_unreduced; j++) {
            double dot = 0, ee = 0, vv = 0;
            for (int k = 0; k < nc; k++) {
                dot += ex[k] * Vc[k * nc + j];
                ee += ex[k] * ex[k];
                vv += Vc[k * nc + j] * Vc[k * nc + j];
            }
            rep->mac[i][j] = dot * dot / (ee * vv);
        }
    }
    /* eq. 2.14 with the mass-normalised first mode: m_e = 1 / phi_tip^2. */
    double phitip = Vc[(nc - 2) * nc + 0];
    rep->effective_mass_kg = 1.0 / (phitip * phitip);
    afm_modal m;
    if (afm_model_build(cfg, &m, err, errlen) != 0) goto done;
    rep->static_stiffness_n_m = m.static_stiffness_n_m;
    rep->beam_mass_kg = r.fem.beam_mass_kg;
    /* Analytical clamped-free Euler-Bernoulli (eq. 3.7), uniform beams, no tip mass. */
    rep->n_analytical = 0;
    if (b->width_m[0] == b->width_m[1] && b->height_m[0] == b->height_m[1]) {
        double W = b->width_m[0], H = b->height_m[0], L = b->length_m;
        double EI = b->youngs_modulus_pa * W * H * H * H / 12.0, mbar = b->density_kg_m3 * W * H;
        rep->n_analytical = rep->n_unreduced;
        for (int k = 0; k < rep->n_analytical; k++) {
            double bl = clamped_free_root(k + 1);
            rep->analytical_hz[k] = bl * bl / (L * L) * sqrt(EI / mbar) / two_pi;
        }
    }
    rc = 0;
done:
    free(Kc);
    free(Mc);
    free(Vc);
    free(lc);
    free(ex);
    reduced_destroy(&r);
    return rc;
}

int afm_model_report(const afm_cfg_model *cfg, afm_modes_report *rep, char *err, size_t errlen) {
    memset(rep, 0, sizeof *rep);
    if (cfg->kind == AFM_MODEL_LUMPED) {
        afm_modal m;
        if (afm_model_build(cfg, &m, err, errlen) != 0) return -1;
        rep->n_reduced = 1;
        rep->reduced_hz[0] = m.omega_rad_s[0] / two_pi;
        rep->static_stiffness_n_m = m.static_stiffness_n_m;
        rep->effective_mass_kg = 1.0 / (m.tip[0] * m.tip[0]);
        return 0;
    }
    return report_beam(cfg, rep, err, errlen);
}
