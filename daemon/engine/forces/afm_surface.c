/* SPDX-License-Identifier: MIT */
/* afm_surface.c -- the sample's height map and material regions (contract in afm_surface.h):
 * analytic features summed, plus a bicubic height image read from PGM or a table. */
#include "forces/afm_surface.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SURF_PI 3.14159265358979323846
#define SURF_MAX_IMAGE_PIXELS (1L << 24) /* 4096 x 4096 */

struct afm_surface {
    afm_cfg_sample cfg;
    double tip_radius_m;
    double cos_a[AFM_MAX_FEATURES], sin_a[AFM_MAX_FEATURES]; /* direction u of each feature */
    int w, h;                                                /* image size (0: no image) */
    double *img;                                             /* heights (m), row-major */
};

/* The C1 ramp from 0 to 1 over [-e/2, e/2] (3 t^2 - 2 t^3). */
static double ramp(double u, double e) {
    double t = u / e + 0.5;
    if (t <= 0.0) return 0.0;
    if (t >= 1.0) return 1.0;
    return t * t * (3.0 - 2.0 * t);
}

/* Smooth maximum of a and b over a width w (C-infinity; max(a, b) + w^2 / (4 |a - b|) far
 * from a = b, where it is w / 2 above). */
static double smax(double a, double b, double w) {
    double d = a - b;
    return 0.5 * (a + b + sqrt(d * d + w * w));
}

/* The grating's phase in [0, pitch) of position u. */
static double grating_phase(const afm_cfg_feature *f, double u) {
    double p = fmod(u - f->position_m, f->pitch_m);
    return p < 0.0 ? p + f->pitch_m : p;
}

/* A particle on the plane as the apex of a tip of radius R traces it: the sphere dilated by
 * R, sqrt((r + R)^2 - rho^2) + r - R (R taken at least r, so that its rim lies on the plane),
 * continued linearly beyond the rim and joined to the plane by a smooth maximum. */
static double sphere_height(const afm_cfg_feature *f, double R, double x, double y) {
    double r = f->radius_m, Re = R > r ? R : r, rr = r + Re;
    double rho = hypot(x - f->x_m, y - f->y_m);
    double top = rho < rr ? sqrt(rr * rr - rho * rho) + r - Re : (r - Re) - (rho - rr);
    return smax(0.0, top, f->edge_m);
}

static double feature_height(const afm_surface *s, int i, double x, double y) {
    const afm_cfg_feature *f = &s->cfg.features[i];
    double u = x * s->cos_a[i] + y * s->sin_a[i];
    switch (f->kind) {
    case AFM_FEATURE_TILT:
        return f->slope_x * x + f->slope_y * y;
    case AFM_FEATURE_STEP:
        return f->height_m * ramp(u - f->position_m, f->edge_m);
    case AFM_FEATURE_GRATING: {
        double ph = grating_phase(f, u), d = f->duty * f->pitch_m;
        return f->height_m *
               (ramp(ph, f->edge_m) - ramp(ph - d, f->edge_m) + ramp(ph - f->pitch_m, f->edge_m));
    }
    case AFM_FEATURE_SPHERE:
        return sphere_height(f, s->tip_radius_m, x, y);
    }
    return 0.0;
}

/* Is (x, y) on the feature's upper part (its material's region)? */
static int feature_holds(const afm_surface *s, int i, double x, double y) {
    const afm_cfg_feature *f = &s->cfg.features[i];
    double u = x * s->cos_a[i] + y * s->sin_a[i];
    switch (f->kind) {
    case AFM_FEATURE_TILT:
        return 1;
    case AFM_FEATURE_STEP:
        return u > f->position_m;
    case AFM_FEATURE_GRATING:
        return grating_phase(f, u) < f->duty * f->pitch_m;
    case AFM_FEATURE_SPHERE:
        return hypot(x - f->x_m, y - f->y_m) < f->radius_m;
    }
    return 0;
}

/* ---- the height image ------------------------------------------------------------------ */

/* The image pixel (i, j), clamped to the image (its edge values extend outwards). */
static double pix(const afm_surface *s, long i, long j) {
    i = i < 0 ? 0 : i >= s->w ? s->w - 1 : i;
    j = j < 0 ? 0 : j >= s->h ? s->h - 1 : j;
    return s->img[j * s->w + i];
}

/* Catmull-Rom weights at fraction t of the interval between p1 and p2 (C1, exact on
 * quadratics' samples at the nodes). */
static void cr_weights(double t, double w[4]) {
    double t2 = t * t, t3 = t2 * t;
    w[0] = 0.5 * (-t3 + 2.0 * t2 - t);
    w[1] = 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0);
    w[2] = 0.5 * (-3.0 * t3 + 4.0 * t2 + t);
    w[3] = 0.5 * (t3 - t2);
}

