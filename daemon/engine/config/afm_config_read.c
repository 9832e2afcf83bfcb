/* SPDX-License-Identifier: MIT */
/* afm_config_read.c -- the config loader's reading primitives on libconfig settings: typed
 * members (number, integer, boolean, choice, group, vector, list), the known-keys check,
 * and messages "FILE:LINE: key 'PATH': reason" (contract in afm_config_read.h). The schema
 * (which groups and keys exist) is afm_config.c's and afm_config_opt.c's; the range checks
 * afm_config_check.c's. */
#include "config/afm_config_read.h"

#include "config/afm_err.h"

#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define KEY_LEN AFM_CONFIG_KEY_LEN

/* Config path of a setting: "model.beam.width_m[1]". */
void afm_cfgr_path(const config_setting_t *s, char *buf, size_t len) {
    const config_setting_t *parent = config_setting_parent(s);
    if (!parent || config_setting_is_root(s)) {
        buf[0] = '\0';
        return;
    }
    afm_cfgr_path(parent, buf, len);
    size_t n = strlen(buf);
    const char *name = config_setting_name(s);
    if (name)
        snprintf(buf + n, len - n, "%s%s", n ? "." : "", name);
    else
        snprintf(buf + n, len - n, "[%d]", config_setting_index(s));
}

int afm_cfgr_line(const config_setting_t *s) {
    int line = s ? (int)config_setting_source_line(s) : 0;
    return line > 0 ? line : 1;
}

const char *afm_cfgr_file(const afm_cfgr *L, const config_setting_t *s) {
    const char *f = s ? config_setting_source_file(s) : NULL;
    return f ? f : L->path;
}

/* "FILE:LINE: key 'PATH[.name]': reason". s is the setting at fault, or for a missing key
 * its parent group (name then gives the key). Always returns -1. */
int afm_cfgr_fail(const afm_cfgr *L, const config_setting_t *s, const char *name, const char *fmt,
                  ...) {
    char key[KEY_LEN], why[AFM_ERR_LEN];
    afm_cfgr_path(s, key, sizeof key);
    if (name) {
        size_t n = strlen(key);
        snprintf(key + n, sizeof key - n, "%s%s", n ? "." : "", name);
    }
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, sizeof why, fmt, ap);
    va_end(ap);
    if (L->err && L->errlen)
        snprintf(L->err, L->errlen, "%s:%d: key '%s': %s", afm_cfgr_file(L, s), afm_cfgr_line(s),
                 key, why);
    return -1;
}

const char *afm_cfgr_type(const config_setting_t *s) {
    switch (config_setting_type(s)) {
    case CONFIG_TYPE_GROUP:
        return "a group";
    case CONFIG_TYPE_INT:
    case CONFIG_TYPE_INT64:
        return "an integer";
    case CONFIG_TYPE_FLOAT:
        return "a floating-point number";
    case CONFIG_TYPE_STRING:
        return "a string";
    case CONFIG_TYPE_BOOL:
        return "a boolean";
    case CONFIG_TYPE_ARRAY:
        return "an array";
    case CONFIG_TYPE_LIST:
        return "a list";
    default:
        return "an unknown type";
    }
}

/* Every member of g must be in allowed (NULL-terminated). */
int afm_cfgr_only_keys(const afm_cfgr *L, const config_setting_t *g, const char *const *allowed) {
    for (int i = 0; i < config_setting_length(g); i++) {
        const config_setting_t *m = config_setting_get_elem(g, (unsigned)i);
        const char *name = config_setting_name(m);
        bool ok = false;
        for (const char *const *a = allowed; *a && !ok; a++)
            ok = strcmp(*a, name) == 0;
        if (!ok) {
            char list[256] = "";
            for (const char *const *a = allowed; *a; a++) {
                size_t n = strlen(list);
                snprintf(list + n, sizeof list - n, "%s%s", n ? ", " : "", *a);
            }
            return afm_cfgr_fail(L, m, NULL, "unknown key (allowed here: %s)", list);
        }
    }
    return 0;
}

