/* SPDX-License-Identifier: MIT */
/* cmd_map_plot.c -- `afmtwin plot map` (issue 31): heat maps of a map file (map_file.h) with
 * gnuplot, and every map quantity as a Gwyddion Simple Field file (gsf_write.h). Apart from
 * cmd_plot.c, which hands the kind "map" over to it, because its input is the map file and
 * its picture a grid of images, not the curves the other kinds draw. */
#include "afmtwin_cmds.h"
#include "gsf_write.h"
#include "map_file.h"
#include "opts.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const char *in, *out, *gsf, *script, *dir_word;
    int width, height;
} mplot_opts;

static void mplot_usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin plot map MAPFILE [--out FILE.png|.svg] [--gsf PREFIX]\n"
            "                        [--direction up|down] [--size WxH] [--script FILE]\n\n"
            "Heat maps of an `afmtwin map` file over its plane: peak force, amplitude, phase lag\n"
            "(of the deflection behind the drive, 90 deg free at resonance) and dissipated\n"
            "energy of one sweep direction (default up, else the one the map has), the bistable\n"
            "points (up and down differ) marked with white crosses, points that did not settle\n"
            "with black dots. A partial map (an interrupted run) shows its finished lines.\n\n"
            "options:\n"
            "  --out FILE       the picture (pngcairo; .svg: SVG)\n"
            "  --gsf PREFIX     every map quantity of every direction as a Gwyddion Simple Field\n"
            "                   file PREFIX-DIR-QUANTITY.gsf (DIR up or down; QUANTITY amplitude,\n"
            "                   phase_lag, peak_force, attractive_force, min_gap, indentation,\n"
            "                   contact_time, dissipated_energy, periodicity, settled) and\n"
            "                   PREFIX-bistable.gsf (1 bistable, 0 not; direction both); the\n"
            "                   pixels centred on the grid values, x and y real in their SI units\n"
            "                   (XYUnits is x's; when y's differs the Title says it); lines not\n"
            "                   computed yet and values that do not exist are 0\n"
            "  --direction D    which sweep direction the heat maps show\n"
            "  --size WxH       picture size in pixels (default 1200x900)\n"
            "  --script FILE    the gnuplot script as run\n"
            "Exit status 0 ok, 1 gnuplot or a file failed, 2 bad usage or bad input.\n");
}

static int parse_size(const char *v, void *dest) {
    mplot_opts *o = dest;
    int w, h;
    char c;
    if (sscanf(v, "%dx%d%c", &w, &h, &c) != 2 || w < 200 || h < 200 || w > 10000 || h > 10000)
        return -1;
    o->width = w;
    o->height = h;
    return 0;
}

static int parse_dir(const char *v, void *dest) {
    if (strcmp(v, "up") && strcmp(v, "down")) return -1;
    *(const char **)dest = v;
    return 0;
}

/* A quantity of a point, and its GSF name and unit. */
typedef struct {
    const char *name, *unit, *label;
    double scale; /* for the heat map's colour bar */
} quantity;

static const quantity quantities[] = {
    {"amplitude", "m", "amplitude A1 (nm)", 1e9},
    {"phase_lag", "deg", "phase lag (deg)", 1.0},
    {"peak_force", "N", "peak force (nN)", 1e9},
    {"attractive_force", "N", "attractive force (nN)", 1e9},
    {"min_gap", "m", "minimum gap (nm)", 1e9},
    {"indentation", "m", "indentation (nm)", 1e9},
    {"contact_time", "s", "contact time (s)", 1.0},
    {"dissipated_energy", "J", "dissipated energy (eV)", 1.0 / 1.602176634e-19},
    {"periodicity", "", "periodicity", 1.0},
    {"settled", "", "settled", 1.0},
};
#define NQ ((int)(sizeof quantities / sizeof quantities[0]))

static double qvalue(const afmt_map_point *p, int q) {
    switch (q) {
    case 0:
        return p->amplitude_m;
    case 1:
        return p->lag_deg;
    case 2:
        return p->peak_force_n;
    case 3:
        return p->attractive_n;
    case 4:
        return p->min_gap_m;
    case 5:
        return p->indentation_m;
    case 6:
        return p->contact_time_s;
    case 7:
        return p->energy_j;
    case 8:
        return p->periodicity;
    default:
        return p->settled;
    }
}

/* The GSF geometry of an axis: pixels centred on the values. */
static void gsf_axis(const afmt_map_axis *a, double *real, double *off) {
    double step = a->n > 1 ? (a->to - a->from) / (a->n - 1) : (a->from != 0 ? fabs(a->from) : 1.0);
    *real = step * a->n;
    *off = a->from - 0.5 * step;
}