static double image_height(const afm_surface *s, double x, double y) {
    double gx = (x - s->cfg.image_x0_m) / s->cfg.image_pixel_m;
    double gy = (y - s->cfg.image_y0_m) / s->cfg.image_pixel_m;
    if (!(fabs(gx) < 1e15 && fabs(gy) < 1e15)) return pix(s, 0, 0); /* far off: the edge */
    double fx = floor(gx), fy = floor(gy), wx[4], wy[4];
    cr_weights(gx - fx, wx);
    cr_weights(gy - fy, wy);
    long i0 = (long)fx - 1, j0 = (long)fy - 1;
    double z = 0.0;
    for (int b = 0; b < 4; b++) {
        double row = 0.0;
        for (int a = 0; a < 4; a++)
            row += wx[a] * pix(s, i0 + a, j0 + b);
        z += wy[b] * row;
    }
    return z;
}

/* Next whitespace-separated token of f (PGM header comments skipped); 0 at the end. */
static int next_token(FILE *f, char *buf, size_t len) {
    int c;
    size_t n = 0;
    do {
        c = fgetc(f);
        if (c == '#')
            while (c != '\n' && c != EOF)
                c = fgetc(f);
    } while (c != EOF && isspace(c));
    while (c != EOF && !isspace(c) && n + 1 < len) {
        buf[n++] = (char)c;
        c = fgetc(f);
    }
    buf[n] = '\0';
    return n > 0;
}

/* A decimal integer in [lo, hi]; -1 otherwise. */
static int parse_long(const char *t, long lo, long hi, long *v) {
    char *end;
    errno = 0;
    long x = strtol(t, &end, 10);
    if (errno || end == t || *end || x < lo || x > hi) return -1;
    *v = x;
    return 0;
}

/* PGM, P2 (text) or P5 (binary, 8 or 16 bit big-endian), into s->img (grey levels). */
static int read_pgm(afm_surface *s, FILE *f, int binary, char *err, size_t errlen) {
    char t[64];
    long w, h, maxval;
    if (!next_token(f, t, sizeof t) || parse_long(t, 1, 1L << 16, &w) ||
        !next_token(f, t, sizeof t) || parse_long(t, 1, 1L << 16, &h) ||
        !next_token(f, t, sizeof t) || parse_long(t, 1, 65535, &maxval) ||
        w * h > SURF_MAX_IMAGE_PIXELS) {
        snprintf(err, errlen,
                 "a bad PGM header (width, height, maxval 1..65535; at most %ld "
                 "pixels)",
                 SURF_MAX_IMAGE_PIXELS);
        return -1;
    }
    s->img = malloc((size_t)(w * h) * sizeof *s->img);
    if (!s->img) {
        snprintf(err, errlen, "out of memory for %ld x %ld pixels", w, h);
        return -1;
    }
    s->w = (int)w;
    s->h = (int)h;
    for (long k = 0; k < w * h; k++) {
        long v;
        if (binary) {
            int b0 = fgetc(f), b1 = maxval > 255 ? fgetc(f) : 0;
            if (b0 == EOF || b1 == EOF) {
                snprintf(err, errlen, "the PGM ends after %ld of %ld pixels", k, w * h);
                return -1;
            }
            v = maxval > 255 ? (b0 << 8 | b1) : b0;
        } else if (!next_token(f, t, sizeof t) || parse_long(t, 0, 65535, &v) != 0) {
            snprintf(err, errlen, "pixel %ld of %ld: '%s' is not a grey level 0..%ld", k, w * h, t,
                     maxval);
            return -1;
        }
        if (v > maxval) {
            snprintf(err, errlen, "pixel %ld: %ld above maxval %ld", k, v, maxval);
            return -1;
        }
        s->img[k] = (double)v;
    }
    return 0;
}

