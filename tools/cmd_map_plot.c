/* SPDX-License-Identifier: MIT */
/* cmd_map_plot.c -- `afmtwin plot map` (issue 31): heat maps of a map file (map_file.h) with
 * gnuplot, the LPC / PD curves of `continue --param2` and a peak-force contour over them, and
 * every map quantity as a Gwyddion Simple Field file (gsf_write.h). Apart from
 * cmd_plot.c, which hands the kind "map" over to it, because its input is the map file and
 * its picture a grid of images, not the curves the other kinds draw. */
#include "afmtwin_cmds.h"
#include "gsf_write.h"
#include "map_file.h"
#include "opts.h"
#include "plot_info.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const char *in, *out, *gsf, *script, *curves;
    int dir;          /* --direction: 0 up, 1 down; -1: the map's first sweep */
    double contour_n; /* --contour-force, N; NaN: none */
    int width, height;
} mplot_opts;

static void mplot_usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin plot map MAPFILE [--out FILE.png|.svg] [--gsf PREFIX]\n"
            "                        [--direction up|down] [--size WxH] [--script FILE]\n"
            "                        [--curves CONT.json] [--contour-force F]\n\n"
            "Heat maps of an `afmtwin map` file over its plane: peak force, amplitude, phase lag\n"
            "(of the deflection behind the drive, 90 deg free at resonance) and dissipated\n"
            "energy of one sweep direction (default up, else the one the map has), the bistable\n"
            "points (up and down differ) marked with white crosses, points that did not settle\n"
            "with black dots. A partial map (an interrupted run) shows its finished lines.\n\n"
            "options:\n"
            "  --out FILE       the picture (pngcairo; .svg: SVG); also -o, --output\n"
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
            "  --script FILE    the gnuplot script as run (its data blocks: $map, $bist, $lpc,\n"
            "                   $lpc2, $pd, $cont)\n"
            "  --curves FILE    overlay the LPC curves (solid black: the edges of the bistable\n"
            "                   windows; dash-dot black: the folds of period-2 and longer\n"
            "                   branches) and PD curves (dashed magenta: of the period-doubled\n"
            "                   regions) of `afmtwin continue --param2 ... --json` on every\n"
            "                   panel; its two parameters must be the map's x and y (either\n"
            "                   order); several runs' outputs concatenated (each ends with its\n"
            "                   summary record) draw as separate curves\n"
            "  --contour-force F  draw the contour where the shown direction's peak force is F\n"
            "                   (N) on every panel (white; linear interpolation in each grid\n"
            "                   cell, cells with a missing value left out)\n"
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

static const afmt_choice dir_choices[] = {{"up", 0}, {"down", 1}, {NULL, 0}};

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
    {"dissipated_energy", "J", "E_ts tip-sample dissipated (eV)", 1.0 / 1.602176634e-19},
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
    h.xy_units = afmt_map_axis_unit(&m->x);
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
    if (strcmp(afmt_map_axis_unit(&m->x), afmt_map_axis_unit(&m->y)))
        snprintf(ynote, sizeof ynote, "; x %s in %s, y %s in %s", afmt_map_axis_name(&m->x),
                 afmt_map_axis_unit(&m->x), afmt_map_axis_name(&m->y), afmt_map_axis_unit(&m->y));
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

static double axis_scale(const afmt_map_axis *a) {
    return a->param == AFMT_MAP_FE ? 1e-3 : a->param == AFMT_MAP_NAMED ? 1.0 : 1e9;
}

/* The axis's label (a named parameter: its name and unit, into buf). */
static const char *axis_label(const afmt_map_axis *a, char *buf, size_t len) {
    if (a->param == AFMT_MAP_NAMED) {
        snprintf(buf, len, "%s (%s)", a->name, a->unit);
        return buf;
    }
    return a->param == AFMT_MAP_FE  ? "drive frequency fe (kHz)"
           : a->param == AFMT_MAP_Z ? "separation Z (nm)"
                                    : "drive amplitude Ae (nm)";
}

