/* SPDX-License-Identifier: MIT */
/* cmd_plot.c -- `afmtwin plot KIND INPUT... -o FILE.png`: pictures of the tools' results
 * through gnuplot, the plotted curves beside them as columns (--data) or CSV (--csv), and
 * the gnuplot script itself (--script).
 *
 * Why a C command and not a set of gnuplot scripts: the inputs are the tools' own JSON
 * lines and LCM logs, which gnuplot cannot read; the command turns them into columns (the
 * data file a person can plot elsewhere) and hands gnuplot a script with the columns as
 * inline data blocks, so nothing else (jq, Python) is needed to look at a result.
 *
 * Kinds: sweep (afmtwin sweep --json), approach (afmtwin approach --json), thermal
 * (afmtwin thermal --psd, with its --json fit), trace (an LCM log of the daemon's outputs),
 * spectrum (the harmonics of one sweep or approach record), scan (afmtwin scan --json),
 * continue (afmtwin continue --json). Phases are the lag of the deflection behind the drive
 * (90 deg free at resonance), as the tools print them. This file holds the command, the
 * helpers every kind shares (cmd_plot.h) and the smaller kinds; continue, trace and fm,
 * each a reader of its own input, are in cmd_plot_continue.c, cmd_plot_trace.c and
 * cmd_plot_fm.c; approach (the largest) in cmd_plot_approach.c and scan (an image layout
 * of its own) in cmd_plot_scan.c.
 *
 * Every picture is laid out the same way, for a paper: the title (--title, else what the
 * kind draws) and under it the config and the drive (plot_info.h); one legend for all
 * panels in a strip of its own under the title (an empty plot of key entries), so that no
 * legend covers data; the panels at fixed places under it, those that share an axis with
 * its tic labels once. Scan images keep x and y at one scale and end at the pixels' edges. */
#include "afmtwin_cmds.h"
#include "cmd_plot.h"
#include "opts.h"
#include "plot_info.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void plot_usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin plot KIND INPUT... -o FILE.png [--title TEXT] [--config FILE\n"
            "                    [--fe HZ] [--ae M] [--z M]] [--data FILE] [--csv FILE]\n"
            "                    [--script FILE] [--size WxH] [kind options]\n\n"
            "Draws a result with gnuplot (pngcairo; an output name ending in .svg gives SVG):\n"
            "the title, under it the config and the drive, one legend for all panels in a\n"
            "strip under the title (scan: right of the panels; never on the data), and the\n"
            "panels. Kinds:\n"
            "  sweep     INPUT: afmtwin sweep --json output(s), e.g. a forward and a backward\n"
            "            sweep: amplitude (half peak-to-peak of xr), lock-in phase lag and the\n"
            "            largest tip-sample force against fe; steps with periodicity p > 1\n"
            "            marked o and labelled with p, steps that did not settle (settled\n"
            "            false or periodicity 0) marked x; the energy dissipated in the last\n"
            "            period by the tip-sample forces (E_ts) and, where a record has it, by\n"
            "            the squeeze film (E_sq, its own panel under E_ts). Columns: fe[kHz]\n"
            "            amplitude[nm] lag[deg] max_force[nN] periodicity settled[0/1]\n"
            "            dissipated[eV] (E_ts) squeeze_dissipated[eV] (E_sq)\n"
            "  approach  INPUT: afmtwin approach --json output: amplitude, phase lag, the\n"
            "            repulsive peak max(F, 0) and the attractive peak min(F, 0) of the\n"
            "            tip-sample force, and the energy dissipated per period by the\n"
            "            tip-sample forces (E_ts) and, where a record has it, by the squeeze\n"
            "            film (E_sq, its own panel under E_ts) against Z, approach and\n"
            "            retract; each jump an arrow from its last point on the old branch to\n"
            "            its first on the new one (z_before_m to z_after_m; none for a change\n"
            "            of regime with no jump, sharp false); p > 1 and unsettled steps\n"
            "            marked as in sweep. Columns: Z[nm] amplitude[nm] lag[deg]\n"
            "            repulsive_peak[nN] attractive_peak[nN] dissipated[eV] (E_ts)\n"
            "            indentation[nm] max_force[nN] min_force[nN] virial[eV] periodicity\n"
            "            settled[0/1] squeeze_dissipated[eV] (E_sq); set J the jumps.\n"
            "            An approach --mode fm output: the frequency shift, the drive's\n"
            "            change (ppm of the drive at the largest Z: the dissipation channel),\n"
            "            the amplitude against its set-point (ppm) and E_ts against Z; steps\n"
            "            not locked or not settled marked x. Columns: Z[nm]\n"
            "            frequency_shift[Hz] drive_amplitude[pm] amplitude[nm]\n"
            "            amplitude_setpoint[nm] dissipated[eV] locked[0/1] settled[0/1]\n"
            "  thermal   INPUT: a PSD from afmtwin thermal --psd; --fit FILE: its --json\n"
            "            output, whose eq. 5.1 fit per mode is drawn over the PSD (its config\n"
            "            names the model in the title unless --config does)\n"
            "  trace     INPUT: an LCM log of the daemon's outputs (lcm-logger on its\n"
            "            samples URL, or afmtwin replay --out; afmtwin listen only reads\n"
            "            logs): deflection, OBD signal and force of one sample stream\n"
            "            (--stream N, default 0) over --from S --to S of model time (default\n"
            "            the first 2 ms); --z M also draws the gap d = xr + Z (cos alpha 1).\n"
            "            The title states the stream's rate, samples per drive period and\n"
            "            low-pass filter (every channel, the force too: its peaks are in the\n"
            "            harmonics records); under 10 samples per period the samples are\n"
            "            drawn as points, never joined; lost messages (jumps in msg_seq)\n"
            "            are shaded and named, and a window inside them says so. Sample\n"
            "            times are less the filter's delay; the filter's start-up samples\n"
            "            this puts before t = 0 (the run's start) are not drawn\n"
            "  fm        INPUT: an LCM log of the daemon's (or replay's) harmonics records\n"
            "            under FM: the frequency shift, the drive amplitude (the dissipation\n"
            "            channel), the lock-in amplitude and the phase error against model\n"
            "            time (--from S --to S; default the whole log); with the internal\n"
            "            loops (control = fm) their shift and phase error, acquiring and lost\n"
            "            records marked; under an outside controller tone 0's frequency less\n"
            "            its first record's and the lock-in lag (90 deg free at resonance).\n"
            "            Columns: t[ms] frequency_shift[Hz] drive_amplitude[pm]\n"
            "            amplitude[nm] phase[deg] lock_state[-1 none, 0 acquiring, 1\n"
            "            locked, 2 lost] Z[nm] msg_seq. locked: the phase error within\n"
            "            fm.lock_threshold_deg for the lock time; lost: outside it now,\n"
            "            having lost the lock; acquiring: neither yet\n"
            "  spectrum  INPUT: sweep or approach --json output; --index N: the record (step)\n"
            "            to draw, 0 the first (default), -1 the last: harmonic amplitudes\n"
            "  scan      INPUT: afmtwin scan --json output: images (trace) of the height,\n"
            "            phase lag, amplitude error and peak force, x and y in nm at one\n"
            "            scale, the axes ending at the pixels' edges, each with a colour bar\n"
            "            and its unit; the middle line's height profile (trace and retrace)\n"
            "            against the true height; a one-line scan draws profiles only\n"
            "  continue  INPUT: afmtwin continue --json output: the bifurcation diagram,\n"
            "            min(xr) and the amplitude at fe against the parameter, stable solid,\n"
            "            unstable dashed, cut at every change of stability (at the LPC, PD or\n"
            "            NS point found there, else where the largest Floquet multiplier\n"
            "            crosses 1 between the two points), each branch in its own colour,\n"
            "            its legend short, saying its period and where it starts (continue's\n"
            "            branch records: the start, a PD of its parent by its label, e.g.\n"
            "            \"b1 (period 2): P1 of b0\", the end of its parent, or its parent\n"
            "            past a fold beyond the range; \"joins bN\" when it ran onto a branch\n"
            "            computed before); LPC, PD and NS points labelled L1.., P1.., N1.. in\n"
            "            the order found (a label that would overlap another goes up a row,\n"
            "            a thin leader down to its point); with --param2, the curves in the\n"
            "            parameter plane. Zoom: --xrange LO:HI (the parameter in the x axis'\n"
            "            unit: kHz for fe, nm for z and ae) draws that window, each panel's y\n"
            "            fitted to the branches inside it and the labels placed anew;\n"
            "            --yrange LO:HI and --yrange2 LO:HI (nm) fix the y of the min(xr)\n"
            "            and of the amplitude panel; --zoom-pd: x and y those of the\n"
            "            period-doubled branches (period > 1), 3 %% more in x, the\n"
            "            period-1 orbit clipped. --data and --csv keep every row of\n"
            "            the run; under a zoom only $E's label rows are those of the window.\n"
            "  force-curve  INPUT: afmtwin force-curve --json output: the force on the\n"
            "            lever k x against the base Z, approach and retract, snap-in and\n"
            "            pull-off marked, spring constant and adhesion in the title.\n"
            "            Columns: Z[nm] force[nN] deflection[nm]; set E the events\n"
            "  map       MAPFILE: an afmtwin map file's heat maps and Gwyddion files, with\n"
            "            options of its own (afmtwin plot map --help)\n\n"
            "options:\n"
            "  -o, --output FILE  the picture (.png, or .svg)\n"
            "  --title TEXT       the title's first line (default: what the kind draws)\n"
            "  --config FILE      the run's config: the title's second line names it, its\n"
            "                     model's f0, Q and k and the drive (fe, Ae, the free amplitude\n"
            "                     A0, Z); what the records carry wins (a sweep's fe, an\n"
            "                     approach's Z and A0, the continuation parameter)\n"
            "  --fe HZ, --ae M, --z M  the run's own --fe, --ae or --z where it overrode the\n"
            "                     config's (trace: --z is the Z of the gap, and the title's)\n"
            "  --data FILE        the plotted columns: the title and its notes as '# ' lines,\n"
            "                     then the data sets, two blank lines apart, each under a\n"
            "                     '# NAME (CURVE): COLUMN[UNIT] ...' line (CURVE for the\n"
            "                     curves the CSV holds, e.g. approach, retract), its rows\n"
            "                     space separated, NaN for no value (a FILE ending in .csv\n"
            "                     is written as --csv)\n"
            "  --csv FILE         the plotted curve(s) as CSV: one header line of column\n"
            "                     names with their units, e.g. 'fe (kHz),amplitude (nm)', then\n"
            "                     one line per point; a first column 'curve (name)' names the\n"
            "                     curve (forward, retract, ...) where a picture has several\n"
            "  --script FILE      the gnuplot script as run, data inline (gnuplot FILE redraws)\n"
            "  --size WxH         pixels, 100..10000 each (default 1000x750)\n"
            "  --index N, --stream N, --from S, --to S, --fit FILE  as the kinds say\n"
            "  --xrange LO:HI, --yrange LO:HI, --yrange2 LO:HI, --zoom-pd  continue's zoom\n\n"
            "Phase convention: the lag of the deflection behind the drive, 90 deg for a free\n"
            "cantilever at resonance, below 90 in the repulsive regime.\n"
            "Exit status 0 ok, 1 gnuplot or a file failed, 2 bad usage or bad input.\n");
}