/* A member that may be absent. *out = NULL when absent. */
int afm_cfgr_member(const afm_cfgr *L, const config_setting_t *g, const char *name, bool required,
                    config_setting_t **out) {
    *out = config_setting_get_member(g, name);
    if (!*out && required) return afm_cfgr_fail(L, g, name, "missing required key");
    return 0;
}

int afm_cfgr_as_num(const afm_cfgr *L, const config_setting_t *s, double *out) {
    switch (config_setting_type(s)) {
    case CONFIG_TYPE_INT:
        *out = config_setting_get_int(s);
        break;
    case CONFIG_TYPE_INT64:
        *out = (double)config_setting_get_int64(s);
        break;
    case CONFIG_TYPE_FLOAT:
        *out = config_setting_get_float(s);
        break;
    default:
        return afm_cfgr_fail(L, s, NULL, "expected a number, got %s", afm_cfgr_type(s));
    }
    if (!isfinite(*out)) return afm_cfgr_fail(L, s, NULL, "not a finite number");
    return 0;
}

/* Number key; leaves *out alone when absent and optional. */
int afm_cfgr_num(const afm_cfgr *L, const config_setting_t *g, const char *name, bool required,
                 double *out, bool *present) {
    config_setting_t *s;
    if (afm_cfgr_member(L, g, name, required, &s)) return -1;
    if (present) *present = s != NULL;
    return s ? afm_cfgr_as_num(L, s, out) : 0;
}

/* Any libconfig integer (int or int64) as long long; -1 with a message otherwise. */
int afm_cfgr_as_integer(const afm_cfgr *L, const config_setting_t *s, long long *v) {
    switch (config_setting_type(s)) {
    case CONFIG_TYPE_INT:
        *v = config_setting_get_int(s);
        return 0;
    case CONFIG_TYPE_INT64:
        *v = config_setting_get_int64(s);
        return 0;
    default:
        return afm_cfgr_fail(L, s, NULL, "expected an integer, got %s", afm_cfgr_type(s));
    }
}

int afm_cfgr_as_int(const afm_cfgr *L, const config_setting_t *s, int *out) {
    long long v = 0;
    if (afm_cfgr_as_integer(L, s, &v)) return -1;
    if (v < INT_MIN || v > INT_MAX) return afm_cfgr_fail(L, s, NULL, "integer out of range");
    *out = (int)v;
    return 0;
}

int afm_cfgr_int(const afm_cfgr *L, const config_setting_t *g, const char *name, bool required,
                 int *out) {
    config_setting_t *s;
    if (afm_cfgr_member(L, g, name, required, &s)) return -1;
    return s ? afm_cfgr_as_int(L, s, out) : 0;
}

int afm_cfgr_bool(const afm_cfgr *L, const config_setting_t *g, const char *name, bool *out) {
    config_setting_t *s;
    if (afm_cfgr_member(L, g, name, false, &s)) return -1;
    if (!s) return 0;
    if (config_setting_type(s) != CONFIG_TYPE_BOOL)
        return afm_cfgr_fail(L, s, NULL, "expected true or false, got %s", afm_cfgr_type(s));
    *out = config_setting_get_bool(s);
    return 0;
}

/* String key that must be one of names[]; *out = index. */
int afm_cfgr_choice(const afm_cfgr *L, const config_setting_t *g, const char *name, bool required,
                    const char *const *names, int *out) {
    config_setting_t *s;
    if (afm_cfgr_member(L, g, name, required, &s)) return -1;
    if (!s) return 0;
    char list[128] = "";
    for (int i = 0; names[i]; i++) {
        size_t n = strlen(list);
        snprintf(list + n, sizeof list - n, "%s\"%s\"", i ? ", " : "", names[i]);
    }
    if (config_setting_type(s) != CONFIG_TYPE_STRING)
        return afm_cfgr_fail(L, s, NULL, "expected one of %s, got %s", list, afm_cfgr_type(s));
    const char *v = config_setting_get_string(s);
    for (int i = 0; names[i]; i++)
        if (strcmp(v, names[i]) == 0) {
            *out = i;
            return 0;
        }
    return afm_cfgr_fail(L, s, NULL, "\"%s\" is not one of %s", v, list);
}

