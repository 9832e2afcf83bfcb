/* SPDX-License-Identifier: MIT */
/* test_model.c -- the reduced-order beam model against thesis Tables 2.1, 3.1, 3.2, E.2,
 * section 4.1.1 / 4.2.1 frequencies, and analytic beam results.
 *
 * Tolerances: the thesis prints frequencies to 5 significant digits (rounding <= 1.3e-5
 * relative), so the 2e-4 leaves room for nothing but real differences; its MAC
 * numbers have 13 digits, and 1e-3 is the bound. */
#include "check.h"

#include "config/afm_config.h"
#include "beam/afm_fem.h"
#include "beam/afm_model.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static afm_config load(const char *path) {
    static afm_config cfg;
    char err[AFM_ERR_LEN];
    if (afm_config_load(path, &cfg, err, sizeof err) != 0) {
        printf("cannot load %s: %s\n", path, err);
        memset(&cfg, 0, sizeof cfg);
    }
    return cfg;
}

static void table_3_1_and_3_2(void) {
    afm_config cfg = load("config/thesis-table-3-1.conf");
    afm_modes_report r;
    char err[AFM_ERR_LEN];
    if (!check_true(afm_model_report(&cfg.model, &r, err, sizeof err) == 0, "Table 3.1 model"))
        return;
    static const double an[4] = {3.8196e4, 2.3937e5, 6.7025e5, 1.3134e6};
    static const double un[4] = {3.8196e4, 2.3937e5, 6.7026e5, 1.3135e6};
    static const double m2[4] = {3.8196e4, 2.3938e5, 6.8714e5, 1.4378e6};
    char item[64];
    for (int i = 0; i < 4; i++) {
        snprintf(item, sizeof item, "mode %d analytical (Hz)", i + 1);
        check_thesis("Table 3.1", item, r.analytical_hz[i], an[i], 2e-4);
        snprintf(item, sizeof item, "mode %d unreduced (Hz)", i + 1);
        check_thesis("Table 3.1", item, r.unreduced_hz[i], un[i], 2e-4);
        snprintf(item, sizeof item, "mode %d method 2 (Hz)", i + 1);
        check_thesis("Table 3.1", item, r.reduced_hz[i], m2[i], 2e-4);
    }
    static const double mac[4][4] = {
        {0.9999999999784, 0.3848900367708, 0.0624643093826, 0.0876828922161},
        {0.3849404219833, 0.9999972713846, 0.2359779606456, 0.0660796487011},
        {0.0664336422155, 0.2583831037744, 0.9875338891790, 0.1413028226591},
        {0.1182104080568, 0.1191825451780, 0.2182604303506, 0.9010385784436}};
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            snprintf(item, sizeof item, "MAC method 2 [%d][%d]", i + 1, j + 1);
            check_thesis_abs("Table 3.2", item, r.mac[i][j], mac[i][j], 1e-3, "");
        }
}

/* Section 2.1.3 / Table 2.1: eigenmode normalisation against the static bending mode,
 * me,S = 33/140 m_beam; the frequency ratio is sqrt(me,S / me,B) (same static k). */
static void table_2_1(void) {
    afm_config cfg = load("config/thesis-table-3-1.conf");
    static const int ne[2] = {10, 100};
    static const double mass_ratio[2] = {1.060602, 1.060606}, freq_ratio[2] = {0.971010, 0.971008};
    for (int k = 0; k < 2; k++) {
        cfg.model.beam.n_elements = ne[k];
        cfg.model.beam.tip_mass_kg = 0.0;
        afm_modes_report r;
        char err[AFM_ERR_LEN], item[64];
        if (!check_true(afm_model_report(&cfg.model, &r, err, sizeof err) == 0, "Table 2.1 model"))
            return;
        double ratio = r.effective_mass_kg / (33.0 / 140.0 * r.beam_mass_kg);
        /* the thesis gives 7 digits: 1e-6 relative is its last digit */
        snprintf(item, sizeof item, "me,B/me,S, %d elements", ne[k]);
        check_thesis("Table 2.1", item, ratio, mass_ratio[k], 1e-6);
        snprintf(item, sizeof item, "w0,B/w0,S, %d elements", ne[k]);
        check_thesis("Table 2.1", item, 1.0 / sqrt(ratio), freq_ratio[k], 1e-6);
    }
}