int plot_err(const char *fmt, const char *a) {
    fprintf(stderr, "afmtwin plot: ");
    fprintf(stderr, fmt, a);
    fprintf(stderr, "\n");
    return -1;
}

int plot_not_lcm_log(const char *path, long long skipped, const char *fault) {
    if (fault)
        fprintf(stderr, "afmtwin plot: %s: not an LCM log (%s)\n", path, fault);
    else
        fprintf(stderr, "afmtwin plot: %s: not an LCM log (no LCM event in its %lld bytes)\n", path,
                skipped);
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

/* A name gnuplot reads in single quotes: no quotes, backslashes or newlines. */
static int quotable(const char *what, const char *v) {
    if (v && strpbrk(v, "'\"\\\n")) {
        fprintf(stderr, "afmtwin plot: %s '%s': no quotes or backslashes in names\n", what, v);
        return -1;
    }
    return 0;
}

/* --xrange, --yrange, --yrange2 LO:HI (continue): two finite numbers, LO < HI. */
static int parse_range(const char *v, double *lo, double *hi) {
    char end;
    if (sscanf(v, "%lf:%lf%c", lo, hi, &end) != 2 || !isfinite(*lo) || !isfinite(*hi) ||
        !(*lo < *hi)) {
        *lo = *hi = NAN;
        return -1;
    }
    return 0;
}
static int parse_xrange(const char *v, void *dest) {
    plot_opts *o = dest;
    return parse_range(v, &o->range_lo[0], &o->range_hi[0]);
}
static int parse_yrange(const char *v, void *dest) {
    plot_opts *o = dest;
    return parse_range(v, &o->range_lo[1], &o->range_hi[1]);
}
static int parse_yrange2(const char *v, void *dest) {
    plot_opts *o = dest;
    return parse_range(v, &o->range_lo[2], &o->range_hi[2]);
}

/* 0 ok, 1 --help, -1 bad usage (said). */
static int parse_args(int argc, char **argv, plot_opts *o) {
    *o = (plot_opts){.width = 1000,
                     .height = 750,
                     .t_from_s = NAN,
                     .t_to_s = NAN,
                     .z_m = NAN,
                     .fe_hz = NAN,
                     .ae_m = NAN,
                     .range_lo = {NAN, NAN, NAN},
                     .range_hi = {NAN, NAN, NAN}};
    const afmt_opt opts[] = {
        AFMT_ARG("KIND", &o->kind),
        AFMT_ARG_FN("INPUT", add_input, o, "at most 8 inputs"),
        AFMT_STRING("-o", &o->out),
        AFMT_STRING("--output", &o->out),
        AFMT_STRING("--data", &o->data),
        AFMT_STRING("--csv", &o->csv),
        AFMT_STRING("--script", &o->script),
        AFMT_STRING("--fit", &o->fit),
        AFMT_STRING("--title", &o->title),
        AFMT_STRING("--config", &o->config),
        AFMT_FN("--size", parse_size, o, "WxH, 100..10000 pixels each"),
        AFMT_INT("--index", &o->index, -1e9 + 1, 1e9 - 1, NULL),
        AFMT_INT("--stream", &o->stream, 0, 127, NULL),
        AFMT_DOUBLE("--from", &o->t_from_s, 0, 0, NULL),
        AFMT_DOUBLE("--to", &o->t_to_s, 0, 0, NULL),
        AFMT_DOUBLE("--z", &o->z_m, 0, 0, NULL),
        AFMT_DOUBLE("--fe", &o->fe_hz, 0, 1e9, NULL),
        AFMT_DOUBLE("--ae", &o->ae_m, 0, 1e-3, NULL),
        AFMT_FN("--xrange", parse_xrange, o, "LO:HI, LO < HI"),
        AFMT_FN("--yrange", parse_yrange, o, "LO:HI, LO < HI"),
        AFMT_FN("--yrange2", parse_yrange2, o, "LO:HI, LO < HI"),
        AFMT_FLAG("--zoom-pd", &o->zoom_pd),
        AFMT_OPTS_END,
    };
    _Static_assert(PLOT_MAX_INPUTS == 8, "add_input's error text");
    int rc = afmt_opts_parse("plot", opts, argc, argv, 1);
    if (rc) return rc == AFMT_OPTS_HELP ? 1 : -1;
    if (!o->kind)
        return plot_err("%s", "KIND is required (sweep, approach, thermal, trace, fm, spectrum, "
                              "scan, continue, force-curve, map)");
    if (o->n_in == 0) return plot_err("%s", "an INPUT file is required");
    for (int i = 0; i < o->n_in; i++)
        if (quotable("input", o->in[i])) return -1;
    if (!o->out) return plot_err("%s", "-o FILE.png is required");
    for (int i = 0; i < 3; i++)
        if ((!isnan(o->range_lo[i]) || o->zoom_pd) && strcmp(o->kind, "continue"))
            return plot_err("%s",
                            "--xrange, --yrange, --yrange2 and --zoom-pd are continue's options");
    if (quotable("output", o->out) || quotable("--script", o->script) ||
        quotable("--config", o->config))
        return -1;
    return 0;
}

/* ---- data sets ---- */

plot_set *plot_set_new(plot_data *d, const char *name, const char *header, int ncol) {
    if (d->nset == PLOT_MAX_SETS || ncol > PLOT_MAX_COLS) return NULL;
    plot_set *s = &d->set[d->nset++];
    memset(s, 0, sizeof *s);
    snprintf(s->name, sizeof s->name, "%s", name);
    snprintf(s->header, sizeof s->header, "%s", header);
    s->ncol = ncol;
    s->seg_col = -1;
    return s;
}

/* A curve of the CSV, named label there. */
plot_set *plot_curve_new(plot_data *d, const char *name, const char *label, const char *header,
                         int ncol) {
    plot_set *s = plot_set_new(d, name, header, ncol);
    if (s) {
        s->csv = true;
        snprintf(s->label, sizeof s->label, "%s", label);
    }
    return s;
}

int plot_set_row(plot_set *s, const double *row) {
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

double plot_cell(const plot_set *s, size_t r, int c) {
    return s->v[r * (size_t)s->ncol + c];
}

static void data_free(plot_data *d) {
    for (int i = 0; i < d->nset; i++)
        free(d->set[i].v);
}

/* The rows, sep between the numbers; a blank line between segments unless csv (whose
 * rows start with the set's label, if any). */
static void set_write(FILE *f, const plot_set *s, const char *sep, bool csv) {
    for (size_t r = 0; r < s->n; r++) {
        if (!csv && s->seg_col >= 0 && r > 0 &&
            plot_cell(s, r, s->seg_col) != plot_cell(s, r - 1, s->seg_col))
            fputc('\n', f);
        if (csv && s->label[0]) fprintf(f, "%s%s", s->label, sep);
        for (int c = 0; c < s->ncol; c++)
            fprintf(f, "%s%.10g", c ? sep : "", plot_cell(s, r, c));
        fputc('\n', f);
    }
}

/* The CSV: the header line (NAME[UNIT] as "NAME (UNIT)"), then the rows of the curves that
 * share the first curve's columns. 0 ok, -1 no curve. */
static int csv_write(FILE *f, const plot_data *d) {
    int first = -1, curves = 0;
    for (int i = 0; i < d->nset; i++)
        if (d->set[i].csv && (first < 0 || !strcmp(d->set[i].header, d->set[first].header))) {
            if (first < 0) first = i;
            curves++;
        }
    if (first < 0) return -1;
    if (curves > 1) fprintf(f, "curve (name),");
    const char *h = d->set[first].header;
    for (int c = 0; *h; c++) {
        size_t n = strcspn(h, " ");
        const char *u = memchr(h, '[', n);
        if (u && h[n - 1] == ']')
            fprintf(f, "%s%.*s (%.*s)", c ? "," : "", (int)(u - h), h, (int)(h + n - u - 2), u + 1);
        else
            fprintf(f, "%s%.*s", c ? "," : "", (int)n, h);
        h += n;
        h += strspn(h, " ");
    }
    fputc('\n', f);
    for (int i = first; i < d->nset; i++)
        if (d->set[i].csv && !strcmp(d->set[i].header, d->set[first].header)) {
            plot_set s = d->set[i];
            if (curves == 1) s.label[0] = 0;
            set_write(f, &s, ",", true);
        }
    return 0;
}

/* ---- JSON input ---- */

double plot_num(const cJSON *o, const char *key) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsNumber(v) ? v->valuedouble : NAN;
}

bool plot_is_true(const cJSON *o, const char *key) {
    return cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(o, key));
}