/* The LPC and PD curves of a `continue --param2 --json` file as gnuplot data (x y, in the
 * map's plotting units), one block per curve side separated by blank lines; side 1 starts
 * again at the curve's start point so that the two sides draw as one line. blk[CV_LPC]: the
 * LPC curves of period-1 orbits (or of no stated period), blk[CV_LPC2]: those of longer
 * periods (the folds of period-doubled branches, another line style), blk[CV_PD]: the PD
 * curves. A summary record (the end of one run's output) ends the curve, so that the outputs
 * of several runs concatenated read as their curves, not joined. blk[] is malloc'd text (the
 * caller frees it), *np the curve points read. 0, or -1 with err (cannot read the file, a bad
 * record, curves in other parameters than the map's). */
enum { CV_LPC, CV_LPC2, CV_PD, CV_N };
static int read_curves(const char *path, const afmt_map_data *m, char **blk, int *np, char *err,
                       size_t errlen) {
    for (int k = 0; k < CV_N; k++)
        blk[k] = NULL;
    *np = 0;
    FILE *f = fopen(path, "r");
    if (!f) {
        snprintf(err, errlen, "cannot read %s", path);
        return -1;
    }
    size_t bl[CV_N];
    FILE *out[CV_N];
    for (int k = 0; k < CV_N; k++)
        out[k] = open_memstream(&blk[k], &bl[k]);
    char *line = NULL;
    size_t cap = 0;
    int rc = 0, lineno = 0, cur = -1, side = -1;
    double start[2] = {NAN, NAN};
    const double sx = axis_scale(&m->x), sy = axis_scale(&m->y);
    for (int k = 0; k < CV_N; k++)
        if (!out[k]) rc = -1;
    while (!rc && getline(&line, &cap, f) > 0) {
        lineno++;
        if (strspn(line, " \t\r\n") == strlen(line)) continue;
        cJSON *o = cJSON_Parse(line);
        const cJSON *t = o ? cJSON_GetObjectItemCaseSensitive(o, "type") : NULL;
        if (!cJSON_IsString(t)) {
            snprintf(err, errlen, "%s:%d: not a record of `afmtwin continue --json`", path, lineno);
            rc = -1;
        } else if (!strcmp(t->valuestring, "summary")) {
            cur = side = -1;
        } else if (!strcmp(t->valuestring, "curve_point")) {
            const cJSON *n1 = cJSON_GetObjectItemCaseSensitive(o, "param_name"),
                        *n2 = cJSON_GetObjectItemCaseSensitive(o, "param2_name"),
                        *v1 = cJSON_GetObjectItemCaseSensitive(o, "param"),
                        *v2 = cJSON_GetObjectItemCaseSensitive(o, "param2"),
                        *kd = cJSON_GetObjectItemCaseSensitive(o, "kind"),
                        *cv = cJSON_GetObjectItemCaseSensitive(o, "curve"),
                        *sd = cJSON_GetObjectItemCaseSensitive(o, "side"),
                        *pe = cJSON_GetObjectItemCaseSensitive(o, "period");
            const char *xn = afmt_map_axis_name(&m->x), *yn = afmt_map_axis_name(&m->y);
            /* a curve's names as continue writes them: fe, z, ae or the table's name */
            int p1 = !cJSON_IsString(n1)            ? -1
                     : !strcmp(n1->valuestring, xn) ? 0
                     : !strcmp(n1->valuestring, yn) ? 1
                                                    : 2;
            int p2 = !cJSON_IsString(n2)            ? -1
                     : !strcmp(n2->valuestring, xn) ? 0
                     : !strcmp(n2->valuestring, yn) ? 1
                                                    : 2;
            if (p1 < 0 || p2 < 0 || !cJSON_IsNumber(v1) || !cJSON_IsNumber(v2) ||
                !cJSON_IsString(kd) || !cJSON_IsNumber(cv) || !cJSON_IsNumber(sd)) {
                snprintf(err, errlen,
                         "%s:%d: a curve_point without param_name/param2_name (fe, z or ae), "
                         "param, param2, kind, curve or side",
                         path, lineno);
                rc = -1;
            } else if (!((p1 == 0 && p2 == 1) || (p1 == 1 && p2 == 0))) {
                snprintf(err, errlen, "%s:%d: curves in (%s, %s), the map is in (%s, %s)", path,
                         lineno, n1->valuestring, n2->valuestring, xn, yn);
                rc = -1;
            } else {
                bool swap = p1 != 0;
                double x = (swap ? v2 : v1)->valuedouble * sx,
                       y = (swap ? v1 : v2)->valuedouble * sy;
                FILE *g = out[!strcmp(kd->valuestring, "PD")                ? CV_PD
                              : cJSON_IsNumber(pe) && pe->valuedouble > 1.5 ? CV_LPC2
                                                                            : CV_LPC];
                if (cv->valueint != cur) {
                    fprintf(g, "\n");
                    start[0] = x;
                    start[1] = y;
                } else if (sd->valueint != side) {
                    fprintf(g, "\n%.10g %.10g\n", start[0], start[1]);
                }
                cur = cv->valueint;
                side = sd->valueint;
                fprintf(g, "%.10g %.10g\n", x, y);
                (*np)++;
            }
        }
        cJSON_Delete(o);
    }
    free(line);
    fclose(f);
    for (int k = 0; k < CV_N; k++)
        if (out[k] && fclose(out[k])) rc = -1;
    if (!rc && *np == 0) {
        snprintf(err, errlen, "%s has no curve_point record (afmtwin continue --param2 --json)",
                 path);
        rc = -1;
    }
    if (rc) {
        if (!err[0]) snprintf(err, errlen, "out of memory reading %s", path);
        for (int k = 0; k < CV_N; k++) {
            free(blk[k]);
            blk[k] = NULL;
        }
    }
    return rc;
}

