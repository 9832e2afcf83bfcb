/* SPDX-License-Identifier: MIT */
/* cmd_plot.c -- `afmtwin plot KIND INPUT... -o FILE.png`: pictures of the tools' results
 * through gnuplot, and the same data as columns beside them (--data).
 *
 * Why a C command and not a set of gnuplot scripts: the inputs are the tools' own JSON
 * lines and LCM logs, which gnuplot cannot read; the command turns them into columns (the
 * data file a person can plot elsewhere) and hands gnuplot a script with the columns as
 * inline data blocks, so nothing else (jq, Python) is needed to look at a result.
 *
 * Kinds: sweep (afmtwin sweep --json), approach (afmtwin approach --json), thermal
 * (afmtwin thermal --psd, with its --json fit), trace (an LCM log of the daemon's outputs),
 * spectrum (the harmonics of one sweep or approach record). Phases are the lag of the
 * deflection behind the drive (90 deg free at resonance), as the tools print them. */
#include "afmtwin_cmds.h"
#include "opts.h"

#include "transport/afm_lcm_log.h"
#include "transport/afm_lcm_wire.h"
#include "afmtwin_samples_t.h"
#include "lcm_tool.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PLOT_MAX_INPUTS 8
#define PLOT_MAX_COLS 12
#define PLOT_MAX_SETS 8
#define PLOT_LINE_MAX (1 << 20)
#define PLOT_EV 1.602176634e-19 /* J per eV */

typedef struct {
    const char *kind, *out, *data, *fit, *title;
    const char *in[PLOT_MAX_INPUTS];
    int n_in, index, stream, width, height;
    double t_from_s, t_to_s, z_m;
} plot_opts;

/* A data set: rows of ncol numbers (NAN prints as "NaN", which gnuplot skips). */
typedef struct {
    char name[32], header[256];
    int ncol;
    size_t n, cap;
    double *v;
} plot_set;

typedef struct {
    plot_set set[PLOT_MAX_SETS];
    int nset;
    char title[512];
} plot_data;

static void plot_usage(FILE *f) {
    fprintf(f, "usage: afmtwin plot KIND INPUT... -o FILE.png [--data FILE] [--title TEXT]\n"
               "                    [--size WxH] [kind options]\n\n"
               "Draws a result with gnuplot (pngcairo; an output name ending in .svg gives SVG)\n"
               "and, with --data, writes the plotted columns to FILE (blank-line separated data\n"
               "sets, each with a # header) for plotting elsewhere. Kinds:\n"
               "  sweep     INPUT: afmtwin sweep --json output(s), e.g. a forward and a backward\n"
               "            sweep: amplitude (half peak-to-peak of xr), lock-in phase lag and\n"
               "            peak force against fe; steps with periodicity p > 1 marked, steps\n"
               "            that did not settle marked x\n"
               "  approach  INPUT: afmtwin approach --json output: amplitude and phase lag\n"
               "            against Z, approach and retract, the regime jumps marked; peak\n"
               "            force, indentation and dissipated energy against Z\n"
               "  thermal   INPUT: a PSD from afmtwin thermal --psd; --fit FILE: its --json\n"
               "            output, whose eq. 5.1 fit per mode is drawn over the PSD\n"
               "  trace     INPUT: an LCM log of the daemon's outputs (lcm-logger, afmtwin\n"
               "            listen): deflection, OBD signal and force of one sample stream\n"
               "            (--stream N, default 0) over --from S --to S of model time (default\n"
               "            the first 2 ms); --z M also draws the gap d = xr + Z (cos alpha 1)\n"
               "  spectrum  INPUT: sweep or approach --json output; --index N: the record (step)\n"
               "            to draw, 0 the first (default), -1 the last: harmonic amplitudes\n"
               "  scan      INPUT: afmtwin scan --json output: images (trace) of the height,\n"
               "            phase lag, amplitude error and peak force with their colour bars,\n"
               "            x and y in nm, and the middle line's height profile (trace and\n"
               "            retrace) against the true height; a one-line scan draws profiles\n"
               "  continue  INPUT: afmtwin continue --json output: the bifurcation diagram,\n"
               "            min(xr) and the amplitude at fe against the parameter, stable\n"
               "            branches solid, unstable dashed, LPC, PD and NS points marked and\n"
               "            labelled L1.., P1.., N1.. in the order found\n\n"
               "Phase convention: the lag of the deflection behind the drive, 90 deg for a free\n"
               "cantilever at resonance, below 90 in the repulsive regime.\n"
               "Exit status 0 ok, 1 gnuplot or a file failed, 2 bad usage or bad input.\n");
}

static int plot_err(const char *fmt, const char *a) {
    fprintf(stderr, "afmtwin plot: ");
    fprintf(stderr, fmt, a);
    fprintf(stderr, "\n");
    return -1;
}

/* The words after KIND: up to PLOT_MAX_INPUTS input files. */
static int add_input(const char *v, void *dest) {
    plot_opts *o = dest;
    if (o->n_in >= PLOT_MAX_INPUTS) return -1;
    o->in[o->n_in++] = v;
    return 0;
}

/* --size WxH, 100..10000 pixels each. */
static int parse_size(const char *v, void *dest) {
    plot_opts *o = dest;
    int w, h;
    if (sscanf(v, "%dx%d", &w, &h) != 2 || w < 100 || h < 100 || w > 10000 || h > 10000) return -1;
    o->width = w;
    o->height = h;
    return 0;
}