bool plot_str_is(const cJSON *o, const char *key, const char *want) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsString(v) && !strcmp(v->valuestring, want);
}

/* Each JSON line of path into fn (objects only; a line that is no JSON is an error). */
int plot_each_json(const char *path, int (*fn)(const cJSON *, void *), void *ctx) {
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

/* max(v, 0) and min(v, 0), NAN kept */
double plot_clip_pos(double v) {
    return isnan(v) ? v : v > 0 ? v : 0.0;
}
double plot_clip_neg(double v) {
    return isnan(v) ? v : v < 0 ? v : 0.0;
}

/* ---- the figure ---- */

/* gnuplot string text: no quotes, backslashes or newlines. */
static void clean(char *s) {
    for (char *p = s; *p; p++)
        if (*p == '\'' || *p == '"' || *p == '\\' || *p == '\n') *p = ' ';
}

void plot_key_add(plot_key *k, const char *with, const char *title) {
    if (k->n == PLOT_MAX_KEYS) return;
    snprintf(k->with[k->n], sizeof k->with[0], "%s", with);
    snprintf(k->title[k->n], sizeof k->title[0], "%s", title);
    clean(k->title[k->n]);
    k->n++;
}

/* The plot area of the next panel, screen fractions. */
void plot_area(FILE *gp, double l, double r, double b, double t) {
    fprintf(gp,
            "set lmargin at screen %.4f\nset rmargin at screen %.4f\nset bmargin at screen "
            "%.4f\nset tmargin at screen %.4f\n",
            l, r, b, t);
}

/* The title and, in a strip under it from l to r, the legend k: an empty plot of its
 * entries. Returns the top of the panels (screen); the panels have no key of their own. */
double plot_figure(FILE *gp, plot_data *d, const plot_key *k, double l, double r) {
    plot_info_line(&d->info, d->sub, sizeof d->sub);
    clean(d->sub);
    fprintf(gp, "set multiplot title \"%s%s%s%s%s%s%s\"\n", d->title, d->sub[0] ? "\\n" : "",
            d->sub, d->note[0] ? "\\n" : "", d->note, d->note2[0] ? "\\n" : "", d->note2);
    int lines = 1 + !!d->sub[0] + !!d->note[0] + !!d->note2[0];
    double y = 1 - (lines * PX_LINE + 12) / d->H; /* under the title */
    if (k->n > 0) {
        int len = 0;
        for (int i = 0; i < k->n; i++)
            if ((int)strlen(k->title[i]) > len) len = (int)strlen(k->title[i]);
        int cols = (int)(((r - l) * d->W - 20) / (len * PX_CHAR + 90));
        cols = cols < 1 ? 1 : cols > k->n ? k->n : cols;
        int rows = (k->n + cols - 1) / cols;
        double h = (rows * PX_LINE + 10) / d->H;
        plot_area(gp, l, r, y - h, y);
        fprintf(gp,
                "unset border\nunset xtics\nunset ytics\nunset xlabel\nunset ylabel\nset xrange "
                "[0:1]\nset yrange [0:1]\nset key at screen %.4f,%.4f center top vertical maxrows "
                "%d Left reverse box samplen 2.5 width 1\nplot -1 notitle",
                0.5 * (l + r), y, rows);
        for (int i = 0; i < k->n; i++)
            fprintf(gp, ", keyentry %s title '%s'", k->with[i], k->title[i]);
        fprintf(gp, "\nunset key\nset border\nset xtics\nset ytics\nset autoscale\n");
        y -= h;
    } else {
        fprintf(gp, "unset key\n");
    }
    return y - 10 / d->H;
}

/* Panel i of n stacked from top to bottom (screen), gap between them. */
void plot_stack(FILE *gp, int i, int n, double l, double r, double bottom, double top, double gap) {
    double h = (top - bottom - (n - 1) * gap) / n;
    double t = top - i * (h + gap);
    plot_area(gp, l, r, t - h, t);
}

/* Panels sharing x: tic labels and the x label only under the last. */
void plot_shared_x(FILE *gp, int i, int n, const char *xlabel) {
    if (i < n - 1)
        fprintf(gp, "set format x ''\nunset xlabel\n");
    else
        fprintf(gp, "set format x\nset xlabel '%s'\n", xlabel);
}

/* y tics for a short panel of column col of the sets: 2 to 5 labels over px pixels (the
 * default would crowd them); the default where the column has no span. */
void plot_short_ytics(FILE *gp, plot_set *const *sets, int n, int col, double px) {
    double lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < n; i++)
        for (size_t r = 0; sets[i] && r < sets[i]->n; r++) {
            double v = plot_cell(sets[i], r, col);
            if (isfinite(v)) lo = fmin(lo, v), hi = fmax(hi, v);
        }
    if (!(hi > lo)) return;
    int most = (int)(px / 28.0); /* intervals over the span */
    most = most < 2 ? 2 : most > 5 ? 5 : most;
    double step = pow(10, floor(log10((hi - lo) / most)));
    static const double m[4] = {1, 2, 5, 10};
    for (int i = 0; i < 4; i++)
        if ((hi - lo) / (step * m[i]) <= most + 1e-9) {
            step *= m[i];
            break;
        }
    fprintf(gp, "set ytics %.6g\n", step);
}