/* The contour v = level of the grid v[iy * nx + ix] (ny rows) by marching squares: per cell
 * the crossings of its edges, linearly interpolated, joined in pairs (a saddle resolved by the
 * cell's mean); a cell with a NaN corner is left out. Segments "x y\nx y\n\n" in the axes'
 * plotting units. Returns the number of segments. */
static int write_contour(FILE *sf, const afmt_map_data *m, const double *v, int ny, double level) {
    const int nx = m->x.n;
    const double sx = axis_scale(&m->x), sy = axis_scale(&m->y);
    int nseg = 0;
    for (int iy = 0; iy + 1 < ny; iy++)
        for (int ix = 0; ix + 1 < nx; ix++) {
            /* corners counter-clockwise from (ix, iy); edge e joins corner e and e + 1 */
            const int cx[4] = {ix, ix + 1, ix + 1, ix}, cy[4] = {iy, iy, iy + 1, iy + 1};
            double c[4], px[4], py[4];
            bool ok = true;
            for (int k = 0; k < 4; k++) {
                c[k] = v[(size_t)cy[k] * nx + cx[k]];
                ok = ok && isfinite(c[k]);
            }
            if (!ok) continue;
            int edge[4], ne = 0;
            for (int e = 0; e < 4; e++) {
                int a = e, b = (e + 1) % 4;
                if ((c[a] >= level) == (c[b] >= level)) continue;
                double t = (level - c[a]) / (c[b] - c[a]);
                px[e] =
                    afmt_map_axis_value(&m->x, cx[a]) * sx +
                    t * (afmt_map_axis_value(&m->x, cx[b]) - afmt_map_axis_value(&m->x, cx[a])) *
                        sx;
                py[e] =
                    afmt_map_axis_value(&m->y, cy[a]) * sy +
                    t * (afmt_map_axis_value(&m->y, cy[b]) - afmt_map_axis_value(&m->y, cy[a])) *
                        sy;
                edge[ne++] = e;
            }
            int pairs[2][2] = {{edge[0], edge[1]}, {-1, -1}};
            if (ne == 4) { /* a saddle: corners 0 and 2 on one side, 1 and 3 on the other */
                bool centre = 0.25 * (c[0] + c[1] + c[2] + c[3]) >= level;
                if (centre == (c[0] >= level)) { /* corners 1 and 3 cut off */
                    pairs[0][0] = 0, pairs[0][1] = 1, pairs[1][0] = 2, pairs[1][1] = 3;
                } else { /* corners 0 and 2 cut off */
                    pairs[0][0] = 3, pairs[0][1] = 0, pairs[1][0] = 1, pairs[1][1] = 2;
                }
            } else if (ne != 2) {
                continue;
            }
            for (int k = 0; k < 2 && pairs[k][0] >= 0; k++) {
                fprintf(sf, "%.10g %.10g\n%.10g %.10g\n\n", px[pairs[k][0]], py[pairs[k][0]],
                        px[pairs[k][1]], py[pairs[k][1]]);
                nseg++;
            }
        }
    return nseg;
}

