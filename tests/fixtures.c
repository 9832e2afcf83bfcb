/* SPDX-License-Identifier: MIT */
/* fixtures.c -- see fixtures.h. */
#include "fixtures.h"

#include <math.h>
#include <string.h>

afm_modal fixture_model(int nmodes, double q1, double xi_hi) {
    static const double f_hz[4] = {370e3, 2.27e6, 6.4e6, 14e6};
    static const double qf[4] = {427, 291, 5, 5};
    static const double share[4] = {0.97, 0.025, 0.004, 0.001};
    const double ks = 40.0, two_pi = 6.283185307179586476925286766559;
    afm_modal m;
    memset(&m, 0, sizeof m);
    m.n = nmodes;
    for (int i = 0; i < nmodes; i++) {
        double w = two_pi * f_hz[i];
        m.omega_rad_s[i] = w;
        m.xi[i] = 0.5 / (i == 0 && q1 > 0 ? q1 : qf[i]);
        if (i >= 2 && xi_hi > 0) m.xi[i] = xi_hi;
        m.tip[i] = (i % 2 ? -1.0 : 1.0) * w * sqrt((nmodes == 1 ? 1.0 : share[i]) / ks);
        m.rot[i] = 1.5e4 * m.tip[i];
        m.base_k[i] = -ks * m.tip[i];
        m.base_m[i] = 0.05 / m.tip[i];
    }
    m.static_stiffness_n_m = ks;
    return m;
}

afm_force_params fixture_no_forces(void) {
    afm_force_params f;
    memset(&f, 0, sizeof f);
    f.cos_alpha = 1.0;
    f.squeeze = AFM_SQUEEZE_NONE;
    return f;
}

double complex fixture_mode_h(const afm_modal *m, int i, double w_rad_s) {
    double re, im;
    afm_model_mode_response(m, i, w_rad_s, &re, &im);
    return re + I * im;
}

double complex fixture_tip_gain(const afm_modal *m, double w_rad_s) {
    double re, im;
    afm_model_tip_response(m, w_rad_s, &re, &im);
    return re + I * im;
}