/* 0 ok, 1 --help, -1 bad usage (said). */
static int parse_args(int argc, char **argv, plot_opts *o) {
    *o = (plot_opts){.width = 1000, .height = 750, .t_from_s = NAN, .t_to_s = NAN, .z_m = NAN};
    const afmt_opt opts[] = {
        AFMT_ARG("KIND", &o->kind),
        AFMT_ARG_FN("INPUT", add_input, o, "at most 8 inputs"),
        AFMT_STRING("-o", &o->out),
        AFMT_STRING("--output", &o->out),
        AFMT_STRING("--data", &o->data),
        AFMT_STRING("--fit", &o->fit),
        AFMT_STRING("--title", &o->title),
        AFMT_FN("--size", parse_size, o, "WxH, 100..10000 pixels each"),
        AFMT_INT("--index", &o->index, -1e9 + 1, 1e9 - 1, NULL),
        AFMT_INT("--stream", &o->stream, 0, 127, NULL),
        AFMT_DOUBLE("--from", &o->t_from_s, 0, 0, NULL),
        AFMT_DOUBLE("--to", &o->t_to_s, 0, 0, NULL),
        AFMT_DOUBLE("--z", &o->z_m, 0, 0, NULL),
        AFMT_OPTS_END,
    };
    _Static_assert(PLOT_MAX_INPUTS == 8, "add_input's error text");
    int rc = afmt_opts_parse("plot", opts, argc, argv, 1);
    if (rc) return rc == AFMT_OPTS_HELP ? 1 : -1;
    if (!o->kind)
        return plot_err("%s", "KIND is required (sweep, approach, thermal, trace, spectrum, scan, "
                              "continue)");
    if (o->n_in == 0) return plot_err("%s", "an INPUT file is required");
    for (int i = 0; i < o->n_in; i++)
        if (strpbrk(o->in[i], "'\\\n"))
            return plot_err("'%s': no quotes or backslashes in names", o->in[i]);
    if (!o->out) return plot_err("%s", "-o FILE.png is required");
    if (strpbrk(o->out, "'\\\n"))
        return plot_err("'%s': no quotes or backslashes in names", o->out);
    return 0;
}

static plot_set *set_new(plot_data *d, const char *name, const char *header, int ncol) {
    if (d->nset == PLOT_MAX_SETS) return NULL;
    plot_set *s = &d->set[d->nset++];
    memset(s, 0, sizeof *s);
    snprintf(s->name, sizeof s->name, "%s", name);
    snprintf(s->header, sizeof s->header, "%s", header);
    s->ncol = ncol;
    return s;
}

static int set_row(plot_set *s, const double *row) {
    if (s->n == s->cap) {
        size_t cap = s->cap ? 2 * s->cap : 256;
        double *v = realloc(s->v, cap * (size_t)s->ncol * sizeof *v);
        if (!v) return -1;
        s->v = v;
        s->cap = cap;
    }
    memcpy(s->v + s->n * (size_t)s->ncol, row, (size_t)s->ncol * sizeof *row);
    s->n++;
    return 0;
}

static void data_free(plot_data *d) {
    for (int i = 0; i < d->nset; i++)
        free(d->set[i].v);
}

static void set_write(FILE *f, const plot_set *s) {
    for (size_t r = 0; r < s->n; r++) {
        for (int c = 0; c < s->ncol; c++) {
            double v = s->v[r * (size_t)s->ncol + c];
            fprintf(f, c ? " %.10g" : "%.10g", v);
        }
        fputc('\n', f);
    }
}

static double num(const cJSON *o, const char *key) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsNumber(v) ? v->valuedouble : NAN;
}

/* Each JSON line of path into fn (objects only; a line that is no JSON is an error). */
static int each_json(const char *path, int (*fn)(const cJSON *, void *), void *ctx) {
    FILE *f = fopen(path, "r");
    if (!f) return plot_err("cannot open %s", path);
    static char line[PLOT_LINE_MAX];
    int rc = 0, lineno = 0, objs = 0;
    while (rc == 0 && fgets(line, sizeof line, f)) {
        lineno++;
        if (line[0] == '#' || line[0] == '\n') continue;
        cJSON *o = cJSON_Parse(line);
        if (!cJSON_IsObject(o)) {
            fprintf(stderr, "afmtwin plot: %s line %d is no JSON object\n", path, lineno);
            rc = -1;
        } else {
            rc = fn(o, ctx);
            objs++;
        }
        cJSON_Delete(o);
    }
    fclose(f);
    if (rc == 0 && objs == 0) return plot_err("%s holds no JSON records", path);
    return rc;
}

/* The file name without its directories (a legend entry; quotes cannot occur in it: the
 * title check below applies to the whole path). */
static const char *base_name(const char *path) {
    const char *b = strrchr(path, '/');
    return b ? b + 1 : path;
}

/* ---- sweep ---- */

typedef struct {
    plot_set *all, *marks;
} sweep_ctx;