/* The line under the title, as every `afmtwin plot` has it (plot_info.h): the config's model
 * (f0, Q, k) and the drive, the map's two axes as ranges. "" when the config the map names
 * cannot be read from here (its path is the one map was given). */
static void map_info_line(const afmt_map_data *m, char *out, size_t n) {
    out[0] = '\0';
    plot_info pi;
    plot_info_init(&pi);
    if (plot_info_config(&pi, m->config)) return;
    const afmt_map_axis *ax[2] = {&m->x, &m->y};
    for (int i = 0; i < 2; i++) {
        const double v[2] = {ax[i]->from, ax[i]->to};
        for (int j = 0; j < 2; j++) {
            if (ax[i]->param == AFMT_MAP_FE)
                plot_info_fe(&pi, v[j]);
            else if (ax[i]->param == AFMT_MAP_Z)
                plot_info_z(&pi, v[j]);
            else
                plot_info_param(&pi, afmt_map_axis_name(ax[i]), v[j]);
        }
    }
    plot_info_line(&pi, out, n);
    for (char *c = out; *c; c++)
        if (*c == '\'') *c = ' '; /* inside a gnuplot '...' string */
}

static int write_script(FILE *sf, const mplot_opts *o, const afmt_map_data *m, int d,
                        char *const *blk) {
    const char *lpc = blk[CV_LPC], *lpc2 = blk[CV_LPC2], *pd = blk[CV_PD];
    const double sx = axis_scale(&m->x), sy = axis_scale(&m->y);
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
    /* the overlays: LPC and PD curves (--curves), the peak-force contour (--contour-force) */
    char over[1024] = "";
    size_t ol = 0;
    if (lpc) {
        fprintf(sf, "$lpc << EOD\n%s%sEOD\n$lpc2 << EOD\n%s%sEOD\n$pd << EOD\n%s%sEOD\n", lpc,
                *lpc ? "" : "NaN NaN\n", lpc2, *lpc2 ? "" : "NaN NaN\n", pd,
                *pd ? "" : "NaN NaN\n");
        ol += snprintf(over + ol, sizeof over - ol,
                       ", $lpc using 1:2 with lines lw 2.5 lc rgb 'black' notitle, $lpc2 using "
                       "1:2 with lines lw 3 dt (6,3,2,3) lc rgb 'black' notitle, $pd using "
                       "1:2 with lines lw 2 dt 2 lc rgb '#ff00ff' notitle");
    }
    if (!isnan(o->contour_n)) {
        size_t np = (size_t)m->x.n * m->lines;
        double *v = malloc((np ? np : 1) * sizeof *v);
        if (!v) return -1;
        for (size_t i = 0; i < np; i++)
            v[i] = m->pts[d][i].peak_force_n * 1e9;
        fprintf(sf, "$cont << EOD\n");
        int nseg = write_contour(sf, m, v, m->lines, o->contour_n * 1e9);
        if (!nseg) fprintf(sf, "NaN NaN\n");
        fprintf(sf, "EOD\n");
        free(v);
        ol += snprintf(over + ol, sizeof over - ol,
                       ", $cont using 1:2 with lines lw 2.5 lc rgb 'white' notitle");
    }
    /* three title lines: what the map is, the model and the drive (plot_info.h, which starts
     * with the config's name: the first line names it only when the config cannot be read),
     * then what the marks and lines are (no key: it would hide part of a panel) */
    char info[256];
    map_info_line(m, info, sizeof info);
    fprintf(sf,
            "set multiplot layout 2,2 title 'afmtwin map%s%s (%s sweep, %d x %d%s)'.\"\\n\"."
            "%s%s%s'white x: bistable points, black dots: unsettled",
            info[0] ? "" : " ", info[0] ? "" : m->config, d ? "down" : "up", m->x.n, m->y.n,
            m->lines < m->y.n ? ", partial" : "", info[0] ? "'" : "", info,
            info[0] ? "'.\"\\n\"." : "");
    if (lpc && *lpc) fprintf(sf, "; black lines: LPC curves");
    if (lpc2 && *lpc2) fprintf(sf, "; dash-dot black: folds of period-2+ branches");
    if (pd && *pd) fprintf(sf, "; dashed magenta: PD curves");
    if (!isnan(o->contour_n)) fprintf(sf, "; white line: peak force %.4g nN", o->contour_n * 1e9);
    fprintf(sf, "'.\"\\n\".'%s'\n", PLOT_LAG_NOTE);
    char xlab[128], ylab[128];
    fprintf(sf,
            "set xlabel '%s'\nset ylabel '%s'\nset palette rgb 33,13,10\nset autoscale cbfix\nset "
            "format cb '%%g'\n",
            axis_label(&m->x, xlab, sizeof xlab), axis_label(&m->y, ylab, sizeof ylab));
    /* the picture's extent: the map's pixels (curves outside it are clipped) */
    double ex[2], ey[2];
    gsf_axis(&m->x, &ex[1], &ex[0]);
    gsf_axis(&m->y, &ey[1], &ey[0]);
    fprintf(sf, "set xrange [%.10g:%.10g]\nset yrange [%.10g:%.10g]\n", ex[0] * sx,
            (ex[0] + ex[1]) * sx, ey[0] * sy, (ey[0] + ey[1]) * sy);
    const int show[4] = {2, 0, 1, 7};
    for (int k = 0; k < 4; k++) {
        /* the colour scale spans the settled points: an unsettled point (marked black) may
         * read anything (on fig 4-2's map, E_ts of -50 to -80 eV beside 0..30 eV settled),
         * and its colour saturates at the scale's end instead of flattening the rest */
        double lo = INFINITY, hi = -INFINITY;
        for (size_t i = 0; i < (size_t)m->x.n * m->lines; i++) {
            const afmt_map_point *p = &m->pts[d][i];
            double v = qvalue(p, show[k]) * quantities[show[k]].scale;
            if (!p->settled || !isfinite(v)) continue;
            lo = fmin(lo, v);
            hi = fmax(hi, v);
        }
        if (lo < hi)
            fprintf(sf, "set cbrange [%.10g:%.10g]\n", lo, hi);
        else
            fprintf(sf, "set autoscale cbfix\n");
        /* the colour bar's unit: the label's last parenthesis ("peak force (nN)": nN), 2
         * characters right (where gnuplot puts it, it sits on the tick labels: "150nN") */
        const char *lab = quantities[show[k]].label, *u = strrchr(lab, '(');
        fprintf(sf, "set cblabel '%.*s' offset 2,0\n", u ? (int)strcspn(u + 1, ")") : 0,
                u ? u + 1 : "");
        fprintf(sf,
                "set title '%s'\nplot $map using 1:2:%d with image notitle, "
                "$bist using 1:2 with points pt 2 ps 1.2 lc rgb 'white' notitle, "
                "$map using 1:($7 > 0.5 ? NaN : $2) with points pt 7 ps 0.4 lc rgb 'black' "
                "notitle%s\n",
                quantities[show[k]].label, 3 + k, over);
    }
    fprintf(sf, "unset multiplot\nset output\n");
    return 0;
}

