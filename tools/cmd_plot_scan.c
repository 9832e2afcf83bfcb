/* SPDX-License-Identifier: MIT */
/* cmd_plot_scan.c -- `afmtwin plot scan`: the images of `afmtwin scan --json` (controller
 * height, true height, phase lag, amplitude error, peak force, dissipated energy) with a
 * colour bar each, x and y at one scale, and a line profile against the true topography. A
 * file of its own because the image layout (equal aspect, tics fitted to the pixel grid)
 * is shared with no other kind; it uses only the data sets, the JSON reader and the layout
 * of cmd_plot.h. Phases are the lag of the deflection behind the drive (90 deg free at
 * resonance). */
#include "cmd_plot.h"
#include "plot_info.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- scan ---- */

#define SCAN_COLS 9
#define SCAN_HEADER                                                                                \
    "x[nm] y[nm] line[index] height[nm] true_height[nm] lag[deg] error[nm] peak_force[nN] "        \
    "dissipated[eV]"

typedef struct {
    plot_set *tr, *re;
    int lines;
    plot_info *pi;
} scan_ctx;

static int scan_row(const cJSON *o, void *vctx) {
    scan_ctx *c = vctx;
    double line = plot_num(o, "line");
    if (isnan(line) || isnan(plot_num(o, "height_m")))
        return plot_err("%s", "a record without line or height_m (afmtwin scan --json?)");
    if (line + 1 > c->lines) c->lines = (int)line + 1;
    if (!isfinite(c->pi->a0_m)) c->pi->a0_m = plot_num(o, "free_amplitude_m");
    double row[SCAN_COLS] = {plot_num(o, "x_m") * 1e9,
                             plot_num(o, "y_m") * 1e9,
                             line,
                             plot_num(o, "height_m") * 1e9,
                             plot_num(o, "true_height_m") * 1e9,
                             plot_num(o, "phase_lag_deg"),
                             plot_num(o, "error_m") * 1e9,
                             plot_num(o, "peak_force_n") * 1e9,
                             plot_num(o, "dissipated_energy_j") / PLOT_EV};
    return plot_set_row(plot_is_true(o, "retrace") ? c->re : c->tr, row);
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

/* A 1-2-5 tic step for an axis of span (data units) drawn px pixels long, each label and
 * the room to the next lab pixels: at most 5 labels, and as many as fit apart (two at
 * least: then the step is the span). */
static double tic_step(double span, double px, double lab) {
    if (!(span > 0)) return 1;
    int most = (int)(px / lab); /* labels */
    most = most < 2 ? 2 : most > 5 ? 5 : most;
    double step = pow(10, floor(log10(span / most)));
    static const double m[4] = {1, 2, 5, 10};
    for (int i = 0; i < 4; i++)
        if (span / (step * m[i]) <= most - 1 + 1e-9) return step * m[i] > span ? span : step * m[i];
    return span;
}

/* Characters of the longer %g label of a and b. */
static int label_chars(double a, double b) {
    char s[2][32];
    int na = snprintf(s[0], sizeof s[0], "%g", a), nb = snprintf(s[1], sizeof s[1], "%g", b);
    return na > nb ? na : nb;
}

/* The largest rectangle of aspect (height / width) in the box l..r x b..t (screen), at its
 * top, centred across (shift: what it moved right): the plot area of an image with square
 * nm. Its left, right and bottom edges out. */
static void aspect_area(FILE *gp, const plot_data *d, double l, double r, double b, double t,
                        double aspect, double *al, double *ar, double *ab) {
    double w = (r - l) * d->W, h = (t - b) * d->H;
    if (h > w * aspect)
        h = w * aspect;
    else
        w = h / aspect;
    *al = l + 0.5 * ((r - l) - w / d->W);
    *ar = *al + w / d->W;
    *ab = t - h / d->H;
    plot_area(gp, *al, *ar, *ab, t);
}

int load_scan(const plot_opts *o, plot_data *d, FILE *gp) {
    scan_ctx c = {plot_curve_new(d, "T", "trace", SCAN_HEADER, SCAN_COLS),
                  plot_curve_new(d, "R", "retrace", SCAN_HEADER, SCAN_COLS), 0, &d->info};
    if (!c.tr || !c.re || plot_each_json(o->in[0], scan_row, &c)) return -1;
    if (c.tr->n == 0) return plot_err("%s: no trace pixels", o->in[0]);
    d->info.no_z = true;
    snprintf(d->note, sizeof d->note, "%s", PLOT_LAG_NOTE);
    scan_line_y(c.tr, c.lines);
    /* the profile: the middle line's trace and retrace against the truth */
    int mid = c.lines / 2;
    plot_set *pt = plot_set_new(d, "PT", SCAN_HEADER, SCAN_COLS),
             *pr = plot_set_new(d, "PR", SCAN_HEADER, SCAN_COLS);
    if (!pt || !pr) return -1;
    for (size_t i = 0; i < c.tr->n; i++)
        if (c.tr->v[i * SCAN_COLS + 2] == mid && plot_set_row(pt, c.tr->v + i * SCAN_COLS))
            return -1;
    for (size_t i = 0; i < c.re->n; i++)
        if (c.re->v[i * SCAN_COLS + 2] == mid && plot_set_row(pr, c.re->v + i * SCAN_COLS))
            return -1;
    /* unit: the colour bar's label; ylab: the profile's axis (room for the error's sign) */
    static const struct {
        const char *title, *unit, *ylab;
        int col;
    } img[4] = {{"height", "height (nm)", "height (nm)", 4},
                {"phase lag", "phase lag (deg)", "phase lag (deg)", 6},
                {"amplitude error", "set-point - A (nm)", "amplitude error: set-point - A (nm)", 7},
                {"peak force", "peak force (nN)", "peak force (nN)", 8}};
    /* the pixels' edges: half a pixel pitch (line pitch in y) beyond the outer centres */
    double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
    for (size_t i = 0; i < c.tr->n; i++) {
        x0 = fmin(x0, c.tr->v[i * SCAN_COLS]);
        x1 = fmax(x1, c.tr->v[i * SCAN_COLS]);
        y0 = fmin(y0, c.tr->v[i * SCAN_COLS + 1]);
        y1 = fmax(y1, c.tr->v[i * SCAN_COLS + 1]);
    }
    double dx = x1 > x0 && pt->n > 1 ? (x1 - x0) / (double)(pt->n - 1) : 1;
    double dy = c.lines > 1 ? (y1 - y0) / (c.lines - 1) : dx;
    x0 -= dx / 2, x1 += dx / 2, y0 -= dy / 2, y1 += dy / 2;
    if (fabs(x0) < 1e-6 * (x1 - x0)) x0 = 0; /* rounding: an edge at 0 is 0 */
    if (fabs(y0) < 1e-6 * (y1 - y0)) y0 = 0;
    fprintf(gp, "set style line 1 lc rgb 'black' lw 2\nset style line 2 lc rgb '#0072b2' lw 1.5 "
                "pt 7 ps 0.5\nset style line 3 lc rgb '#d55e00' lw 1.5 pt 6 ps 0.6\n");
    plot_key none = {0};
    const double W = d->W, H = d->H;
    const double top = plot_figure(gp, d, &none, 0, 1);
    char xr[96];
    snprintf(xr, sizeof xr, "set xrange [%.6g:%.6g]\n", x0, x1);
    /* the profile's legend: right of it */
    static const char key[] =
        "set key at screen %.4f,%.4f left top vertical Left reverse box samplen 2.5\n";
    if (c.lines == 1) { /* profiles only, two by two */
        const double kr = 1 - 190 / W, h = (top - PX_BOTTOM / H - PX_LINE / H) / 2;
        for (int p = 0; p < 4; p++) {
            double cl = p % 2 ? 0.5 + 60 / W : PX_LEFT / W, cr = p % 2 ? kr : 0.5 - 40 / W;
            double t = top - (p / 2) * (h + PX_LINE / H);
            plot_area(gp, cl, cr, t - h + (p < 2 ? (PX_BOTTOM - 10) / H : 0), t);
            /* tics that fit the panel's width (gnuplot's own ran "100150200" together) */
            double xs = tic_step(x1 - x0, (cr - cl) * W, label_chars(x0, x1) * PX_CHAR + 12);
            fprintf(gp, "%sset xtics %g\nset xlabel 'x (nm)'\nset ylabel '%s'\n", xr, xs,
                    img[p].ylab);
            if (p == 0) fprintf(gp, key, kr + 12 / W, top);
            fprintf(gp,
                    "plot $PT using 1:%d with linespoints ls 2 %s, $PR using 1:%d with "
                    "linespoints ls 3 %s%s\nunset key\n",
                    img[p].col, p ? "notitle" : "title 'trace'", img[p].col,
                    p ? "notitle" : "title 'retrace'",
                    p ? "" : ", $PT using 1:5 with lines ls 1 title 'true height'");
        }
        fprintf(gp, "unset multiplot\n");
        return 0;
    }
    /* the images two by two, the two in a column sharing the x tic labels, the profile
     * under them */
    const double aspect = (y1 - y0) / (x1 - x0);
    const double prof_h = 0.2 * top, img_bot = PX_BOTTOM / H + prof_h + 12 / H;
    const double title = (PX_LINE + 8) / H, xlab = (PX_BOTTOM + 6) / H;
    const double img_h = (top - img_bot - 2 * title - 12 / H - xlab) / 2;
    for (int p = 0; p < 4; p++) {
        /* the plot area: under the panel's title, right of its y labels, left of its
         * colour bar */
        double cl = (p % 2) * 0.5, t = top - title - (p / 2) * (img_h + 12 / H + title);
        double l = cl + 70 / W, r = cl + 0.5 - 110 / W, al, ar, ab;
        aspect_area(gp, d, l, r, t - img_h, t, aspect, &al, &ar, &ab);
        double xs = tic_step(x1 - x0, (ar - al) * W, label_chars(x0, x1) * PX_CHAR + 12);
        double ys = tic_step(y1 - y0, (t - ab) * H, PX_LINE + 8);
        plot_shared_x(gp, p / 2, 2, "x (nm)");
        fprintf(gp,
                "set size ratio -1\nset autoscale fix\n%sset yrange [%.6g:%.6g]\nset xtics %g\n"
                "set ytics %g\nset ylabel 'y (nm)'\nset title '%s (trace)'\nset cblabel '%s'\n"
                "set colorbox user origin screen %.4f,%.4f size screen %.4f,%.4f\nplot $T using "
                "1:2:%d with image notitle\nset size noratio\n",
                xr, y0, y1, xs, ys, img[p].title, img[p].unit, ar + 10 / W, ab, 18 / W, t - ab,
                img[p].col);
    }
    const double pl = 70 / W, prr = 1 - 190 / W, ptop = PX_BOTTOM / H + prof_h - (PX_LINE + 8) / H;
    plot_area(gp, pl, prr, PX_BOTTOM / H, ptop);
    fprintf(gp,
            "set autoscale y\nset xtics auto\nset ytics auto\n%sset xlabel 'x (nm)'\nset ylabel "
            "'height (nm)'\nset title 'line %d: height against the truth'\n",
            xr, mid);
    fprintf(gp, key, prr + 12 / W, ptop);
    fprintf(gp, "plot $PT using 1:5 with lines ls 1 title 'true height', $PT using 1:4 with "
                "linespoints ls 2 title 'trace', $PR using 1:4 with linespoints ls 3 title "
                "'retrace'\nunset key\nunset multiplot\n");
    return 0;
}