static int sweep_row(const cJSON *o, void *vctx) {
    sweep_ctx *c = vctx;
    double fe = num(o, "fe_hz"),
           amp = 0.5 * (num(o, "max_deflection_m") - num(o, "min_deflection_m"));
    const cJSON *lk = cJSON_GetObjectItemCaseSensitive(o, "lockin");
    double lag = num(lk, "phase_deg"), p = num(o, "periodicity");
    if (isnan(fe)) return plot_err("%s", "a sweep record without fe_hz (is it sweep --json?)");
    double row[6] = {
        fe * 1e-3, amp * 1e9,
        lag,       num(o, "max_force_n") * 1e9,
        p,         cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(o, "settled")) ? 1 : 0};
    if (set_row(c->all, row)) return -1;
    if (p != 1) return set_row(c->marks, row);
    return 0;
}

static int load_sweep(const plot_opts *o, plot_data *d, FILE *gp) {
    for (int i = 0; i < o->n_in; i++) {
        char name[32];
        snprintf(name, sizeof name, "S%d", i);
        sweep_ctx c = {set_new(d, name, "fe_kHz amplitude_nm lag_deg peak_force_nN p settled", 6),
                       NULL};
        snprintf(name, sizeof name, "M%d", i);
        c.marks = set_new(d, name, "fe_kHz amplitude_nm lag_deg peak_force_nN p settled", 6);
        if (!c.all || !c.marks || each_json(o->in[i], sweep_row, &c)) return -1;
    }
    fprintf(gp, "set multiplot layout 3,1 title '%s'\nset key top left\n", d->title);
    const char *ylab[3] = {"amplitude (nm)", "phase lag (deg)", "peak force (nN)"};
    for (int panel = 0; panel < 3; panel++) {
        fprintf(gp, "set ylabel '%s'\n%s", ylab[panel],
                panel == 2 ? "set xlabel 'drive frequency fe (kHz)'\n" : "unset xlabel\n");
        fprintf(gp, "plot ");
        for (int i = 0; i < o->n_in; i++)
            fprintf(gp,
                    "%s$S%d using 1:%d with linespoints pt 7 ps 0.4 title '%s', "
                    "$M%d using 1:($6 > 0 ? $%d : 1/0) with points pt 6 ps 1.5 lc rgb 'red' "
                    "title %s, $M%d using 1:($6 > 0 ? 1/0 : $%d) with points pt 2 ps 1.5 "
                    "lc rgb 'black' title %s",
                    i ? ", " : "", i, panel + 2, base_name(o->in[i]), i, panel + 2,
                    i ? "''" : "'p > 1 (period doubling)'", i, panel + 2,
                    i ? "''" : "'not settled'");
        fprintf(gp, "\n");
    }
    fprintf(gp, "unset multiplot\n");
    return 0;
}

/* ---- approach ---- */

typedef struct {
    plot_set *app, *ret, *jump;
} approach_ctx;

static int approach_row(const cJSON *o, void *vctx) {
    approach_ctx *c = vctx;
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(o, "jump");
    if (j) {
        double row[9] = {0.5e9 * (num(j, "z_before_m") + num(j, "z_after_m")),
                         num(j, "amplitude_before_m") * 1e9,
                         num(j, "amplitude_after_m") * 1e9,
                         num(j, "phase_before_deg"),
                         num(j, "phase_after_deg"),
                         0,
                         0,
                         0,
                         0};
        const cJSON *dir = cJSON_GetObjectItemCaseSensitive(j, "direction");
        row[5] = cJSON_IsString(dir) && !strcmp(dir->valuestring, "retract");
        return set_row(c->jump, row);
    }
    double z = num(o, "z_m");
    if (isnan(z)) return plot_err("%s", "an approach record without z_m (approach --json?)");
    const cJSON *dir = cJSON_GetObjectItemCaseSensitive(o, "direction");
    bool ret = cJSON_IsString(dir) && !strcmp(dir->valuestring, "retract");
    double row[9] = {z * 1e9,
                     num(o, "amplitude_m") * 1e9,
                     num(o, "phase_lag_deg"),
                     num(o, "peak_force_n") * 1e9,
                     num(o, "indentation_m") * 1e9,
                     num(o, "dissipated_energy_j") / PLOT_EV,
                     num(o, "attractive_force_n") * 1e9,
                     num(o, "virial_j") / PLOT_EV,
                     num(o, "periodicity")};
    return set_row(ret ? c->ret : c->app, row);
}

static int load_approach(const plot_opts *o, plot_data *d, FILE *gp) {
    const char *h = "Z_nm amplitude_nm lag_deg peak_force_nN indentation_nm dissipated_eV "
                    "attractive_force_nN virial_eV p";
    approach_ctx c = {set_new(d, "A", h, 9), set_new(d, "R", h, 9),
                      set_new(d, "J",
                              "Z_nm amp_before_nm amp_after_nm lag_before_deg "
                              "lag_after_deg retract 0 0 0",
                              9)};
    if (!c.app || !c.ret || !c.jump || each_json(o->in[0], approach_row, &c)) return -1;
    if (c.app->n + c.ret->n == 0) return plot_err("%s: no approach records", o->in[0]);
    fprintf(gp, "set multiplot layout 2,2 title '%s'\nset xlabel 'separation Z (nm)'\n", d->title);
    struct {
        const char *ylab;
        int col;
    } panel[4] = {{"amplitude (nm)", 2},
                  {"phase lag (deg)", 3},
                  {"peak repulsive force (nN)", 4},
                  {"dissipated energy per period (eV)", 6}};
    for (int p = 0; p < 4; p++) {
        fprintf(gp,
                "set key %s left\nset ylabel '%s'\nplot $A using 1:%d with linespoints pt "
                "7 ps 0.4 title 'approach'",
                p < 2 ? "top" : "bottom", panel[p].ylab, panel[p].col);
        if (c.ret->n)
            fprintf(gp, ", $R using 1:%d with linespoints pt 6 ps 0.4 title 'retract'",
                    panel[p].col);
        if (c.jump->n && p < 2)
            fprintf(gp,
                    ", $J using 1:%d:(0):($%d - $%d) with vectors lw 2 lc rgb 'red' title "
                    "'jump'",
                    2 + 2 * p, 3 + 2 * p, 2 + 2 * p);
        fprintf(gp, "\n");
    }
    fprintf(gp, "unset multiplot\n");
    return 0;
}

