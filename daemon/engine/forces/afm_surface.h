/* SPDX-License-Identifier: MIT */
/* afm_surface.h -- the sample under the tip (issue 18): its height z_s(x, y) and the material
 * region at a lateral tip position, from the config's `sample` group. The tip-sample gap is
 * d = x cos(alpha) + Z - z_s(x_tip, y_tip): a caller moves the tip laterally and hands the
 * integrator the separation Z - z_s (afm_sim_set_separation) and the forces of the region
 * (afm_sim_set_forces).
 *
 * Heights are smooth (C1 at least) so that a moving tip never meets a kink the integrator
 * would have to locate: step and grating edges are cubic ramps of width edge_m, a particle is
 * its shape as the tip's apex traces it (dilated by the tip radius, joined to the plane by a
 * smooth maximum), a height image is interpolated bicubically (Catmull-Rom) between pixels.
 *
 * Layer forces/ (2) (uses config only). Allocates in create only (the image); the queries
 * allocate nothing and take a bounded time (features + one 4x4 image stencil). */
#ifndef AFM_SURFACE_H
#define AFM_SURFACE_H

#include "config/afm_config.h"

#include <stddef.h>

typedef struct afm_surface afm_surface;

/* From cfg (the sample group; a disabled group gives a flat uniform sample) and the tip
 * radius tip_radius_m (R, for the particles' traced shape). Reads the image file if any.
 * 0, or -1 with err ("sample.image.file: ..." and the like). */
int afm_surface_create(afm_surface **out, const afm_cfg_sample *cfg, double tip_radius_m, char *err,
                       size_t errlen);
void afm_surface_destroy(afm_surface **s);

/* z_s (m) at the lateral position (x_m, y_m): the sum of the features and the image. */
double afm_surface_height(const afm_surface *s, double x_m, double y_m);

/* The material region at (x_m, y_m): 0 the forces group's sample, i >= 1 the config's
 * materials[i - 1]: the region of the last feature whose upper part holds the point. */
int afm_surface_material(const afm_surface *s, double x_m, double y_m);

/* The forces group of material m (0: the base sample), with what the material changes. The
 * terms switched on are the same for every m (afm_sim_set_forces needs that): a term one
 * material turns on (the viscoelastic one) is on for all, at zero strength where not given.
 * Create the simulator with material 0's. */
void afm_surface_material_forces(const afm_cfg_sample *cfg, const afm_cfg_forces *base, int m,
                                 afm_cfg_forces *out);

#endif
