/* SPDX-License-Identifier: MIT */
/* afm_config_read.h -- what the config loader (afm_config.c, afm_config_opt.c) reads settings with:
 * typed members of a libconfig group, each failure written as "FILE:LINE: key 'PATH': reason" into
 * the loader's err. Internal to the config layer: not part of afm_config.h. */
#ifndef AFM_CONFIG_READ_H
#define AFM_CONFIG_READ_H

#include "config/afm_config_impl.h"

#include <libconfig.h>
#include <stdbool.h>
#include <stddef.h>

typedef struct {
    const char *path; /* file name for messages */
    char *err;
    size_t errlen;
} afm_cfgr;

/* Config path of a setting: "model.beam.width_m[1]". */
void afm_cfgr_path(const config_setting_t *s, char *buf, size_t len);
/* The setting's line (1 when unknown) and file (L's path when unknown). */
int afm_cfgr_line(const config_setting_t *s);
const char *afm_cfgr_file(const afm_cfgr *L, const config_setting_t *s);
/* "FILE:LINE: key 'PATH[.name]': reason". s is the setting at fault, or for a missing key
 * its parent group (name then gives the key). Always returns -1. */
int afm_cfgr_fail(const afm_cfgr *L, const config_setting_t *s, const char *name, const char *fmt,
                  ...) __attribute__((format(printf, 4, 5)));
/* "a group", "an integer", ...: the setting's type as a message says it. */
const char *afm_cfgr_type(const config_setting_t *s);
/* Every member of g must be in allowed (NULL-terminated). */
int afm_cfgr_only_keys(const afm_cfgr *L, const config_setting_t *g, const char *const *allowed);
/* A member that may be absent (*out = NULL), or must be present (required). */
int afm_cfgr_member(const afm_cfgr *L, const config_setting_t *g, const char *name, bool required,
                    config_setting_t **out);
/* s as a finite number (an integer or a float). */
int afm_cfgr_as_num(const afm_cfgr *L, const config_setting_t *s, double *out);
/* Number key; leaves *out alone when absent and optional (present: whether it was given). */
int afm_cfgr_num(const afm_cfgr *L, const config_setting_t *g, const char *name, bool required,
                 double *out, bool *present);
/* Any libconfig integer (int or int64) as long long, or as int (range-checked). */
int afm_cfgr_as_integer(const afm_cfgr *L, const config_setting_t *s, long long *v);
int afm_cfgr_as_int(const afm_cfgr *L, const config_setting_t *s, int *out);
/* Integer and boolean keys; *out alone when absent and optional. */
int afm_cfgr_int(const afm_cfgr *L, const config_setting_t *g, const char *name, bool required,
                 int *out);
int afm_cfgr_bool(const afm_cfgr *L, const config_setting_t *g, const char *name, bool *out);
/* String key that must be one of names[] (NULL-terminated); *out = its index. */
int afm_cfgr_choice(const afm_cfgr *L, const config_setting_t *g, const char *name, bool required,
                    const char *const *names, int *out);
/* A member that must be a group { ... } when present. */
int afm_cfgr_group(const afm_cfgr *L, const config_setting_t *g, const char *name, bool required,
                   config_setting_t **out);
/* An optional group with "enabled": *out the group or NULL; *enabled false when it is
 * absent, else its "enabled" key, true when not given. */
int afm_cfgr_feature(const afm_cfgr *L, const config_setting_t *g, const char *name,
                     config_setting_t **out, bool *enabled);
/* Numbers given as [a, b, ...] or (a, b, ...), 1..max of them. */
int afm_cfgr_vector(const afm_cfgr *L, const config_setting_t *s, double *v, int max, int *n);
/* A list ( {...}, ... ) of at most max groups, each read by one() into items[i] (size bytes
 * apart). */
int afm_cfgr_list(const afm_cfgr *L, const config_setting_t *g, const char *name, int max, int *n,
                  int (*one)(const afm_cfgr *, const config_setting_t *, void *), void *items,
                  size_t size);
/* Setting for a path written by afm_config_check_all ("drive.tones[1].frequency_hz"); the
 * deepest existing ancestor when the key itself is absent (a default value). */
const config_setting_t *afm_cfgr_resolve(const config_setting_t *root, const char *path);

#endif