/* ---- continue ---- */

typedef struct {
    plot_set *pts, *ev, *cv;
    int branch, stable; /* of the previous point (-1: none) */
    double prev[5];
    int count[4];  /* events so far per type, for their labels */
    double scale;  /* of the parameter: 1e-3 for fe (kHz) */
    double scale2; /* of the second parameter (--param2): 1e-3 fe, 1e9 z and ae (nm) */
    char name2[64];
    int curve, side; /* of the previous curve point (-1: none) */
    double start[4]; /* the row of the current curve's first point (its start) */
    int ncurve[3];   /* curve points per kind (1 LPC, 2 PD) */
} cont_ctx;

/* Columns of a curve_point: param, param2 (scaled), kind (1 LPC, 2 PD), curve index. A NaN
 * row between curves and sides; side 1 starts again at the curve's start point, so that the
 * two sides draw as one line. */
static int curve_row(cont_ctx *c, const cJSON *o) {
    const cJSON *n2 = cJSON_GetObjectItemCaseSensitive(o, "param2_name");
    if (cJSON_IsString(n2)) {
        snprintf(c->name2, sizeof c->name2, "%s", n2->valuestring);
        c->scale2 = !strcmp(n2->valuestring, "fe")                                    ? 1e-3
                    : !strcmp(n2->valuestring, "z") || !strcmp(n2->valuestring, "ae") ? 1e9
                                                                                      : 1.0;
    }
    const cJSON *kd = cJSON_GetObjectItemCaseSensitive(o, "kind");
    double x = num(o, "param") * c->scale, y = num(o, "param2") * c->scale2;
    int cv = (int)num(o, "curve"), side = (int)num(o, "side");
    if (isnan(x) || isnan(y) || !cJSON_IsString(kd))
        return plot_err("%s", "a curve_point record without param, param2 or kind");
    int k = !strcmp(kd->valuestring, "PD") ? 2 : 1;
    static const double gap[4] = {NAN, NAN, NAN, NAN};
    double row[4] = {x, y, k, cv};
    if (cv != c->curve) {
        if (c->curve >= 0 && set_row(c->cv, gap)) return -1;
        memcpy(c->start, row, sizeof row);
    } else if (side != c->side && (set_row(c->cv, gap) || set_row(c->cv, c->start))) {
        return -1;
    }
    c->curve = cv;
    c->side = side;
    c->ncurve[k]++;
    return set_row(c->cv, row);
}

/* Columns: param, min x stable, min x unstable, amplitude stable, amplitude unstable (nm).
 * A NaN row between branches breaks the lines; at a change of stability the point goes in
 * both columns, so that the solid and dashed parts meet. */
static int continue_row(const cJSON *o, void *vctx) {
    cont_ctx *c = vctx;
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(o, "type");
    if (!cJSON_IsString(t)) return plot_err("%s", "a record without type (continue --json?)");
    const cJSON *pn = cJSON_GetObjectItemCaseSensitive(o, "param_name");
    if (cJSON_IsString(pn)) c->scale = strcmp(pn->valuestring, "fe") ? 1.0 : 1e-3;
    const char *ty = t->valuestring;
    if (!strcmp(ty, "summary") || !strcmp(ty, "end") || !strcmp(ty, "curve_end")) return 0;
    if (!strcmp(ty, "curve_point")) return curve_row(c, o);
    double x = num(o, "param") * c->scale, mn = num(o, "min_deflection_m") * 1e9,
           am = num(o, "amplitude_m") * 1e9;
    if (isnan(x) || isnan(mn)) return plot_err("%s", "a continue record without param");
    int br = (int)num(o, "branch"),
        st = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(o, "stable"));
    if (strcmp(ty, "point")) {
        int k = !strcmp(ty, "LPC") ? 1 : !strcmp(ty, "PD") ? 2 : 3;
        double row[5] = {x, mn, am, k, ++c->count[k]};
        return set_row(c->ev, row);
    }
    static const double gap[5] = {NAN, NAN, NAN, NAN, NAN};
    if (c->branch >= 0 && br != c->branch && set_row(c->pts, gap)) return -1;
    double row[5] = {x, st ? mn : NAN, st ? NAN : mn, st ? am : NAN, st ? NAN : am};
    if (c->branch == br && st != c->stable) { /* join the two parts at this point */
        row[1] = row[2] = mn;
        row[3] = row[4] = am;
    }
    c->branch = br;
    c->stable = st;
    return set_row(c->pts, row);
}