static int write_gsf(const char *path, const afmt_map_data *m, const char *title, const char *zunit,
                     const float *v) {
    afmt_gsf_header h = {.xres = m->x.n, .yres = m->y.n, .z_units = zunit, .title = title};
    gsf_axis(&m->x, &h.xreal, &h.xoffset);
    gsf_axis(&m->y, &h.yreal, &h.yoffset);
    h.xy_units = afmt_map_param_unit(m->x.param);
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    int rc = afmt_gsf_write_header(f, &h) || afmt_gsf_write_values(f, v, (size_t)m->x.n * m->y.n);
    if (fclose(f) != 0) rc = -1;
    return rc ? -1 : 0;
}

static int write_all_gsf(const char *prefix, const afmt_map_data *m) {
    size_t np = (size_t)m->x.n * (size_t)m->y.n;
    float *v = malloc(np * sizeof *v);
    if (!v) return -1;
    char path[4096], title[256], ynote[96] = "";
    if (strcmp(afmt_map_param_unit(m->x.param), afmt_map_param_unit(m->y.param)))
        snprintf(ynote, sizeof ynote, "; x %s in %s, y %s in %s", afmt_map_param_name(m->x.param),
                 afmt_map_param_unit(m->x.param), afmt_map_param_name(m->y.param),
                 afmt_map_param_unit(m->y.param));
    int rc = 0;
    for (int d = 0; d < 2 && !rc; d++) {
        if (!m->pts[d]) continue;
        for (int q = 0; q < NQ && !rc; q++) {
            for (size_t i = 0; i < np; i++) {
                double x = qvalue(&m->pts[d][i], q);
                v[i] = isfinite(x) ? (float)x : 0.0f;
            }
            snprintf(path, sizeof path, "%s-%s-%s.gsf", prefix, d ? "down" : "up",
                     quantities[q].name);
            snprintf(title, sizeof title, "%s (%s sweep%s)", quantities[q].name, d ? "down" : "up",
                     ynote);
            if (write_gsf(path, m, title, quantities[q].unit, v)) rc = -1;
        }
    }
    if (!rc && m->pts[0] && m->pts[1]) {
        for (size_t i = 0; i < np; i++)
            v[i] = m->bistable[i] ? 1.0f : 0.0f;
        snprintf(path, sizeof path, "%s-bistable.gsf", prefix);
        snprintf(title, sizeof title, "bistable (up and down differ%s)", ynote);
        if (write_gsf(path, m, title, "", v)) rc = -1;
    }
    if (rc) fprintf(stderr, "afmtwin plot map: cannot write %s\n", path);
    free(v);
    return rc;
}

static double axis_scale(afmt_map_param p) {
    return p == AFMT_MAP_FE ? 1e-3 : 1e9;
}

static const char *axis_label(afmt_map_param p) {
    return p == AFMT_MAP_FE  ? "drive frequency fe (kHz)"
           : p == AFMT_MAP_Z ? "separation Z (nm)"
                             : "drive amplitude Ae (nm)";
}

