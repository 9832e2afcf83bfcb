/* SPDX-License-Identifier: MIT */
/* fixtures.h -- hand-built models shared by the integrator tests (no config files). */
#ifndef AFM_TEST_FIXTURES_H
#define AFM_TEST_FIXTURES_H

#include "forces/afm_force.h"

#include <complex.h>
#include "beam/afm_model.h"

/* The 4-mode model of ../shared/notes/numerics.md: 370 kHz, 2.27, 6.4, 14 MHz, Q 427, 291,
 * 5, 5, static tip stiffness k_s = 40 N/m split 97 / 2.5 / 0.4 / 0.1 % in compliance
 * (sum tip_i^2 / w_i^2 = 1/k_s). base_k_i = -k_s tip_i makes a static base offset move the
 * tip rigidly (sum tip_i (-base_k_i) / w_i^2 = 1); base_m_i is an arbitrary inertial
 * coupling so that both drive terms are exercised; rot_i = 1.5e4 tip_i (any finite value).
 * nmodes (1..4) keeps the first modes (nmodes = 1: mode 1 with all the compliance).
 * q1 > 0 overrides Q of mode 1; xi_hi > 0 overrides xi of modes 3 and 4. */
afm_modal fixture_model(int nmodes, double q1, double xi_hi);

/* afm_model_mode_response / afm_model_tip_response as complex numbers. */
double complex fixture_mode_h(const afm_modal *m, int i, double w_rad_s);
double complex fixture_tip_gain(const afm_modal *m, double w_rad_s);

/* All tip forces off (the force module then returns exactly 0). */
afm_force_params fixture_no_forces(void);

#endif