/* Panel p of a 2 x 2 grid (0 top left, 1 top right, 2, 3 below), or with split the last
 * cell cut into two panels sharing x, p 3 over p 4 (the energies, E_ts over E_sq). Sets
 * the x tic labels and xlabel as shared_x; returns the panel's height in pixels. */
double plot_grid_cell(FILE *gp, const plot_data *d, int p, bool split, double l, double r,
                      double top, const char *xlabel) {
    /* rows apart by more than shared x needs: each has its x tics' marks */
    const double bottom = PX_BOTTOM / d->H, gap = (PX_GAP + 12) / d->H;
    const double cell_h = (top - bottom - gap) / 2, half = (cell_h - PX_GAP / d->H) / 2;
    const int cx = p < 4 ? p % 2 : 1;
    double pl = cx ? 0.5 + (PX_LEFT + 15) / d->W : l, pr = cx ? r : 0.5 - 30 / d->W;
    if (split && p >= 3) {
        plot_area(gp, pl, pr, p == 3 ? bottom + cell_h - half : bottom,
                  p == 3 ? bottom + cell_h : bottom + half);
        plot_shared_x(gp, p - 3, 2, xlabel);
        return half * d->H;
    }
    plot_stack(gp, p / 2, 2, pl, pr, bottom, top, gap);
    plot_shared_x(gp, p / 2, 2, xlabel);
    return cell_h * d->H;
}

/* ---- sweep ---- */

static const char *const plot_colour[PLOT_MAX_INPUTS] = {
    "#0072b2", "#d55e00", "#009e73", "#cc79a7", "#e69f00", "#56b4e9", "#000000", "#f0e442"};

typedef struct {
    plot_set *all, *pm, *um;
    plot_info *pi;
    double first, last;
    int n;
    bool *squeeze; /* a record with squeeze film dissipation (its panel is drawn) */
} sweep_ctx;

#define SWEEP_COLS 8
#define SWEEP_HEADER                                                                               \
    "fe[kHz] amplitude[nm] lag[deg] max_force[nN] periodicity[periods] settled[0/1] "              \
    "dissipated[eV] squeeze_dissipated[eV]"