/* A whitespace table: one image row per line, the same number of numbers in each. */
static int read_table(afm_surface *s, FILE *f, char *err, size_t errlen) {
    char line[65536];
    long cap = 0, n = 0;
    int w = 0, h = 0;
    while (fgets(line, sizeof line, f)) {
        if (!strchr(line, '\n') && !feof(f)) {
            snprintf(err, errlen, "row %d: longer than %zu characters", h + 1, sizeof line - 1);
            return -1;
        }
        char *p = line, *end;
        int cols = 0;
        for (;;) {
            while (isspace((unsigned char)*p))
                p++;
            if (!*p || *p == '#') break;
            errno = 0;
            double v = strtod(p, &end);
            if (end == p || errno || !isfinite(v)) {
                snprintf(err, errlen, "row %d, column %d: not a finite number", h + 1, cols + 1);
                return -1;
            }
            if (n == cap) {
                cap = cap ? 2 * cap : 4096;
                if (cap > SURF_MAX_IMAGE_PIXELS) {
                    snprintf(err, errlen, "more than %ld values", SURF_MAX_IMAGE_PIXELS);
                    return -1;
                }
                double *g = realloc(s->img, (size_t)cap * sizeof *g);
                if (!g) {
                    snprintf(err, errlen, "out of memory");
                    return -1;
                }
                s->img = g;
            }
            s->img[n++] = v;
            cols++;
            p = end;
        }
        if (cols == 0) continue;
        if (w && cols != w) {
            snprintf(err, errlen, "row %d has %d values, the first row %d", h + 1, cols, w);
            return -1;
        }
        w = cols;
        h++;
    }
    if (!w) {
        snprintf(err, errlen, "no numbers in the table");
        return -1;
    }
    s->w = w;
    s->h = h;
    return 0;
}

static int load_image(afm_surface *s, char *err, size_t errlen) {
    const char *path = s->cfg.image_file;
    char why[256];
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errlen, "sample.image.file: cannot open %s: %s", path, strerror(errno));
        return -1;
    }
    char magic[3] = {0};
    int rc;
    if (fread(magic, 1, 2, f) == 2 && magic[0] == 'P' && (magic[1] == '2' || magic[1] == '5')) {
        rc = read_pgm(s, f, magic[1] == '5', why, sizeof why);
    } else {
        rewind(f);
        rc = read_table(s, f, why, sizeof why);
    }
    fclose(f);
    if (rc) {
        snprintf(err, errlen, "sample.image.file: %s: %s", path, why);
        return -1;
    }
    for (long k = 0; k < (long)s->w * s->h; k++)
        s->img[k] *= s->cfg.image_height_per_level_m;
    return 0;
}

/* ---- the contract ---------------------------------------------------------------------- */

int afm_surface_create(afm_surface **out, const afm_cfg_sample *cfg, double tip_radius_m, char *err,
                       size_t errlen) {
    *out = NULL;
    afm_surface *s = calloc(1, sizeof *s);
    if (!s) {
        snprintf(err, errlen, "out of memory");
        return -1;
    }
    s->cfg = *cfg;
    if (!cfg->enabled) s->cfg.n_features = 0, s->cfg.image_file[0] = '\0';
    s->tip_radius_m = tip_radius_m;
    for (int i = 0; i < s->cfg.n_features; i++) {
        double a = s->cfg.features[i].angle_deg * (SURF_PI / 180.0);
        s->cos_a[i] = cos(a);
        s->sin_a[i] = sin(a);
    }
    if (s->cfg.image_file[0] && load_image(s, err, errlen)) {
        afm_surface_destroy(&s);
        return -1;
    }
    *out = s;
    return 0;
}

void afm_surface_destroy(afm_surface **s) {
    if (!s || !*s) return;
    free((*s)->img);
    free(*s);
    *s = NULL;
}

double afm_surface_height(const afm_surface *s, double x_m, double y_m) {
    double z = s->img ? image_height(s, x_m, y_m) : 0.0;
    for (int i = 0; i < s->cfg.n_features; i++)
        z += feature_height(s, i, x_m, y_m);
    return z;
}

int afm_surface_material(const afm_surface *s, double x_m, double y_m) {
    int m = 0;
    for (int i = 0; i < s->cfg.n_features; i++)
        if (s->cfg.features[i].material && feature_holds(s, i, x_m, y_m))
            m = s->cfg.features[i].material;
    return m;
}

void afm_surface_material_forces(const afm_cfg_sample *cfg, const afm_cfg_forces *base, int m,
                                 afm_cfg_forces *out) {
    *out = *base;
    /* The terms on are those of any material (the integrator's set is fixed at create): a
     * viscoelastic material turns the term on everywhere, at eta 0 where none is given. */
    if (cfg->enabled && !base->viscoelastic)
        for (int i = 0; i < cfg->n_materials; i++)
            if (cfg->materials[i].eta_pa_s > 0) {
                out->viscoelastic = true;
                out->eta_pa_s = 0.0;
            }
    if (!cfg->enabled || m < 1 || m > cfg->n_materials) return;
    const afm_cfg_material *mt = &cfg->materials[m - 1];
    if (!isnan(mt->reduced_modulus_pa)) out->reduced_modulus_pa = mt->reduced_modulus_pa;
    if (!isnan(mt->hamaker_j)) out->hamaker_j = mt->hamaker_j;
    if (!isnan(mt->a0_m)) out->a0_m = mt->a0_m;
    if (!isnan(mt->eta_pa_s)) out->eta_pa_s = mt->eta_pa_s;
}