static int load_continue(const plot_opts *o, plot_data *d, FILE *gp) {
    cont_ctx c = {.pts = set_new(d, "B",
                                 "param min_x_stable_nm min_x_unstable_nm amp_stable_nm "
                                 "amp_unstable_nm",
                                 5),
                  .ev =
                      set_new(d, "E", "param min_x_nm amplitude_nm type(1 LPC 2 PD 3 NS) index", 5),
                  .cv = set_new(d, "C", "param param2 kind(1 LPC 2 PD) curve", 4),
                  .branch = -1,
                  .scale = 1.0,
                  .scale2 = 1.0,
                  .curve = -1,
                  .side = -1};
    if (!c.pts || !c.ev || !c.cv || each_json(o->in[0], continue_row, &c)) return -1;
    if (c.pts->n == 0) return plot_err("%s: no point records", o->in[0]);
    const char *xl = c.scale == 1e-3 ? "drive frequency fe (kHz)" : "parameter";
    const bool curves = c.cv->n > 0;
    fprintf(gp, "set multiplot layout %d,1 title '%s'\nset xlabel '%s'\n", curves ? 3 : 2, d->title,
            xl);
    const char *ylab[2] = {"min deflection min(xr) (nm)", "amplitude at fe (nm)"};
    for (int p = 0; p < 2; p++) {
        fprintf(gp,
                "set ylabel '%s'\nset key bottom right\n"
                "plot $B using 1:%d with lines lw 2 lc rgb 'blue' title 'stable', "
                "$B using 1:%d with lines lw 1 dt 2 lc rgb 'blue' title 'unstable'",
                ylab[p], 2 + 2 * p, 3 + 2 * p);
        static const char *const ev[3][3] = {
            {"LPC", "7", "red"}, {"PD", "5", "dark-green"}, {"NS", "9", "orange"}};
        for (int k = 0; k < 3; k++) /* gnuplot's sprintf fails on an empty set's NaN */
            if (c.count[k + 1] > 0)
                fprintf(gp,
                        ", $E using ($4 == %d ? $1 : 1/0):%d with points pt %s ps 1.2 lc "
                        "rgb '%s' title '%s', $E using ($4 == %d ? $1 : 1/0):%d:"
                        "(sprintf('%c%%d', $5)) with labels offset 1,1 notitle",
                        k + 1, 2 + p, ev[k][1], ev[k][2], ev[k][0], k + 1, 2 + p, ev[k][0][0]);
        fprintf(gp, "\n");
    }
    if (curves) { /* the parameter plane: the LPC and PD curves through the events */
        const char *u2 = c.scale2 == 1e-3 ? " (kHz)" : c.scale2 == 1e9 ? " (nm)" : "";
        double big = 0.0;
        for (size_t i = 0; i < c.cv->n; i++)
            if (isfinite(c.cv->v[4 * i + 1])) big = fmax(big, fabs(c.cv->v[4 * i + 1]));
        if (c.scale2 == 1e9 && big < 0.1) { /* sub-0.1 nm drive amplitudes: in pm */
            for (size_t i = 0; i < c.cv->n; i++)
                c.cv->v[4 * i + 1] *= 1e3;
            u2 = " (pm)";
        }
        char yl[128];
        const char *n2 = !strcmp(c.name2, "fe")   ? "drive frequency fe"
                         : !strcmp(c.name2, "z")  ? "separation Z"
                         : !strcmp(c.name2, "ae") ? "drive amplitude Ae"
                         : c.name2[0]             ? c.name2
                                                  : "param2";
        snprintf(yl, sizeof yl, "%s%s", n2, u2);
        fprintf(
            gp,
            "set title 'the bifurcation curves in the plane of the two parameters (own "
            "scales)'\nset ylabel '%s'\nset offsets 0, 0, graph 0.3, 0\nset key top center\nplot ",
            yl);
        static const char *const kn[2][2] = {{"LPC curve (fold)", "red"},
                                             {"PD curve (period doubling)", "dark-green"}};
        const char *sep = "";
        for (int k = 1; k <= 2; k++)
            if (c.ncurve[k] > 0) {
                fprintf(gp,
                        "%s$C using 1:($3 == %d || $3 != $3 ? $2 : 1/0) with linespoints lw 2 "
                        "pt 7 ps 0.5 lc rgb '%s' title '%s'",
                        sep, k, kn[k - 1][1], kn[k - 1][0]);
                sep = ", ";
            }
        fprintf(gp, "\n");
    }
    fprintf(gp, "unset multiplot\n");
    return 0;
}

/* ---- thermal ---- */