/* A record with the tip-sample energy (sweep --json's cycle): else its panel says so. */
static bool sweep_have_ets;

static int sweep_row(const cJSON *o, void *vctx) {
    sweep_ctx *c = vctx;
    double fe = plot_num(o, "fe_hz"),
           amp = 0.5 * (plot_num(o, "max_deflection_m") - plot_num(o, "min_deflection_m"));
    const cJSON *lk = cJSON_GetObjectItemCaseSensitive(o, "lockin");
    double lag = plot_num(lk, "phase_deg"), p = plot_num(o, "periodicity");
    if (isnan(fe)) return plot_err("%s", "a sweep record without fe_hz (is it sweep --json?)");
    bool settled = plot_is_true(o, "settled");
    /* the last period's energies (cycle is null before a whole period was seen) */
    const cJSON *cy = cJSON_GetObjectItemCaseSensitive(o, "cycle");
    double ets = plot_num(cy, "dissipated_energy_j") / PLOT_EV,
           esq = plot_num(cy, "squeeze_dissipated_energy_j") / PLOT_EV;
    if (isfinite(esq) && esq != 0.0) *c->squeeze = true;
    if (isfinite(ets)) sweep_have_ets = true;
    double row[SWEEP_COLS] = {fe * 1e-3, amp * 1e9,       lag, plot_num(o, "max_force_n") * 1e9,
                              p,         settled ? 1 : 0, ets, esq};
    if (plot_set_row(c->all, row)) return -1;
    if (c->n++ == 0) c->first = fe;
    c->last = fe;
    plot_info_fe(c->pi, fe);
    if (settled && p > 1 && plot_set_row(c->pm, row)) return -1;
    if ((!settled || p == 0) && plot_set_row(c->um, row)) return -1;
    return 0;
}

static int load_sweep(const plot_opts *o, plot_data *d, FILE *gp) {
    sweep_have_ets = false;
    plot_set *pm = plot_set_new(d, "PM", SWEEP_HEADER, SWEEP_COLS),
             *um = plot_set_new(d, "UM", SWEEP_HEADER, SWEEP_COLS);
    plot_set *s[PLOT_MAX_INPUTS];
    bool squeeze = false;
    if (!pm || !um) return -1;
    for (int i = 0; i < o->n_in; i++) {
        char name[16];
        snprintf(name, sizeof name, "S%d", i);
        sweep_ctx c = {s[i] = plot_curve_new(d, name, "", SWEEP_HEADER, SWEEP_COLS),
                       pm,
                       um,
                       &d->info,
                       NAN,
                       NAN,
                       0,
                       &squeeze};
        if (!c.all || plot_each_json(o->in[i], sweep_row, &c)) return -1;
        snprintf(s[i]->label, sizeof s[i]->label, "%s",
                 c.n < 2            ? "one step"
                 : c.last > c.first ? "forward (fe up)"
                                    : "backward (fe down)");
    }
    for (int i = 0; i < o->n_in; i++) /* the same direction twice: numbered */
        for (int j = 0; j < o->n_in; j++)
            if (i != j && !strncmp(s[i]->label, s[j]->label, 8)) {
                char t[48];
                snprintf(t, sizeof t, "%.24s, sweep %d", s[i]->label, i + 1);
                snprintf(s[i]->label, sizeof s[i]->label, "%s", t);
                break;
            }
    plot_key k = {0};
    for (int i = 0; i < o->n_in; i++) {
        char with[64];
        fprintf(gp, "set style line %d lc rgb '%s' lw 1.5 pt 7 ps 0.6\n", i + 1, plot_colour[i]);
        snprintf(with, sizeof with, "with linespoints ls %d", i + 1);
        plot_key_add(&k, with, s[i]->label);
    }
    fprintf(gp, "set style line 11 lc rgb 'red' lw 1.5 pt 6 ps 1.8\n"
                "set style line 12 lc rgb 'black' lw 1.5 pt 2 ps 1.6\n");
    if (pm->n) plot_key_add(&k, "with points ls 11", "period p > 1 (p labelled)");
    if (um->n) plot_key_add(&k, "with points ls 12", "not settled (or periodicity 0)");
    snprintf(d->note, sizeof d->note, "%s",
             squeeze ? "energy dissipated in the last drive period: E_ts by the tip-sample "
                       "forces, E_sq by the squeeze film (air under the beam)"
                     : "E_ts: the energy the tip-sample forces dissipate in the last period");
    snprintf(d->note2, sizeof d->note2, "%s", PLOT_LAG_NOTE);
    const double l = PX_LEFT / d->W, r = 1 - PX_RIGHT / d->W;
    double top = plot_figure(gp, d, &k, l, r);
    /* the energies per period in panels of their own: E_ts (tip-sample) and, where a
     * record has it, E_sq (the squeeze film on the beam), often 10^3 times larger */
    static const struct {
        const char *ylab;
        int col;
    } panel[5] = {{"amplitude (nm)", 2},
                  {"phase lag (deg)", 3},
                  {"max tip-sample force (nN)", 4},
                  {"E_ts tip-sample (eV)", 7},
                  {"E_sq (eV)", 8}};
    for (int p = 0; p < (squeeze ? 5 : 4); p++) {
        const int col = panel[p].col;
        double px = plot_grid_cell(gp, d, p, squeeze, l, r, top, "drive frequency fe (kHz)");
        fprintf(gp, "set ytics autofreq\n");
        if (squeeze && p >= 3) plot_short_ytics(gp, s, o->n_in, col - 1, px);
        /* room over the top points for their p labels */
        fprintf(gp, "set offsets 0, 0, graph %g, 0\nset ylabel '%s'\n",
                p == 0 && pm->n ? 0.12 : 0.0, squeeze && p == 3 ? "E_ts (eV)" : panel[p].ylab);
        if (p == 3 && !sweep_have_ets) { /* no energies in the input (no whole period) */
            fprintf(gp, "set yrange [-1:1]\nset label 1 'no energy per period in the input' at "
                        "graph 0.5, 0.5 center\nplot $S0 using 1:(0) with lines lc rgb 'white' "
                        "notitle\nunset label 1\nset autoscale y\n");
            continue;
        }
        fprintf(gp, "plot ");
        for (int i = 0; i < o->n_in; i++)
            fprintf(gp, "%s$S%d using 1:%d with linespoints ls %d notitle", i ? ", " : "", i, col,
                    i + 1);
        if (pm->n) {
            fprintf(gp, ", $PM using 1:%d with points ls 11 notitle", col);
            if (p == 0)
                fprintf(gp,
                        ", $PM using 1:%d:(sprintf('p %%d', $5)) with labels offset 0,1.3 "
                        "tc rgb 'red' notitle",
                        col);
        }
        if (um->n) fprintf(gp, ", $UM using 1:%d with points ls 12 notitle", col);
        fprintf(gp, "\n");
    }
    fprintf(gp, "unset multiplot\n");
    return 0;
}