/* Appendix E.2 / Fig. E.1: 50 elements, T. 3.1 column (no tip mass; Fig. E.1's 0.06% for
 * mode 1 at nk = 0 and 15.93% for mode 6 at nk = 4 identify it). */
static void appendix_e_2(void) {
    afm_config cfg = load("config/thesis-table-3-1.conf");
    cfg.model.beam.n_elements = 50;
    for (int nk = 0; nk <= 9; nk++) {
        cfg.model.beam.n_kept = nk;
        afm_modes_report r;
        char err[AFM_ERR_LEN], item[96];
        if (!check_true(afm_model_report(&cfg.model, &r, err, sizeof err) == 0, "E.2 model"))
            return;
        int within = 0;
        while (within < r.n_reduced &&
               fabs(r.reduced_hz[within] - r.unreduced_hz[within]) / r.unreduced_hz[within] < 1e-3)
            within++;
        if (nk >= 2 && nk <= 6) {
            snprintf(item, sizeof item, "nk = %d: first modes within 0.1%%", nk);
            check_thesis_abs("App. E.2", item, within >= nk ? nk : within, nk, 0, "modes");
        } else if (nk >= 7) {
            snprintf(item, sizeof item, "nk = %d: only nk - 1 modes within 0.1%%", nk);
            check_thesis_abs("App. E.2", item, within, nk - 1, 0, "modes");
        }
        if (nk == 0)
            check_thesis_abs("Fig. E.1", "mode 1, nk = 0: df/f (%)",
                             100 * (r.reduced_hz[0] - r.unreduced_hz[0]) / r.unreduced_hz[0], 0.06,
                             0.005, "%");
        if (nk == 4)
            check_thesis_abs("Fig. E.1", "mode 6, nk = 4: df/f (%)",
                             100 * (r.reduced_hz[5] - r.unreduced_hz[5]) / r.unreduced_hz[5], 15.93,
                             0.005, "%");
    }
}

static void section_4_frequencies(void) {
    afm_config cfg = load("config/thesis-fig-4-2.conf");
    afm_modes_report r;
    char err[AFM_ERR_LEN];
    if (check_true(afm_model_report(&cfg.model, &r, err, sizeof err) == 0, "fig 4-2 model")) {
        check_thesis("Sec. 4.1.1", "4-DOF f1 (Hz)", r.reduced_hz[0], 80.821e3, 2e-4);
        check_thesis("Sec. 4.1.1", "4-DOF f2 (Hz)", r.reduced_hz[1], 506.610e3, 2e-4);
    }
    cfg = load("config/thesis-fig-4-13.conf");
    if (check_true(afm_model_report(&cfg.model, &r, err, sizeof err) == 0, "fig 4-13 model")) {
        check_thesis("Sec. 4.2.1", "5-DOF f1 (Hz)", r.reduced_hz[0], 80.821e3, 2e-4);
        check_thesis("Sec. 4.2.1", "5-DOF f2 (Hz)", r.reduced_hz[1], 506.602e3, 2e-4);
        check_thesis("Sec. 4.2.1", "5-DOF f3 (Hz)", r.reduced_hz[2], 1.41897e6, 2e-4);
    }
}

/* The tapered beams were designed for integer frequency ratios (sections 4.1.2, 4.2.2). */
static void tapered_design_ratios(void) {
    afm_config cfg = load("config/thesis-fig-4-8.conf");
    afm_modes_report r;
    char err[AFM_ERR_LEN];
    if (check_true(afm_model_report(&cfg.model, &r, err, sizeof err) == 0, "fig 4-8 model"))
        check_thesis_abs("Sec. 4.1.2", "tapered f2/f1 (design: close to 6)",
                         r.reduced_hz[1] / r.reduced_hz[0], 6.0, 0.05, "");
    cfg = load("config/thesis-fig-4-20.conf");
    if (check_true(afm_model_report(&cfg.model, &r, err, sizeof err) == 0, "fig 4-20 model"))
        check_thesis_abs("Sec. 4.2.2", "tapered f3/f1 (design: close to 18)",
                         r.reduced_hz[2] / r.reduced_hz[0], 18.0, 0.05, "");
}

