/* SPDX-License-Identifier: MIT */
/* afm_cont_model.h -- what a continuation varies: the named parameters (drive frequency fe,
 * separation Z, drive amplitude Ae, or a live what-if parameter of afm_cmd.h's table) and
 * the model instance (modal form, tip forces, drive) at given values of them.
 *
 * Layer analysis/ (6, above the runner) (offline; on top of the runner layer's parameter table,
 * afm_cmd). A periodic orbit of a continuation is driven by tone 0 alone: x_dit = Ae sin(2 pi fe t)
 * (its phase origin is the orbit's start, drive phase 0); other tones are rejected.
 *
 * Parameters (names as `afmtwin continue --param` takes them):
 *   fe   tone 0 frequency (Hz), AFM_LIM_FREQUENCY_MIN_HZ .. sample rate / 2
 *   z    separation Z (m), 0 .. AFM_LIM_SEPARATION_MAX_M (= drive.separation_m)
 *   ae   tone 0 amplitude (m), 0 .. AFM_LIM_TONE_AMPLITUDE_MAX_M
 *   any name of the live parameter table whose effect is FORCE, DAMPING or SEPARATION, in
 *   its unit and range (e.g. forces.vdw_contact.hamaker_j, model.quality_factor[0]).
 * Geometry names (beam, lumped) are rejected: they rebuild the modal basis, so the modal
 * state of one value is not a state of the next.
 *
 * Building an instance copies the config, applies the values (afm_param_apply checks
 * ranges and the config's validity) and recomputes the force constants (afm_force_init);
 * damping is set on a copy of the modal form built once. No simulator is made. */
#ifndef AFM_CONT_MODEL_H
#define AFM_CONT_MODEL_H

#include "config/afm_config.h"
#include "forces/afm_force.h"
#include "beam/afm_model.h"

typedef enum { AFM_CONT_FE = 0, AFM_CONT_Z, AFM_CONT_AE, AFM_CONT_NAMED } afm_cont_param_kind;

typedef struct {
    afm_cont_param_kind kind;
    int entry, index; /* afm_param_table() entry and index (AFM_CONT_NAMED) */
    char name[80];    /* as given: "fe", "z", "ae" or the table name */
    char unit[16];    /* "Hz", "m", or the table's unit */
} afm_cont_param;

/* One model instance: everything the vector field of afm_cont_flow needs. */
typedef struct {
    afm_modal m;
    afm_force_params f;
    double fe_hz; /* tone 0 frequency */
    double ae_m;  /* tone 0 amplitude */
    double z_m;   /* separation */
} afm_cont_inst;

/* The base of every instance: the config (tone 0 only), its modal form built once. */
typedef struct {
    afm_config cfg;
    afm_modal m;
} afm_cont_base;

/* Load-time checks and the modal build. 0, or -1 with err (more than one tone, a model that
 * does not build, forces that do not initialise). */
int afm_cont_base_init(afm_cont_base *b, const afm_config *cfg, char *err, size_t errlen);

/* Resolve a parameter name against the base's config. 0 or -1 with err (unknown name, a
 * geometry parameter, a term the config has switched off). */
int afm_cont_param_parse(const afm_cont_base *b, const char *name, afm_cont_param *p, char *err,
                         size_t errlen);

/* The parameter's value in the base config. */
double afm_cont_param_value(const afm_cont_base *b, const afm_cont_param *p);

/* The instance with parameters ps[0..np) set to vals[0..np) (np 0..2). 0, or -1 with err
 * (a value out of the parameter's range or making the config invalid). */
int afm_cont_inst_at(const afm_cont_base *b, const afm_cont_param *ps, const double *vals, int np,
                     afm_cont_inst *out, char *err, size_t errlen);

/* Contact line x_c = (a0 - Z) / cos(alpha) of an instance, -HUGE_VAL when no force term has
 * one (afm_force_contact_x). */
double afm_cont_inst_contact_x(const afm_cont_inst *in);

#endif