static int load_thermal(const plot_opts *o, plot_data *d, FILE *gp) {
    FILE *f = fopen(o->in[0], "r");
    if (!f) return plot_err("cannot open %s", o->in[0]);
    plot_set *s = set_new(d, "P", "f_hz psd_m2_per_hz", 2);
    char line[256];
    int bad = 0;
    while (s && fgets(line, sizeof line, f)) {
        double row[2];
        if (line[0] == '#') continue;
        if (sscanf(line, "%lf %lf", &row[0], &row[1]) != 2) {
            bad = 1;
            break;
        }
        if (row[0] > 0 && set_row(s, row)) break;
    }
    fclose(f);
    if (!s || bad || s->n == 0) return plot_err("%s is no PSD (afmtwin thermal --psd)", o->in[0]);
    fprintf(gp,
            "set logscale xy\nset format y '%%.0e'\nset xlabel 'frequency (Hz)'\nset ylabel "
            "'deflection PSD (m^2/Hz)'\nset title '%s'\n",
            d->title);
    fprintf(gp, "plot $P using 1:2 with lines lc rgb 'gray40' title 'PSD (Welch)'");
    if (o->fit) {
        FILE *jf = fopen(o->fit, "r");
        static char buf[PLOT_LINE_MAX];
        size_t n = jf ? fread(buf, 1, sizeof buf - 1, jf) : 0;
        if (jf) fclose(jf);
        buf[n] = 0;
        cJSON *j = cJSON_Parse(buf);
        const cJSON *ms = cJSON_GetObjectItemCaseSensitive(j, "modes"), *m;
        double T = num(j, "temperature_k");
        if (!cJSON_IsArray(ms) || isnan(T)) {
            cJSON_Delete(j);
            return plot_err("--fit %s is no afmtwin thermal --json output", o->fit);
        }
        int i = 0;
        cJSON_ArrayForEach(m, ms) {
            double fn = num(m, "f_hz"), q = num(m, "q"), k = num(m, "k_n_per_m");
            double fl = num(m, "floor_m_rthz");
            /* eq. 5.1 */
            fprintf(gp,
                    ", [%g:%g] 2*1.380649e-23*%g/(pi*%g*%g*%g)/((x**2/%g**2-1)**2+(x/(%g*%g))**2)"
                    "+%g**2 with lines lw 2 title 'eq. 5.1 fit, mode %d: f %.5g Hz, Q %.4g, k "
                    "%.4g N/m'",
                    fn * (1 - 8 / q), fn * (1 + 8 / q), T, k, fn, q, fn, fn, q, fl, ++i, fn, q, k);
        }
        cJSON_Delete(j);
    }
    fprintf(gp, "\n");
    return 0;
}

/* ---- trace ---- */

static int load_trace(const plot_opts *o, plot_data *d, FILE *gp) {
    char err[256];
    afm_lcm_log *l = afm_lcm_log_open(o->in[0], 0, err, sizeof err);
    if (!l) return plot_err("cannot read the log: %s", err);
    plot_set *s = set_new(d, "T", "t_ms deflection_nm obd_nm force_nN gap_nm", 5);
    double t0 = isnan(o->t_from_s) ? -HUGE_VAL : o->t_from_s;
    double t1 = isnan(o->t_to_s) ? HUGE_VAL : o->t_to_s, first = NAN;
    afm_lcm_log_event ev;
    int r, blocks = 0;
    while (s && (r = afm_lcm_log_next(l, &ev, err, sizeof err)) > 0) {
        size_t cl = strlen(ev.channel);
        if (cl < 7 || strcmp(ev.channel + cl - 7, "SAMPLES")) continue;
        afmtwin_samples_t m;
        if (afm_wire_decode(&afm_wire_samples_t, ev.data, (int)ev.datalen, &m, err, sizeof err))
            continue; /* not a samples_t: skipped, as listen does */
        if (m.stream == o->stream) {
            if (isnan(first)) first = m.t0_s;
            double a = isnan(o->t_from_s) ? first : t0;
            double b = isnan(o->t_to_s) ? a + 2e-3 : t1;
            for (int i = 0; i < m.n; i++) {
                double t = m.t0_s + i / m.rate_hz;
                if (t < a || t > b) continue;
                double row[5] = {t * 1e3, m.deflection_m[i] * 1e9, m.obd_m[i] * 1e9,
                                 m.force_n[i] * 1e9,
                                 isnan(o->z_m) ? NAN : (m.deflection_m[i] + o->z_m) * 1e9};
                if (set_row(s, row)) break;
            }
            blocks++;
        }
        afm_wire_free(&afm_wire_samples_t, &m);
    }
    afm_lcm_log_close(&l);
    if (!s || s->n == 0) {
        fprintf(stderr, "afmtwin plot: %s: no samples of stream %d in the window (%d blocks)\n",
                o->in[0], o->stream, blocks);
        return -1;
    }
    fprintf(gp, "set multiplot layout %d,1 title '%s'\n", isnan(o->z_m) ? 2 : 3, d->title);
    fprintf(gp, "unset xlabel\nset ylabel 'deflection (nm)'\nplot $T using 1:2 with lines title "
                "'tip deflection xr', $T using 1:3 with lines title 'OBD signal'\n");
    if (!isnan(o->z_m))
        fprintf(gp, "set ylabel 'gap (nm)'\nplot $T using 1:5 with lines title 'gap xr + Z'\n");
    fprintf(gp, "set xlabel 'model time (ms)'\nset ylabel 'force (nN)'\nplot $T using 1:4 with "
                "lines lc rgb 'red' title 'tip-sample force'\nunset multiplot\n");
    return 0;
}

/* ---- spectrum ---- */

typedef struct {
    int want, seen;
    plot_set *s;
    double z, fe;
} spectrum_ctx;

static int spectrum_row(const cJSON *o, void *vctx) {
    spectrum_ctx *c = vctx;
    const cJSON *hs = cJSON_GetObjectItemCaseSensitive(o, "harmonics"), *h;
    if (!cJSON_IsArray(hs)) return 0; /* a jump record */
    if (c->want >= 0 && c->seen++ != c->want) return 0;
    c->s->n = 0; /* -1: the last one wins */
    c->z = num(o, "z_m");
    c->fe = num(o, "fe_hz");
    cJSON_ArrayForEach(h, hs) {
        double a = num(h, "amplitude_m");
        if (isnan(a)) a = num(h, "deflection_amplitude_m");
        double row[2] = {num(h, "k"), a * 1e9};
        if (set_row(c->s, row)) return -1;
    }
    return 0;
}