/* Analytic beam facts that do not depend on the thesis. */
static void analytic(void) {
    afm_config cfg = load("config/thesis-fig-4-2.conf");
    const afm_cfg_beam *b = &cfg.model.beam;
    afm_modal m;
    char err[AFM_ERR_LEN];
    if (!check_true(afm_model_build(&cfg.model, &m, err, sizeof err) == 0, "modal build")) return;
    /* Cubic Hermite elements are exact for a static tip load: k = 3 E I / L^3 (uniform). */
    double I = b->width_m[0] * pow(b->height_m[0], 3) / 12.0;
    check_rel(m.static_stiffness_n_m, 3 * b->youngs_modulus_pa * I / pow(b->length_m, 3), 1e-9,
              "static tip stiffness = 3EI/L^3");
    /* A static base displacement moves the whole beam rigidly: tip follows 1:1, slope 0. */
    double tip = 0, rot = m.rot_base;
    for (int i = 0; i < m.n; i++) {
        double q = -m.base_k[i] / (m.omega_rad_s[i] * m.omega_rad_s[i]);
        tip += m.tip[i] * q;
        rot += m.rot[i] * q;
    }
    check_rel(tip, 1.0, 1e-9, "quasi-static tip / base displacement = 1");
    check_abs(rot, 0.0, 1e-6, "quasi-static tip rotation per metre of base = 0 rad/m");
    /* Tip slope of a static tip load on a cantilever: theta = 3 x / (2 L) (beam theory). */
    double x = 0, th = 0;
    for (int i = 0; i < m.n; i++) {
        double q = m.tip[i] / (m.omega_rad_s[i] * m.omega_rad_s[i]);
        x += m.tip[i] * q;
        th += m.rot[i] * q;
    }
    check_rel(th / x, 1.5 / b->length_m, 1e-9, "static tip slope / deflection = 3/(2L)");
    /* Uniform element: the quadrature reproduces eq. (2.15) exactly. */
    double me[16], ke[16], L = 1e-5, E = 170e9, rho = 2332, W = 28e-6, H = 3e-6;
    afm_fem_element(E, rho, L, W, W, H, H, me, ke);
    double mc = rho * W * H * L / 420, kc = E * W * H * H * H / 12 / (L * L * L);
    check_rel(me[0], 156 * mc, 1e-12, "uniform element m11 = 156 rho A Le / 420");
    check_rel(me[1], 22 * L * mc, 1e-12, "uniform element m12 = 22 Le rho A Le / 420");
    check_rel(me[3], -13 * L * mc, 1e-12, "uniform element m14 = -13 Le rho A Le / 420");
    check_rel(ke[0], 12 * kc, 1e-12, "uniform element k11 = 12 EI / Le^3");
    check_rel(ke[5], 4 * L * L * kc, 1e-12, "uniform element k22 = 4 Le^2 EI / Le^3");
    check_rel(ke[7], 2 * L * L * kc, 1e-12, "uniform element k24 = 2 Le^2 EI / Le^3");
    /* Lumped model: f0 and k as configured. */
    cfg = load("config/thesis-1dof.conf");
    if (check_true(afm_model_build(&cfg.model, &m, err, sizeof err) == 0, "1-DOF build")) {
        check_rel(m.omega_rad_s[0], 6.283185307179586 * cfg.model.lumped.resonance_hz, 1e-12,
                  "1-DOF w0");
        check_rel(m.static_stiffness_n_m, 40.0, 1e-12, "1-DOF k (Table C.1)");
    }
}

int main(void) {
    table_3_1_and_3_2();
    table_2_1();
    appendix_e_2();
    section_4_frequencies();
    tapered_design_ratios();
    analytic();
    return check_done();
}