/* ---- thermal ---- */

static int load_thermal(const plot_opts *o, plot_data *d, FILE *gp) {
    FILE *f = fopen(o->in[0], "r");
    if (!f) return plot_err("cannot open %s", o->in[0]);
    plot_set *s = plot_curve_new(d, "P", "", "f[Hz] psd[m^2/Hz]", 2);
    char line[256];
    int bad = 0;
    while (s && fgets(line, sizeof line, f)) {
        double row[2];
        if (line[0] == '#') continue;
        if (sscanf(line, "%lf %lf", &row[0], &row[1]) != 2) {
            bad = 1;
            break;
        }
        if (row[0] > 0 && plot_set_row(s, row)) break;
    }
    fclose(f);
    if (!s || bad || s->n == 0) return plot_err("%s is no PSD (afmtwin thermal --psd)", o->in[0]);
    d->info.no_drive = true;
    plot_key k = {0};
    plot_key_add(&k, "with lines lc rgb 'gray40'", "deflection PSD (Welch)");
    char *fit = NULL;
    size_t fit_len = 0;
    FILE *ff = open_memstream(&fit, &fit_len);
    if (!ff) return -1;
    if (o->fit) {
        FILE *jf = fopen(o->fit, "r");
        static char buf[PLOT_LINE_MAX];
        size_t n = jf ? fread(buf, 1, sizeof buf - 1, jf) : 0;
        if (jf) fclose(jf);
        buf[n] = 0;
        cJSON *j = cJSON_Parse(buf);
        const cJSON *ms = cJSON_GetObjectItemCaseSensitive(j, "modes"), *m;
        double T = plot_num(j, "temperature_k");
        if (!cJSON_IsArray(ms) || isnan(T)) {
            cJSON_Delete(j);
            fclose(ff);
            free(fit);
            return plot_err("--fit %s is no afmtwin thermal --json output", o->fit);
        }
        d->info.temperature_k = T;
        d->info.seconds = plot_num(j, "seconds");
        const cJSON *cf = cJSON_GetObjectItemCaseSensitive(j, "config");
        if (!o->config && cJSON_IsString(cf)) { /* the model too where the file is there */
            FILE *t = fopen(cf->valuestring, "r");
            if (t) fclose(t);
            if (!t || plot_info_config(&d->info, cf->valuestring) != 0) {
                const char *bn = strrchr(cf->valuestring, '/');
                snprintf(d->info.config, sizeof d->info.config, "%s",
                         bn ? bn + 1 : cf->valuestring);
            }
        }
        static const char *const fc[4] = {"#d55e00", "#009e73", "#0072b2", "#cc79a7"};
        /* The fit's model folded at the sample rate, as afm_thermfit fits it (images
         * |j fs +- f|, j <= 16; R is even in x). */
        double fs = plot_num(j, "sample_rate_hz");
        if (!(fs > 0)) fs = 0;
        int i = 0;
        cJSON_ArrayForEach(m, ms) {
            double fn = plot_num(m, "f_hz"), q = plot_num(m, "q"), kk = plot_num(m, "k_n_per_m");
            double fl = plot_num(m, "floor_m_rthz");
            char with[64], t[96];
            snprintf(with, sizeof with, "with lines lw 2 lc rgb '%s'", fc[i % 4]);
            const cJSON *nn = cJSON_GetObjectItemCaseSensitive(m, "n");
            /* MHz from 1 MHz: "f 5800.55 kHz" on the axis' 1M tic read badly */
            const bool mhz = fn >= 1e6;
            snprintf(t, sizeof t, "eq. 5.1 fit, mode %d: f %.6g %s, Q %.4g, k %.4g N/m",
                     cJSON_IsNumber(nn) ? nn->valueint : i + 1, fn * (mhz ? 1e-6 : 1e-3),
                     mhz ? "MHz" : "kHz", q, kk);
            plot_key_add(&k, with, t);
            /* eq. 5.1, folded at fs: F(x, f, Q, k, T, fs) defined before the plot */
            double hi = fn * (1 + 8 / q);
            if (fs > 0 && hi > fs / 2) hi = fs / 2;
            fprintf(ff, ", [%g:%g] F(x,%g,%g,%g,%g,%g)+%g**2 with lines lw 2 lc rgb '%s' notitle",
                    fmax(fn * (1 - 8 / q), fn / 8), hi, fn, q, kk, T, fs, fl, fc[i % 4]);
            i++;
        }
        cJSON_Delete(j);
    }
    fclose(ff);
    const double l = PX_LEFT / d->W, r = 1 - PX_RIGHT / d->W;
    double top = plot_figure(gp, d, &k, l, r);
    plot_area(gp, l, r, PX_BOTTOM / d->H, top);
    fprintf(
        gp,
        "set logscale xy\nset format y '%%.0e'\nset format x '%%.0s%%c'\nset autoscale xfix\n"
        "set xlabel 'frequency (Hz)'\nset ylabel 'deflection PSD (m^2/Hz)'\n"
        "R(x,f,q,k,T)=2*1.380649e-23*T/(pi*k*f*q)/((x**2/f**2-1)**2+(x/(f*q))**2)\n"
        "F(x,f,q,k,T,fs)=R(x,f,q,k,T)+(fs>0?sum [j=1:16] (R(j*fs-x,f,q,k,T)+R(j*fs+x,f,q,k,T)):0)\n"
        "plot $P using 1:2 with lines lc rgb 'gray40' notitle%s\nunset multiplot\n",
        fit ? fit : "");
    free(fit);
    return 0;
}

/* ---- spectrum ---- */

typedef struct {
    int want, seen;
    plot_set *s;
    double z, fe, a0, lag0;
} spectrum_ctx;

static int spectrum_row(const cJSON *o, void *vctx) {
    spectrum_ctx *c = vctx;
    const cJSON *hs = cJSON_GetObjectItemCaseSensitive(o, "harmonics"), *h;
    if (!cJSON_IsArray(hs)) return 0; /* a jump record */
    if (c->want >= 0 && c->seen++ != c->want) return 0;
    c->s->n = 0; /* -1: the last one wins */
    c->z = plot_num(o, "z_m");
    c->fe = plot_num(o, "fe_hz");
    c->a0 = plot_num(o, "free_amplitude_m");
    c->lag0 = plot_num(o, "free_phase_lag_deg");
    cJSON_ArrayForEach(h, hs) {
        double a = plot_num(h, "amplitude_m");
        if (isnan(a)) a = plot_num(h, "deflection_amplitude_m");
        double row[2] = {plot_num(h, "k"), a * 1e9};
        if (plot_set_row(c->s, row)) return -1;
    }
    return 0;
}