static int load_spectrum(const plot_opts *o, plot_data *d, FILE *gp) {
    spectrum_ctx c = {.want = o->index, .s = set_new(d, "H", "k amplitude_nm", 2)};
    if (!c.s || each_json(o->in[0], spectrum_row, &c)) return -1;
    if (c.s->n == 0) return plot_err("%s: no record with harmonics at that --index", o->in[0]);
    fprintf(gp, "set logscale y\nset format y '%%.0e'\nset boxwidth 0.6\nset style fill solid 0.6\n"
                "set xlabel 'harmonic k'\nset ylabel 'deflection amplitude (nm)'\nset xtics 1\n");
    fprintf(gp, "set title '%s%s", d->title, isnan(c.z) ? "" : ", ");
    if (!isnan(c.z)) fprintf(gp, "Z %.4g nm", c.z * 1e9);
    if (!isnan(c.fe)) fprintf(gp, ", fe %.6g Hz", c.fe);
    fprintf(gp, "'\nplot $H using 1:2 with boxes title 'A_k'\n");
    return 0;
}

/* ---- scan ---- */

#define SCAN_COLS 9 /* x_nm y_nm line height_nm true_nm lag_deg error_nm peak_nN dissipated_eV */

typedef struct {
    plot_set *tr, *re;
    int lines;
} scan_ctx;

static int scan_row(const cJSON *o, void *vctx) {
    scan_ctx *c = vctx;
    double line = num(o, "line");
    if (isnan(line) || isnan(num(o, "height_m")))
        return plot_err("%s", "a record without line or height_m (afmtwin scan --json?)");
    if (line + 1 > c->lines) c->lines = (int)line + 1;
    double row[SCAN_COLS] = {num(o, "x_m") * 1e9,
                             num(o, "y_m") * 1e9,
                             line,
                             num(o, "height_m") * 1e9,
                             num(o, "true_height_m") * 1e9,
                             num(o, "phase_lag_deg"),
                             num(o, "error_m") * 1e9,
                             num(o, "peak_force_n") * 1e9,
                             num(o, "dissipated_energy_j") / PLOT_EV};
    return set_row(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(o, "retrace")) ? c->re : c->tr,
                   row);
}

/* Each line's y: the mean of its pixels' (the slow axis moves during a line), so that the
 * trace is a regular grid for gnuplot's image. */
static void scan_line_y(plot_set *s, int lines) {
    for (int l = 0; l < lines; l++) {
        double sum = 0;
        int n = 0;
        for (size_t r = 0; r < s->n; r++)
            if (s->v[r * SCAN_COLS + 2] == l) sum += s->v[r * SCAN_COLS + 1], n++;
        for (size_t r = 0; r < s->n && n; r++)
            if (s->v[r * SCAN_COLS + 2] == l) s->v[r * SCAN_COLS + 1] = sum / n;
    }
}

static int load_scan(const plot_opts *o, plot_data *d, FILE *gp) {
    const char *h = "x_nm y_nm line height_nm true_height_nm lag_deg error_nm peak_force_nN "
                    "dissipated_eV";
    scan_ctx c = {set_new(d, "T", h, SCAN_COLS), set_new(d, "R", h, SCAN_COLS), 0};
    if (!c.tr || !c.re || each_json(o->in[0], scan_row, &c)) return -1;
    if (c.tr->n == 0) return plot_err("%s: no trace pixels", o->in[0]);
    scan_line_y(c.tr, c.lines);
    /* the profile: the middle line's trace and retrace against the truth */
    int mid = c.lines / 2;
    plot_set *pt = set_new(d, "PT", h, SCAN_COLS), *pr = set_new(d, "PR", h, SCAN_COLS);
    if (!pt || !pr) return -1;
    for (size_t r = 0; r < c.tr->n; r++)
        if (c.tr->v[r * SCAN_COLS + 2] == mid && set_row(pt, c.tr->v + r * SCAN_COLS)) return -1;
    for (size_t r = 0; r < c.re->n; r++)
        if (c.re->v[r * SCAN_COLS + 2] == mid && set_row(pr, c.re->v + r * SCAN_COLS)) return -1;
    static const struct {
        const char *label;
        int col;
    } img[4] = {{"height (nm)", 4},
                {"phase lag (deg)", 6},
                {"amplitude error (nm)", 7},
                {"peak force (nN)", 8}};
    /* x tics: a 1-2-5 step giving about 4 intervals over the scan */
    double x0 = INFINITY, x1 = -INFINITY;
    for (size_t r = 0; r < c.tr->n; r++) {
        x0 = fmin(x0, c.tr->v[r * SCAN_COLS]);
        x1 = fmax(x1, c.tr->v[r * SCAN_COLS]);
    }
    double step = x1 > x0 ? pow(10, floor(log10((x1 - x0) / 4))) : 1;
    double ratio = x1 > x0 ? (x1 - x0) / 4 / step : 1;
    step *= ratio >= 5 ? 5 : ratio >= 2 ? 2 : 1;
    fprintf(gp,
            "set xtics %g\nset multiplot layout %d,%d title '%s (phase: lag behind the drive, 90 "
            "deg free at resonance)'\n",
            step, c.lines > 1 ? 2 : 3, c.lines > 1 ? 3 : 2, d->title);
    for (int p = 0; p < 4; p++) {
        if (c.lines > 1)
            fprintf(gp,
                    "set xlabel 'x (nm)'\nset ylabel 'y (nm)'\nset size ratio -1\nset title "
                    "'%s (trace)'\nunset key\nplot $T using 1:2:%d with image notitle\nset size "
                    "noratio\nset key\n",
                    img[p].label, img[p].col);
        else
            fprintf(gp,
                    "set xlabel 'x (nm)'\nset ylabel '%s'\nset title '%s'\nplot $PT using 1:%d "
                    "with linespoints pt 7 ps 0.4 title 'trace', $PR using 1:%d with "
                    "linespoints pt 6 ps 0.4 title 'retrace'\n",
                    img[p].label, img[p].label, img[p].col, img[p].col);
    }
    fprintf(gp,
            "set xlabel 'x (nm)'\nset ylabel 'height (nm)'\nset title 'line %d: height against "
            "the truth'\nplot $PT using 1:5 with lines lw 2 lc rgb 'black' title 'true', $PT "
            "using 1:4 with linespoints pt 7 ps 0.4 title 'trace', $PR using 1:4 with "
            "linespoints pt 6 ps 0.4 title 'retrace'\nunset multiplot\n",
            mid);
    return 0;
}