static int write_script(FILE *sf, const mplot_opts *o, const afmt_map_data *m, int d) {
    const double sx = axis_scale(m->x.param), sy = axis_scale(m->y.param);
    bool svg = o->out && strlen(o->out) > 4 && !strcmp(o->out + strlen(o->out) - 4, ".svg");
    fprintf(sf, "set terminal %s size %d,%d noenhanced\nset output '%s'\n",
            svg ? "svg" : "pngcairo", o->width, o->height, o->out);
    fprintf(sf, "$map << EOD\n");
    for (int iy = 0; iy < m->lines; iy++) {
        for (int ix = 0; ix < m->x.n; ix++) {
            const afmt_map_point *p = &m->pts[d][(size_t)iy * m->x.n + ix];
            fprintf(sf, "%.10g %.10g", afmt_map_axis_value(&m->x, ix) * sx,
                    afmt_map_axis_value(&m->y, iy) * sy);
            const int show[4] = {2, 0, 1, 7};
            for (int k = 0; k < 4; k++) {
                double v = qvalue(p, show[k]) * quantities[show[k]].scale;
                fprintf(sf, isfinite(v) ? " %.10g" : " NaN", v);
            }
            fprintf(sf, " %d\n", p->settled);
        }
        fprintf(sf, "\n");
    }
    fprintf(sf, "EOD\n$bist << EOD\n");
    int nb = 0;
    for (int iy = 0; iy < m->lines; iy++)
        for (int ix = 0; ix < m->x.n; ix++)
            if (m->bistable[(size_t)iy * m->x.n + ix]) {
                fprintf(sf, "%.10g %.10g\n", afmt_map_axis_value(&m->x, ix) * sx,
                        afmt_map_axis_value(&m->y, iy) * sy);
                nb++;
            }
    if (!nb) fprintf(sf, "NaN NaN\n");
    fprintf(sf, "EOD\n");
    fprintf(sf,
            "set multiplot layout 2,2 title 'afmtwin map %s (%s sweep, %d x %d%s): x marks "
            "bistable points, dots unsettled'\n",
            m->config, d ? "down" : "up", m->x.n, m->y.n, m->lines < m->y.n ? ", partial" : "");
    fprintf(sf, "set xlabel '%s'\nset ylabel '%s'\nset palette rgb 33,13,10\n",
            axis_label(m->x.param), axis_label(m->y.param));
    const int show[4] = {2, 0, 1, 7};
    for (int k = 0; k < 4; k++) {
        fprintf(sf,
                "set title '%s'\nplot $map using 1:2:%d with image notitle, "
                "$bist using 1:2 with points pt 2 ps 1.2 lc rgb 'white' notitle, "
                "$map using 1:($7 > 0.5 ? NaN : $2) with points pt 7 ps 0.4 lc rgb 'black' "
                "notitle\n",
                quantities[show[k]].label, 3 + k);
    }
    fprintf(sf, "unset multiplot\nset output\n");
    return 0;
}

int afm_cmd_plot_map(int argc, char **argv) {
    mplot_opts o = {.width = 1200, .height = 900};
    const afmt_opt opts[] = {
        AFMT_STRING("--out", &o.out),
        AFMT_STRING("--gsf", &o.gsf),
        AFMT_STRING("--script", &o.script),
        AFMT_FN("--direction", parse_dir, &o.dir_word, "up or down"),
        AFMT_FN("--size", parse_size, &o, "WxH, 200..10000 pixels each"),
        AFMT_ARG("MAPFILE", &o.in),
        AFMT_OPTS_END,
    };
    int prc = afmt_opts_parse("plot map", opts, argc, argv, 1);
    int rc = afmt_opts_done("plot map", prc == AFMT_OPTS_HELP ? 1 : prc ? -1 : 0, mplot_usage);
    if (rc >= 0) return rc;
    if (!o.in || (!o.out && !o.gsf)) {
        fprintf(stderr, "afmtwin plot map: a MAPFILE and --out or --gsf are required\n");
        return 2;
    }
    static afmt_map_data m;
    char err[512];
    if (afmt_map_read(o.in, &m, err, sizeof err)) {
        fprintf(stderr, "afmtwin plot map: %s\n", err);
        return 2;
    }
    int status = 0;
    if (o.gsf && write_all_gsf(o.gsf, &m)) status = 1;
    if (!status && o.out) {
        int d = o.dir_word ? !strcmp(o.dir_word, "down") : !m.pts[0];
        if (!m.pts[d]) {
            fprintf(stderr, "afmtwin plot map: %s has no %s sweep\n", o.in, d ? "down" : "up");
            afmt_map_data_destroy(&m);
            return 2;
        }
        if (m.lines == 0) {
            fprintf(stderr, "afmtwin plot map: %s has no finished line yet\n", o.in);
            afmt_map_data_destroy(&m);
            return 2;
        }
        char *script = NULL;
        size_t len = 0;
        FILE *sf = open_memstream(&script, &len);
        if (!sf || write_script(sf, &o, &m, d) || fclose(sf)) status = 1;
        if (!status && o.script) {
            FILE *f = fopen(o.script, "w");
            if (!f || fwrite(script, 1, len, f) != len || fclose(f)) {
                fprintf(stderr, "afmtwin plot map: cannot write %s\n", o.script);
                status = 1;
            }
        }
        FILE *gp = status ? NULL : popen("gnuplot", "w");
        if (gp) {
            fwrite(script, 1, len, gp);
            int g = pclose(gp);
            if (g != 0) {
                fprintf(stderr, "afmtwin plot map: gnuplot failed (status %d)\n", g);
                status = 1;
            }
        } else if (!status) {
            fprintf(stderr, "afmtwin plot map: cannot run gnuplot (package gnuplot-nox)\n");
            status = 1;
        }
        free(script);
    }
    afmt_map_data_destroy(&m);
    return status;
}