static int load_spectrum(const plot_opts *o, plot_data *d, FILE *gp) {
    spectrum_ctx c = {.want = o->index,
                      .s = plot_curve_new(d, "H", "", "k[harmonic] amplitude[nm]", 2)};
    if (!c.s || plot_each_json(o->in[0], spectrum_row, &c)) return -1;
    if (c.s->n == 0 && c.seen > 0) { /* say what --index may be */
        fprintf(stderr,
                "afmtwin plot: %s: no record with harmonics at --index %d: it has %d (0..%d; -1 "
                "the last)\n",
                o->in[0], o->index, c.seen, c.seen - 1);
        return -1;
    }
    if (c.s->n == 0) return plot_err("%s: no record with harmonics at that --index", o->in[0]);
    plot_info_z(&d->info, c.z);
    plot_info_fe(&d->info, c.fe);
    d->info.a0_m = c.a0;
    d->info.a0_lag_deg = c.lag0;
    double kmax = 1;
    for (size_t i = 0; i < c.s->n; i++)
        kmax = fmax(kmax, plot_cell(c.s, i, 0));
    plot_key k = {0};
    plot_key_add(&k, "with boxes fill solid 0.6 lc rgb '#0072b2'",
                 "harmonic amplitudes A_k of the deflection");
    const double l = PX_LEFT / d->W, r = 1 - PX_RIGHT / d->W;
    double top = plot_figure(gp, d, &k, l, r);
    plot_area(gp, l, r, PX_BOTTOM / d->H, top);
    fprintf(gp,
            "set logscale y\nset format y '%%.0e'\nset boxwidth 0.6\nset style fill solid 0.6\n"
            "set xlabel 'harmonic k'\nset ylabel 'deflection amplitude (nm)'\nset xtics 1\n"
            "set xrange [0.4:%g]\nplot $H using 1:2 with boxes lc rgb '#0072b2' notitle\n"
            "unset multiplot\n",
            kmax + 0.6);
    return 0;
}

/* ---- force-curve ---- */

typedef struct {
    plot_set *ap, *re, *ev;
    double k_n_m, adhesion_n, speed_m_s;
} fc_ctx;

/* One line of `afmtwin force-curve --json`: a point (approach or retract), an event
 * (snap_in, pull_off) or the summary. */
static int fc_row(const cJSON *o, void *vctx) {
    fc_ctx *c = vctx;
    const cJSON *sum = cJSON_GetObjectItemCaseSensitive(o, "summary");
    if (cJSON_IsObject(sum)) {
        c->k_n_m = plot_num(sum, "spring_constant_n_m");
        c->adhesion_n = plot_num(sum, "adhesion_force_n");
        c->speed_m_s = plot_num(sum, "speed_m_s");
        return 0;
    }
    const cJSON *ev = cJSON_GetObjectItemCaseSensitive(o, "event");
    if (cJSON_IsString(ev)) {
        double kind = !strcmp(ev->valuestring, "snap_in")    ? 1
                      : !strcmp(ev->valuestring, "pull_off") ? 2
                                                             : 0;
        if (kind == 0) return 0;
        double row[3] = {plot_num(o, "z_m") * 1e9, plot_num(o, "force_n") * 1e9, kind};
        return plot_set_row(c->ev, row);
    }
    const cJSON *dir = cJSON_GetObjectItemCaseSensitive(o, "direction");
    double z = plot_num(o, "z_m"), f = plot_num(o, "force_n");
    if (isnan(z) || isnan(f) || !cJSON_IsString(dir))
        return plot_err("%s", "a record without z_m, force_n or direction (afmtwin force-curve "
                              "--json?)");
    double row[3] = {z * 1e9, f * 1e9, plot_num(o, "deflection_m") * 1e9};
    return plot_set_row(strcmp(dir->valuestring, "retract") ? c->ap : c->re, row);
}

/* The quasi-static force-distance curve: the force k x on the lever against the base Z,
 * approach and retract, snap-in and pull-off marked where the run found them, the adhesion
 * (the force at pull-off) stated in the title; the drive is off (no A0). */
static int load_force_curve(const plot_opts *o, plot_data *d, FILE *gp) {
    fc_ctx c = {.ap = plot_curve_new(d, "A", "approach", "Z[nm] force[nN] deflection[nm]", 3),
                .re = plot_curve_new(d, "R", "retract", "Z[nm] force[nN] deflection[nm]", 3),
                .ev = plot_set_new(d, "E", "Z[nm] force[nN] event[1_snap_in_2_pull_off]", 3),
                .k_n_m = NAN,
                .adhesion_n = NAN,
                .speed_m_s = NAN};
    if (!c.ap || !c.re || !c.ev || plot_each_json(o->in[0], fc_row, &c)) return -1;
    if (c.ap->n == 0) return plot_err("%s: no approach points", o->in[0]);
    for (size_t i = 0; i < c.ap->n; i++)
        plot_info_z(&d->info, plot_cell(c.ap, i, 0) * 1e-9);
    d->info.no_drive = true;
    /* the ramp speed in the unit a user sets it in: "30 nm/s", "1 um/s", not "3e-08 m/s" */
    const double v = c.speed_m_s, av = fabs(v);
    const bool nm = av < 1e-6, um = !nm && av < 1e-3;
    snprintf(d->note, sizeof d->note,
             "drive off, Z ramped at %.3g %s; spring k %.4g N/m; adhesion (force at pull-off) "
             "%.4g nN",
             nm   ? v * 1e9
             : um ? v * 1e6
                  : v,
             nm   ? "nm/s"
             : um ? "um/s"
                  : "m/s",
             c.k_n_m, c.adhesion_n * 1e9);
    if (isnan(c.adhesion_n)) snprintf(d->note, sizeof d->note, "drive off; no pull-off found");
    bool snap = false, pull = false;
    for (size_t i = 0; i < c.ev->n; i++) {
        if (plot_cell(c.ev, i, 2) == 1) snap = true;
        if (plot_cell(c.ev, i, 2) == 2) pull = true;
    }
    plot_key k = {0};
    plot_key_add(&k, "with lines lw 2 lc rgb '#0072b2'", "approach");
    plot_key_add(&k, "with lines lw 2 lc rgb '#d55e00'", "retract");
    if (snap) plot_key_add(&k, "with points pt 7 ps 1.5 lc rgb '#009e73'", "snap-in");
    if (pull) plot_key_add(&k, "with points pt 5 ps 1.5 lc rgb 'black'", "pull-off (adhesion)");
    const double l = PX_LEFT / d->W, r = 1 - PX_RIGHT / d->W;
    double top = plot_figure(gp, d, &k, l, r);
    plot_area(gp, l, r, PX_BOTTOM / d->H, top);
    fprintf(gp, "set xlabel 'base separation Z (nm)'\nset ylabel 'force on the lever k x (nN; < 0 "
                "attractive)'\n"
                "set xzeroaxis lt -1 lw 0.5\nset offsets 0, 0, graph 0.05, graph 0.05\n"
                "plot $A using 1:2 with lines lw 2 lc rgb '#0072b2' notitle, "
                "$R using 1:2 with lines lw 2 lc rgb '#d55e00' notitle, "
                "$E using 1:($3 == 1 ? $2 : 1/0) with points pt 7 ps 1.5 lc rgb '#009e73' notitle, "
                "$E using 1:($3 == 2 ? $2 : 1/0) with points pt 5 ps 1.5 lc rgb 'black' notitle\n"
                "unset multiplot\n");
    return 0;
}