/* gnuplot string literal text: no quotes or backslashes from file names. */
static void title_of(const plot_opts *o, plot_data *d) {
    const char *t = o->title ? o->title : o->in[0];
    snprintf(d->title, sizeof d->title, "afmtwin %s: %s", o->kind, t);
    for (char *p = d->title; *p; p++)
        if (*p == '\'' || *p == '\\' || *p == '\n') *p = ' ';
}

int afm_cmd_plot(int argc, char **argv) {
    plot_opts o;
    int rc = afmt_opts_done("plot", parse_args(argc, argv, &o), plot_usage);
    if (rc >= 0) return rc;
    static const struct {
        const char *kind;
        int (*load)(const plot_opts *, plot_data *, FILE *);
    } kinds[] = {{"sweep", load_sweep},      {"approach", load_approach}, {"thermal", load_thermal},
                 {"trace", load_trace},      {"spectrum", load_spectrum}, {"scan", load_scan},
                 {"continue", load_continue}};
    int k = -1;
    for (int i = 0; i < (int)(sizeof kinds / sizeof kinds[0]); i++)
        if (!strcmp(o.kind, kinds[i].kind)) k = i;
    if (k < 0) {
        fprintf(stderr,
                "afmtwin plot: unknown kind '%s' (sweep, approach, thermal, trace, "
                "spectrum, scan, continue)\n",
                o.kind);
        return 2;
    }
    /* the plot commands first into memory: the data blocks go before them */
    static plot_data d;
    memset(&d, 0, sizeof d);
    title_of(&o, &d);
    char *cmds = NULL;
    size_t cmds_len = 0;
    FILE *cf = open_memstream(&cmds, &cmds_len);
    if (!cf) return 1;
    rc = kinds[k].load(&o, &d, cf);
    fclose(cf);
    if (rc != 0) {
        free(cmds);
        data_free(&d);
        return 2;
    }
    int status = 0;
    if (o.data) {
        FILE *df = fopen(o.data, "w");
        if (!df) {
            fprintf(stderr, "afmtwin plot: cannot write %s\n", o.data);
            status = 1;
        } else {
            fprintf(df, "# %s\n", d.title);
            for (int i = 0; i < d.nset; i++) {
                fprintf(df, "%s# %s: %s\n", i ? "\n\n" : "", d.set[i].name, d.set[i].header);
                set_write(df, &d.set[i]);
            }
            if (fclose(df) != 0) status = 1;
        }
    }
    size_t ol = strlen(o.out);
    bool svg = ol > 4 && !strcmp(o.out + ol - 4, ".svg");
    FILE *gp = status ? NULL : popen("gnuplot", "w");
    if (gp) {
        fprintf(gp,
                "set terminal %s size %d,%d noenhanced\nset output '%s'\nset grid\nset key "
                "box opaque\n",
                svg ? "svg" : "pngcairo", o.width, o.height, o.out);
        for (int i = 0; i < d.nset; i++) { /* empty sets are still defined (one NaN row) */
            fprintf(gp, "$%s << EOD\n", d.set[i].name);
            set_write(gp, &d.set[i]);
            if (d.set[i].n == 0) {
                for (int c = 0; c < d.set[i].ncol; c++)
                    fprintf(gp, c ? " NaN" : "NaN");
                fputc('\n', gp);
            }
            fprintf(gp, "EOD\n");
        }
        fwrite(cmds, 1, cmds_len, gp);
        fprintf(gp, "set output\n");
        int grc = pclose(gp);
        if (grc != 0) {
            fprintf(stderr, "afmtwin plot: gnuplot failed (status %d)\n", grc);
            status = 1;
        }
    } else if (!status) {
        fprintf(stderr, "afmtwin plot: cannot run gnuplot (package gnuplot-nox)\n");
        status = 1;
    }
    free(cmds);
    data_free(&d);
    return status;
}