int afm_cfgr_group(const afm_cfgr *L, const config_setting_t *g, const char *name, bool required,
                   config_setting_t **out) {
    *out = config_setting_get_member(g, name);
    if (!*out && required) return afm_cfgr_fail(L, g, name, "missing required group");
    if (*out && config_setting_type(*out) != CONFIG_TYPE_GROUP)
        return afm_cfgr_fail(L, *out, NULL, "expected a group { ... }, got %s",
                             afm_cfgr_type(*out));
    return 0;
}

/* An optional group with "enabled" (default true when the group is present). */
int afm_cfgr_feature(const afm_cfgr *L, const config_setting_t *g, const char *name,
                     config_setting_t **out, bool *enabled) {
    *enabled = false;
    if (afm_cfgr_group(L, g, name, false, out)) return -1;
    if (!*out) return 0;
    *enabled = true;
    return afm_cfgr_bool(L, *out, "enabled", enabled);
}

/* Numbers given as [a, b, ...] or (a, b, ...), 1..max of them. */
int afm_cfgr_vector(const afm_cfgr *L, const config_setting_t *s, double *v, int max, int *n) {
    int t = config_setting_type(s);
    if (t != CONFIG_TYPE_ARRAY && t != CONFIG_TYPE_LIST)
        return afm_cfgr_fail(L, s, NULL, "expected an array [ ... ], got %s", afm_cfgr_type(s));
    int len = config_setting_length(s);
    if (len < 1 || len > max)
        return afm_cfgr_fail(L, s, NULL, "needs 1 to %d values (got %d)", max, len);
    for (int i = 0; i < len; i++)
        if (afm_cfgr_as_num(L, config_setting_get_elem(s, (unsigned)i), &v[i])) return -1;
    *n = len;
    return 0;
}

/* A list ( {...}, ... ) of at most max groups, each read by one(). */
int afm_cfgr_list(const afm_cfgr *L, const config_setting_t *g, const char *name, int max, int *n,
                  int (*one)(const afm_cfgr *, const config_setting_t *, void *), void *items,
                  size_t size) {
    config_setting_t *s;
    if (afm_cfgr_member(L, g, name, false, &s)) return -1;
    if (!s) return 0;
    if (config_setting_type(s) != CONFIG_TYPE_LIST)
        return afm_cfgr_fail(L, s, NULL, "expected a list ( { ... }, ... ), got %s",
                             afm_cfgr_type(s));
    int len = config_setting_length(s);
    if (len > max) return afm_cfgr_fail(L, s, NULL, "at most %d entries (got %d)", max, len);
    for (int i = 0; i < len; i++)
        if (one(L, config_setting_get_elem(s, (unsigned)i), (char *)items + (size_t)i * size))
            return -1;
    *n = len;
    return 0;
}

/* Setting for a path written by afm_config_check_all ("drive.tones[1].frequency_hz"); the deepest
 * existing ancestor when the key itself is absent (a default value). */
const config_setting_t *afm_cfgr_resolve(const config_setting_t *root, const char *path) {
    const config_setting_t *s = root;
    char buf[KEY_LEN];
    snprintf(buf, sizeof buf, "%s", path);
    char *save = NULL;
    for (char *tok = strtok_r(buf, ".", &save); tok; tok = strtok_r(NULL, ".", &save)) {
        char *br = strchr(tok, '[');
        int idx = -1;
        if (br) {
            idx = (int)strtol(br + 1, NULL, 10);
            *br = '\0';
        }
        const config_setting_t *next = config_setting_get_member(s, tok);
        if (!next) return s;
        s = next;
        if (idx >= 0) {
            int t = config_setting_type(s);
            if (t != CONFIG_TYPE_ARRAY && t != CONFIG_TYPE_LIST)
                return s; /* a scalar standing for both ends, e.g. width_m = 28e-6 */
            next = config_setting_get_elem(s, (unsigned)idx);
            if (!next) return s;
            s = next;
        }
    }
    return s;
}