/* ---- the command ---- */

static const char *kind_title(const char *kind) {
    static const struct {
        const char *kind, *title;
    } t[] = {{"sweep", "frequency sweep"},
             {"approach", "approach curve"},
             {"thermal", "thermal tune"},
             {"trace", "time trace of the daemon outputs"},
             {"fm", "FM channels of the daemon outputs"},
             {"spectrum", "harmonic spectrum"},
             {"scan", "scan: height, phase lag, amplitude error and peak force"},
             {"continue", "bifurcation diagram"},
             {"force-curve", "force-distance curve"}};
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
        if (!strcmp(kind, t[i].kind)) return t[i].title;
    return kind;
}

/* --data and --csv: 0, or 1 (said). */
static int write_data(const plot_opts *o, const plot_data *d) {
    size_t dl = o->data ? strlen(o->data) : 0;
    bool data_csv = dl > 4 && !strcmp(o->data + dl - 4, ".csv");
    const char *files[2] = {o->data, o->csv};
    for (int i = 0; i < 2; i++) {
        if (!files[i]) continue;
        FILE *df = fopen(files[i], "w");
        if (!df) {
            fprintf(stderr, "afmtwin plot: cannot write %s\n", files[i]);
            return 1;
        }
        if (i == 1 || data_csv) {
            if (csv_write(df, d) != 0) fprintf(stderr, "afmtwin plot: no curve for the CSV\n");
        } else {
            fprintf(df, "# %s%s%s\n", d->title, d->sub[0] ? ": " : "", d->sub);
            if (d->note[0]) fprintf(df, "# %s\n", d->note);
            if (d->note2[0]) fprintf(df, "# %s\n", d->note2);
            for (int s = 0; s < d->nset; s++) {
                fprintf(df, "%s# %s%s%s%s: %s\n", s ? "\n\n" : "", d->set[s].name,
                        d->set[s].label[0] ? " (" : "", d->set[s].label,
                        d->set[s].label[0] ? ")" : "", d->set[s].header);
                set_write(df, &d->set[s], " ", false);
            }
        }
        if (fclose(df) != 0) {
            fprintf(stderr, "afmtwin plot: cannot write %s\n", files[i]);
            return 1;
        }
    }
    return 0;
}

int afm_cmd_plot(int argc, char **argv) {
    if (argc > 1 && !strcmp(argv[1], "map")) /* the map file's heat maps: cmd_map_plot.c */
        return afm_cmd_plot_map(argc - 1, argv + 1);
    plot_opts o;
    int rc = afmt_opts_done("plot", parse_args(argc, argv, &o), plot_usage);
    if (rc >= 0) return rc;
    static const struct {
        const char *kind;
        int (*load)(const plot_opts *, plot_data *, FILE *);
    } kinds[] = {
        {"sweep", load_sweep},       {"approach", load_approach},       {"thermal", load_thermal},
        {"trace", load_trace},       {"spectrum", load_spectrum},       {"scan", load_scan},
        {"continue", load_continue}, {"force-curve", load_force_curve}, {"fm", load_fm}};
    int k = -1;
    for (int i = 0; i < (int)(sizeof kinds / sizeof kinds[0]); i++)
        if (!strcmp(o.kind, kinds[i].kind)) k = i;
    if (k < 0) {
        fprintf(stderr,
                "afmtwin plot: unknown kind '%s' (sweep, approach, thermal, trace, fm, "
                "spectrum, scan, continue, force-curve, map)\n",
                o.kind);
        return 2;
    }
    static plot_data d;
    memset(&d, 0, sizeof d);
    d.W = o.width;
    d.H = o.height;
    snprintf(d.title, sizeof d.title, "%s", o.title ? o.title : kind_title(o.kind));
    clean(d.title);
    plot_info_init(&d.info);
    if (o.config && plot_info_config(&d.info, o.config) != 0) return 2;
    d.info.opt_fe_hz = o.fe_hz;
    d.info.opt_ae_m = o.ae_m;
    d.info.opt_z_m = o.z_m;
    /* the plot commands first into memory: the data blocks go before them */
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
    int status = write_data(&o, &d);
    /* the whole script: terminal, data blocks, commands */
    char *script = NULL;
    size_t script_len = 0;
    FILE *sf = status ? NULL : open_memstream(&script, &script_len);
    if (sf) {
        size_t ol = strlen(o.out);
        bool svg = ol > 4 && !strcmp(o.out + ol - 4, ".svg");
        fprintf(sf, "set terminal %s size %d,%d noenhanced\nset output '%s'\nset grid\n",
                svg ? "svg" : "pngcairo", o.width, o.height, o.out);
        for (int i = 0; i < d.nset; i++) { /* empty sets are still defined (one NaN row) */
            fprintf(sf, "$%s << EOD\n", d.set[i].name);
            set_write(sf, &d.set[i], " ", false);
            if (d.set[i].n == 0) {
                for (int c = 0; c < d.set[i].ncol; c++)
                    fprintf(sf, c ? " NaN" : "NaN");
                fputc('\n', sf);
            }
            fprintf(sf, "EOD\n");
        }
        fwrite(cmds, 1, cmds_len, sf);
        fprintf(sf, "set output\n");
        if (fclose(sf) != 0) status = 1;
    } else {
        status = 1;
    }
    if (!status && o.script) {
        FILE *f = fopen(o.script, "w");
        bool ok = f && fwrite(script, 1, script_len, f) == script_len;
        if (f && fclose(f) != 0) ok = false;
        if (!ok) {
            fprintf(stderr, "afmtwin plot: cannot write %s\n", o.script);
            status = 1;
        }
    }
    FILE *gp = status ? NULL : popen("gnuplot", "w");
    if (gp) {
        fwrite(script, 1, script_len, gp);
        int grc = pclose(gp);
        if (grc != 0) {
            fprintf(stderr, "afmtwin plot: gnuplot failed (status %d)\n", grc);
            status = 1;
        }
    } else if (!status) {
        fprintf(stderr, "afmtwin plot: cannot run gnuplot (package gnuplot-nox)\n");
        status = 1;
    }
    free(script);
    free(cmds);
    data_free(&d);
    return status;
}