int afm_cmd_plot_map(int argc, char **argv) {
    mplot_opts o = {.width = 1200, .height = 900, .contour_n = NAN, .dir = -1};
    const afmt_opt opts[] = {
        AFMT_STRING("--out", &o.out),
        AFMT_STRING("-o", &o.out), /* as every other plot kind takes it */
        AFMT_STRING("--output", &o.out),
        AFMT_STRING("--gsf", &o.gsf),
        AFMT_STRING("--script", &o.script),
        AFMT_STRING("--curves", &o.curves),
        AFMT_DOUBLE_ABOVE("--contour-force", &o.contour_n, 0, 1, "a force in N, 0 < F <= 1"),
        AFMT_CHOICE("--direction", &o.dir, dir_choices),
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
        int d = o.dir >= 0 ? o.dir : !m.pts[0];
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
        char *script = NULL, *blk[CV_N] = {NULL, NULL, NULL};
        size_t len = 0;
        if (o.curves) {
            int np;
            err[0] = 0;
            if (read_curves(o.curves, &m, blk, &np, err, sizeof err)) {
                fprintf(stderr, "afmtwin plot map: %s\n", err);
                afmt_map_data_destroy(&m);
                return 2;
            }
        }
        FILE *sf = open_memstream(&script, &len);
        if (!sf || write_script(sf, &o, &m, d, blk) || fclose(sf)) status = 1;
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
        for (int k = 0; k < CV_N; k++)
            free(blk[k]);
    }
    afmt_map_data_destroy(&m);
    return status;
}
