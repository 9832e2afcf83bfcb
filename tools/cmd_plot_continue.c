/* SPDX-License-Identifier: MIT */
/* cmd_plot_continue.c -- `afmtwin plot continue`: the bifurcation diagram of `afmtwin
 * continue --json` (min(xr) and the amplitude against the parameter, each branch cut at
 * every change of stability, the LPC, PD and NS points labelled) and, of a two-parameter run,
 * its curves. A file of its own because it is the largest kind, with its own records and
 * segmenting, and shares only the data sets and the layout (cmd_plot.h) with the others. */
#include "cmd_plot.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- continue ---- */

#define CONT_PLOT_BRANCHES 32 /* continue --max-branches' bound */

/* A point or a bifurcation of a branch, in the order of the file. */
typedef struct {
    int branch, period, event; /* event: 0 a point, 1 LPC, 2 PD, 3 NS */
    bool stable;
    double x, mn, am, mu; /* mu: the largest |multiplier| (NAN unknown) */
} cont_rec;

typedef struct {
    plot_set *ev, *cv;
    cont_rec *rec;
    size_t n, cap;
    int count[4];  /* events so far per type, for their labels */
    double scale;  /* of the parameter: 1e-3 for fe (kHz), 1e9 for z and ae (nm) */
    char name[32]; /* the parameter */
    double scale2; /* of the second parameter (--param2) */
    char name2[64];
    int curve, side; /* of the previous curve point (-1: none) */
    double start[4]; /* the row of the current curve's first point (its start) */
    int ncurve[3];   /* curve points per kind (1 LPC, 2 PD) */
    int max_period;
    plot_info *pi;
    /* how each branch was reached (its "branch" record) and what it ran onto ("end") */
    struct {
        bool have;
        char via[8];
        int parent, period, joined;
        double via_param;
    } br[CONT_PLOT_BRANCHES];
    int n_branch; /* 1 + the largest branch index seen */
} cont_ctx;

static double param_scale(const char *name) {
    return !strcmp(name, "fe") ? 1e-3 : !strcmp(name, "z") || !strcmp(name, "ae") ? 1e9 : 1.0;
}

static const char *scale_unit(double scale) {
    return scale == 1e-3 ? "kHz" : scale == 1e9 ? "nm" : scale == 1e12 ? "pm" : "SI";
}

/* Columns of a curve_point: param, param2 (scaled), kind (1 LPC, 2 PD), curve index. A NaN
 * row between curves and sides; side 1 starts again at the curve's start point, so that the
 * two sides draw as one line. */
static int curve_row(cont_ctx *c, const cJSON *o) {
    const cJSON *n2 = cJSON_GetObjectItemCaseSensitive(o, "param2_name");
    if (cJSON_IsString(n2)) {
        snprintf(c->name2, sizeof c->name2, "%s", n2->valuestring);
        c->scale2 = param_scale(n2->valuestring);
    }
    const cJSON *kd = cJSON_GetObjectItemCaseSensitive(o, "kind");
    double x = plot_num(o, "param") * c->scale, y = plot_num(o, "param2") * c->scale2;
    int cv = (int)plot_num(o, "curve"), side = (int)plot_num(o, "side");
    if (isnan(x) || isnan(y) || !cJSON_IsString(kd))
        return plot_err("%s", "a curve_point record without param, param2 or kind");
    int k = !strcmp(kd->valuestring, "PD") ? 2 : 1;
    static const double gap[4] = {NAN, NAN, NAN, NAN};
    double row[4] = {x, y, k, cv};
    if (cv != c->curve) {
        if (c->curve >= 0 && plot_set_row(c->cv, gap)) return -1;
        memcpy(c->start, row, sizeof row);
    } else if (side != c->side && (plot_set_row(c->cv, gap) || plot_set_row(c->cv, c->start))) {
        return -1;
    }
    c->curve = cv;
    c->side = side;
    c->ncurve[k]++;
    return plot_set_row(c->cv, row);
}

/* The largest modulus of a point's multipliers ([[re, im], ...]). */
static double max_multiplier(const cJSON *o) {
    const cJSON *ms = cJSON_GetObjectItemCaseSensitive(o, "multipliers"), *m;
    double best = NAN;
    cJSON_ArrayForEach(m, ms) {
        const cJSON *re = cJSON_GetArrayItem(m, 0), *im = cJSON_GetArrayItem(m, 1);
        if (!cJSON_IsNumber(re) || !cJSON_IsNumber(im)) continue;
        double a = hypot(re->valuedouble, im->valuedouble);
        if (!(best >= a)) best = a;
    }
    return best;
}

static int continue_row(const cJSON *o, void *vctx) {
    cont_ctx *c = vctx;
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(o, "type");
    if (!cJSON_IsString(t)) return plot_err("%s", "a record without type (continue --json?)");
    const cJSON *pn = cJSON_GetObjectItemCaseSensitive(o, "param_name");
    if (cJSON_IsString(pn)) {
        snprintf(c->name, sizeof c->name, "%s", pn->valuestring);
        c->scale = param_scale(pn->valuestring);
    }
    const char *ty = t->valuestring;
    double bn = plot_num(o, "branch");
    int bi = isfinite(bn) && bn >= 0 && bn < CONT_PLOT_BRANCHES ? (int)bn : -1;
    if (bi >= 0 && !strcmp(ty, "branch")) { /* how the branch was reached: its legend */
        const cJSON *via = cJSON_GetObjectItemCaseSensitive(o, "via");
        c->br[bi].have = true;
        snprintf(c->br[bi].via, sizeof c->br[bi].via, "%s",
                 cJSON_IsString(via) ? via->valuestring : "?");
        c->br[bi].parent = (int)plot_num(o, "parent");
        c->br[bi].via_param = plot_num(o, "via_param");
        c->br[bi].joined = -1;
        return 0;
    }
    if (bi >= 0 && !strcmp(ty, "end")) {
        double j = plot_num(o, "joined");
        if (isfinite(j)) c->br[bi].joined = (int)j;
        return 0;
    }
    if (!strcmp(ty, "summary") || !strcmp(ty, "end") || !strcmp(ty, "curve_end") ||
        !strcmp(ty, "branch"))
        return 0;
    if (!strcmp(ty, "curve_point")) return curve_row(c, o);
    double x = plot_num(o, "param"), mn = plot_num(o, "min_deflection_m") * 1e9,
           am = plot_num(o, "amplitude_m") * 1e9;
    if (isnan(x) || isnan(mn)) return plot_err("%s", "a continue record without param");
    plot_info_param(c->pi, c->name[0] ? c->name : "param", x);
    x *= c->scale;
    int ev = !strcmp(ty, "point") ? 0 : !strcmp(ty, "LPC") ? 1 : !strcmp(ty, "PD") ? 2 : 3;
    if (ev) {
        double row[6] = {x, mn, am, ev, ++c->count[ev], 0};
        if (plot_set_row(c->ev, row)) return -1;
    }
    if (c->n == c->cap) {
        size_t cap = c->cap ? 2 * c->cap : 256;
        cont_rec *r = realloc(c->rec, cap * sizeof *r);
        if (!r) return -1;
        c->rec = r;
        c->cap = cap;
    }
    double per = plot_num(o, "period");
    int period = isfinite(per) && per >= 1 ? (int)per : 1;
    if (period > c->max_period) c->max_period = period;
    if (bi >= 0) {
        c->br[bi].period = period;
        if (bi + 1 > c->n_branch) c->n_branch = bi + 1;
    }
    c->rec[c->n++] = (cont_rec){.branch = (int)plot_num(o, "branch"),
                                .period = period,
                                .event = ev,
                                .stable = plot_is_true(o, "stable"),
                                .x = x,
                                .mn = mn,
                                .am = am,
                                .mu = ev ? NAN : max_multiplier(o)};
    return 0;
}

/* One row of the branch set: param, min_x, amplitude, stable, branch, period, segment. */
static int branch_row(plot_set *s, const cont_rec *r, bool stable, int seg) {
    double row[7] = {r->x, r->mn, r->am, stable ? 1 : 0, r->branch, r->period, seg};
    return plot_set_row(s, row);
}

/* The branches cut into segments of one stability each. Where the stability of two
 * consecutive points of a branch differs, the segments meet at the bifurcation found
 * between them (the first, if several), else where the largest multiplier modulus crosses
 * 1 on the straight line between them (half way if unknown); that point ends the one
 * segment and starts the next. A bifurcation where the stability does not change is a
 * point of its segment. */
static int continue_segments(const cont_ctx *c, plot_set *b) {
    int seg = 0;
    for (size_t i = 0; i < c->n; i++) {
        int br = c->rec[i].branch;
        bool seen = false; /* an earlier record of this branch: done with it */
        for (size_t j = 0; j < i && !seen; j++)
            seen = c->rec[j].branch == br;
        if (seen) continue;
        int st = -1;             /* the segment's stability (-1: no point yet) */
        size_t pend[64], np = 0; /* events since the last point */
        const cont_rec *last = NULL;
        for (size_t j = i; j < c->n; j++) {
            const cont_rec *r = &c->rec[j];
            if (r->branch != br) continue;
            if (r->event) {
                if (np < sizeof pend / sizeof pend[0]) pend[np++] = j;
                continue;
            }
            size_t e0 = 0;
            if (st >= 0 && last && r->stable != (st == 1)) {
                cont_rec cut;
                if (np > 0) {
                    cut = c->rec[pend[0]];
                    e0 = 1;
                } else {
                    double u = 0.5;
                    if (isfinite(last->mu) && isfinite(r->mu) && (last->mu - 1) * (r->mu - 1) < 0)
                        u = (1 - last->mu) / (r->mu - last->mu);
                    cut = *r;
                    cut.x = last->x + u * (r->x - last->x);
                    cut.mn = last->mn + u * (r->mn - last->mn);
                    cut.am = last->am + u * (r->am - last->am);
                }
                cut.branch = br;
                cut.period = r->period;
                if (branch_row(b, &cut, st == 1, seg) || branch_row(b, &cut, r->stable, ++seg))
                    return -1;
                st = r->stable;
            }
            if (st < 0) st = r->stable;
            for (size_t e = e0; e < np; e++)
                if (branch_row(b, &c->rec[pend[e]], st == 1, seg)) return -1;
            np = 0;
            if (branch_row(b, r, st == 1, seg)) return -1;
            last = r;
        }
        for (size_t e = 0; e < np && st >= 0; e++) /* events after the last point */
            if (branch_row(b, &c->rec[pend[e]], st == 1, seg)) return -1;
        seg++;
    }
    return 0;
}

/* Event i of ev lies in the picture's window (x, and y in either panel): its label and
 * marker are drawn, and only those take part in the placing of the labels (both panels
 * share the rows, so one drawn in either panel counts). */
static bool cont_in_window(const plot_set *ev, size_t i, double xlo, double xhi,
                           const double ylo[2], const double yhi[2]) {
    double x = plot_cell(ev, i, 0);
    bool in_y = false;
    for (int p = 0; p < 2; p++)
        in_y = in_y || (plot_cell(ev, i, 1 + p) >= ylo[p] && plot_cell(ev, i, 1 + p) <= yhi[p]);
    return x >= xlo && x <= xhi && in_y;
}

/* The rows of the bifurcation labels (ev's column 6): each label ("L7": type letter and
 * count, drawn 1 character right of and 1 line over its point, row steps of 0.09 of the
 * panel's y span higher) takes the lowest row where, in both panels, it overlaps no label
 * placed before it and no event's marker; boxes estimated from PX_CHAR and PX_LINE on a
 * panel w_px wide, with half a character to spare (issue 30: "P2P6" ran together, and a
 * column of labels stood over a cluster of points at no distance one could read). */
static void continue_label_rows(plot_set *ev, double xlo, double xhi, const double ylo[2],
                                const double yhi[2], double w_px, bool zoom) {
    double cw = w_px > 0 && xhi > xlo ? PX_CHAR / w_px * (xhi - xlo) : 0.0;
    for (size_t i = 0; i < ev->n; i++) {
        double xi = plot_cell(ev, i, 0), wi = (plot_cell(ev, i, 4) >= 10 ? 3.0 : 2.0) * cw;
        int row = 0;
        ev->v[i * 6 + 5] = 0;
        if (zoom && !cont_in_window(ev, i, xlo, xhi, ylo, yhi)) continue; /* not drawn */
        for (; row < 40; row++) {
            bool clash = false;
            for (int p = 0; p < 2 && !clash; p++) {
                double step = yhi[p] > ylo[p] ? 0.09 * (yhi[p] - ylo[p]) : 1.0;
                double yi = plot_cell(ev, i, 1 + p) / step + row + 0.5; /* the box: [yi, yi + 1] */
                for (size_t j = 0; j < ev->n && !clash; j++) {
                    if (zoom && !cont_in_window(ev, j, xlo, xhi, ylo, yhi)) continue;
                    double xj = plot_cell(ev, j, 0), yj = plot_cell(ev, j, 1 + p) / step;
                    /* j's marker, a character square about its point */
                    if (j != i && xi + cw - 0.5 * cw < xj + 0.6 * cw &&
                        xj - 0.6 * cw < xi + cw + wi + 0.5 * cw && yi < yj + 0.5 &&
                        yj - 0.5 < yi + 1)
                        clash = true;
                    if (j >= i) continue;
                    /* j's label, placed */
                    double wj = (plot_cell(ev, j, 4) >= 10 ? 3.0 : 2.0) * cw,
                           yl = yj + plot_cell(ev, j, 5) + 0.5;
                    if (xi + cw < xj + cw + wj + 0.5 * cw && xj + cw < xi + cw + wi + 0.5 * cw &&
                        yi < yl + 1 && yl < yi + 1)
                        clash = true;
                }
            }
            if (!clash) break;
        }
        ev->v[i * 6 + 5] = row;
    }
}

/* The label ("P3") of the event of type (1 LPC, 2 PD, 3 NS) at the parameter x (scaled),
 * on branch br (-1: any), within 1e-6 of x: its letter and its count in the file's order,
 * as drawn beside its point; 0 if there is none (t is then ""). */
static int cont_event_label(const cont_ctx *c, int type, int br, double x, char *t, size_t n) {
    int k = 0;
    t[0] = 0;
    for (size_t i = 0; i < c->n; i++) {
        if (c->rec[i].event != type) continue;
        k++;
        if ((br < 0 || c->rec[i].branch == br) &&
            fabs(c->rec[i].x - x) <= 1e-6 * fmax(fabs(x), 1e-300)) {
            snprintf(t, n, "%c%d", "LPN"[type - 1], k);
            return k;
        }
    }
    return 0;
}

/* The legend of branch b, short (the legend is one strip for all panels, and a long entry
 * takes a column of its own): its period and where it starts, by the label of the event
 * drawn there: "b1 (period 2): P1 of b0, joins b2"; the parameter where no label names it. */
static void cont_branch_label(const cont_ctx *c, int b, char *t, size_t n) {
    const char *u = scale_unit(c->scale);
    double v = c->br[b].via_param * c->scale;
    char at[16], val[40];
    snprintf(val, sizeof val, "%.5g %s", v, u);
    int parent = c->br[b].parent, w = snprintf(t, n, "b%d (period %d)", b, c->br[b].period);
    if (w < 0 || (size_t)w >= n) return;
    const char *via = c->br[b].have ? c->br[b].via : "";
    if (!strcmp(via, "start"))
        w += snprintf(t + w, n - (size_t)w, ": start");
    else if (!strcmp(via, "PD"))
        w += snprintf(t + w, n - (size_t)w, ": %s of b%d",
                      cont_event_label(c, 2, parent, v, at, sizeof at) ? at : val, parent);
    else if (!strcmp(via, "end"))
        w += snprintf(t + w, n - (size_t)w, ": %s, end of b%d",
                      cont_event_label(c, 2, -1, v, at, sizeof at) ? at : val, parent);
    else if (!strcmp(via, "fold"))
        w += snprintf(t + w, n - (size_t)w, ": b%d past its fold", parent);
    if (c->br[b].have && c->br[b].joined >= 0 && w > 0 && (size_t)w < n)
        snprintf(t + w, n - (size_t)w, ", joins b%d", c->br[b].joined);
}

int load_continue(const plot_opts *o, plot_data *d, FILE *gp) {
    cont_ctx c = {.ev = plot_set_new(d, "E", "", 6),
                  .cv = plot_set_new(d, "C", "", 4),
                  .scale = 1.0,
                  .scale2 = 1.0,
                  .curve = -1,
                  .side = -1,
                  .max_period = 1,
                  .pi = &d->info};
    int rc = (!c.ev || !c.cv) ? -1 : plot_each_json(o->in[0], continue_row, &c);
    size_t points = 0;
    for (size_t i = 0; i < c.n; i++)
        points += c.rec[i].event == 0;
    if (rc == 0 && points == 0) rc = plot_err("%s: no point records", o->in[0]);
    const char *pname = c.name[0] ? c.name : "param", *u = scale_unit(c.scale);
    char hdr[200];
    snprintf(hdr, sizeof hdr,
             "%s[%s] min_x[nm] amplitude[nm] stable[0/1] branch[index] period[periods] "
             "segment[index]",
             pname, u);
    plot_set *b = rc ? NULL : plot_curve_new(d, "B", "", hdr, 7);
    if (b) b->seg_col = 6;
    if (rc == 0 && (!b || continue_segments(&c, b))) rc = -1;
    char blab[CONT_PLOT_BRANCHES][96]; /* the branches' legends (they need c.rec) */
    for (int q = 0; q < c.n_branch && rc == 0; q++)
        cont_branch_label(&c, q, blab[q], sizeof blab[q]);
    free(c.rec);
    if (rc) return -1;
    snprintf(c.ev->header, sizeof c.ev->header,
             "%s[%s] min_x[nm] amplitude[nm] type[1_LPC_2_PD_3_NS] index[count] "
             "label_row[count]",
             pname, u);
    /* labels that would overlap one over the other: the row of each (continue_label_rows),
     * a thin leader from the point up to a label above the first row */
    double xlo = INFINITY, xhi = -INFINITY, ylo[2] = {INFINITY, INFINITY},
           yhi[2] = {-INFINITY, -INFINITY};
    for (size_t i = 0; i < b->n; i++) {
        xlo = fmin(xlo, plot_cell(b, i, 0));
        xhi = fmax(xhi, plot_cell(b, i, 0));
        for (int p = 0; p < 2; p++) {
            ylo[p] = fmin(ylo[p], plot_cell(b, i, 1 + p));
            yhi[p] = fmax(yhi[p], plot_cell(b, i, 1 + p));
        }
    }
    /* the zoom (--xrange, --yrange, --yrange2, --zoom-pd): the window in x, and each panel's y the
     * option's or the extent of the branches within that x window, the labels placed for it
     * (their rows in $E change; the branches' columns do not) */
    bool zoom = false, fixed[2] = {false, false};
    /* --zoom-pd: the period-doubled branches (period > 1) alone set the window: x their
     * extent and 3 % more each side, y theirs inside it */
    if (o->zoom_pd) {
        double lo = INFINITY, hi = -INFINITY;
        for (size_t i = 0; i < b->n; i++)
            if (plot_cell(b, i, 5) > 1) {
                lo = fmin(lo, plot_cell(b, i, 0));
                hi = fmax(hi, plot_cell(b, i, 0));
            }
        if (!(lo <= hi)) return plot_err("%s", "--zoom-pd: no branch of period > 1");
        double pad = fmax(0.03 * (hi - lo), 1e-6 * fmax(fabs(lo), fabs(hi)) + 1e-12);
        xlo = lo - pad;
        xhi = hi + pad;
    }
    if (!isnan(o->range_lo[0])) {
        xlo = o->range_lo[0];
        xhi = o->range_hi[0];
    }
    if (o->zoom_pd || !isnan(o->range_lo[0])) {
        zoom = true;
        for (int p = 0; p < 2; p++) {
            ylo[p] = INFINITY;
            yhi[p] = -INFINITY;
        }
        for (size_t i = 0; i < b->n; i++) {
            double x = plot_cell(b, i, 0);
            bool take = x >= xlo && x <= xhi && (!o->zoom_pd || plot_cell(b, i, 5) > 1);
            for (int p = 0; p < 2 && take; p++) {
                ylo[p] = fmin(ylo[p], plot_cell(b, i, 1 + p));
                yhi[p] = fmax(yhi[p], plot_cell(b, i, 1 + p));
            }
        }
    }
    for (int p = 0; p < 2; p++)
        if (!isnan(o->range_lo[1 + p])) {
            ylo[p] = o->range_lo[1 + p];
            yhi[p] = o->range_hi[1 + p];
            zoom = fixed[p] = true;
        }
    if (!(ylo[0] <= yhi[0]) || !(ylo[1] <= yhi[1]))
        return plot_err("%s", "no point of the branches in --xrange");
    continue_label_rows(c.ev, xlo, xhi, ylo, yhi, d->W - PX_LEFT - PX_RIGHT, zoom);
    const char *xl = !strcmp(c.name, "fe")   ? "drive frequency fe (kHz)"
                     : !strcmp(c.name, "z")  ? "separation Z (nm)"
                     : !strcmp(c.name, "ae") ? "drive amplitude Ae (nm)"
                                             : pname;
    const bool curves = c.cv->n > 0;
    /* a colour per branch (8, then again); stable solid, unstable dashed and thin */
    static const char *const pc[8] = {"#0072b2", "#cc79a7", "#009e73", "#d55e00",
                                      "#56b4e9", "#e69f00", "#000000", "#999933"};
    for (int q = 0; q < c.n_branch; q++)
        fprintf(gp,
                "set style line %d lc rgb '%s' lw 2\nset style line %d lc rgb '%s' lw 1.2 dt "
                "2\n",
                21 + 2 * q, pc[q % 8], 22 + 2 * q, pc[q % 8]);
    static const char *const ev[3][3] = {{"LPC (fold)", "7", "red"},
                                         {"PD (period doubling)", "5", "dark-green"},
                                         {"NS (torus)", "9", "orange"}};
    for (int k = 0; k < 3; k++)
        fprintf(gp, "set style line %d lc rgb '%s' pt %s ps 1.3\n", 11 + k, ev[k][2], ev[k][1]);
    plot_key k = {0};
    /* the line styles' samples in grey: black is branch b6's colour */
    /* only the kinds drawn: a legend 'unstable' over a wholly stable branch misleads */
    bool any_st = false, any_un = false;
    for (size_t r = 0; r < c.n; r++) {
        if (c.rec[r].event != 0) continue;
        if (c.rec[r].stable)
            any_st = true;
        else
            any_un = true;
    }
    if (any_st || !any_un) plot_key_add(&k, "with lines lw 2 lc rgb 'gray50'", "stable");
    if (any_un || !any_st) plot_key_add(&k, "with lines lw 1.2 dt 2 lc rgb 'gray50'", "unstable");
    /* each branch: its period and how it was reached (parent, event) */
    for (int q = 0; q < c.n_branch && c.n_branch > 1; q++) {
        char with[64];
        snprintf(with, sizeof with, "with lines ls %d", 21 + 2 * q);
        plot_key_add(&k, with, blab[q]);
    }
    for (int e = 0; e < 3; e++)
        if (c.count[e + 1] > 0) {
            char with[32];
            snprintf(with, sizeof with, "with points ls %d", 11 + e);
            plot_key_add(&k, with, ev[e][0]);
        }
    if (c.ncurve[1])
        plot_key_add(&k, "with linespoints lw 2 pt 7 ps 0.5 lc rgb 'red'", "LPC curve");
    if (c.ncurve[2])
        plot_key_add(&k, "with linespoints lw 2 pt 7 ps 0.5 lc rgb 'dark-green'", "PD curve");
    const double l = PX_LEFT / d->W, r = 1 - PX_RIGHT / d->W;
    double top = plot_figure(gp, d, &k, l, r);
    /* the diagram's two panels share x; the parameter plane under them has its own */
    double bottom = PX_BOTTOM / d->H;
    if (curves) bottom += 0.36 * (top - bottom);
    const char *ylab[2] = {"min tip deflection xr (nm)", "amplitude at fe (nm)"};
    for (int p = 0; p < 2; p++) {
        plot_stack(gp, p, 2, l, r, bottom, top, PX_GAP / d->H);
        plot_shared_x(gp, p, 2, xl);
        /* y: the branches, and over them room for the stacked labels */
        double span = yhi[p] - ylo[p], ytop = yhi[p];
        for (size_t i = 0; i < c.ev->n; i++)
            if (!zoom || cont_in_window(c.ev, i, xlo, xhi, ylo, yhi))
                ytop = fmax(ytop, plot_cell(c.ev, i, 1 + p) +
                                      (plot_cell(c.ev, i, 5) + 2.2) * 0.09 * span);
        if (zoom) fprintf(gp, "set xrange [%.9g:%.9g]\n", xlo, xhi);
        if (fixed[p])
            fprintf(gp, "set yrange [%.9g:%.9g]\n", ylo[p], yhi[p]);
        else if (span > 0)
            fprintf(gp, "set yrange [%g:%g]\n", ylo[p] - 0.04 * span, ytop + 0.02 * span);
        fprintf(gp, "set ylabel '%s'\nplot ", ylab[p]);
        const char *sep = "";
        for (int q = 0; q < c.n_branch; q++)
            for (int s = 1; s >= 0; s--) {
                fprintf(gp,
                        "%s$B using 1:($4 == %d && $5 == %d ? $%d : 1/0) with lines ls %d notitle",
                        sep, s, q, 2 + p, 21 + 2 * q + (1 - s));
                sep = ", ";
            }
        if (c.ev->n > 0) /* leaders: from each point up to its label's row */
            fprintf(gp,
                    ", $E using 1:%d:(0):($6 * %g) with vectors nohead lw 0.6 lc rgb 'gray50' "
                    "notitle",
                    2 + p, 0.09 * (yhi[p] - ylo[p]));
        for (int e = 0; e < 3; e++) /* gnuplot's sprintf fails on an empty set's NaN */
            if (c.count[e + 1] > 0)
                fprintf(gp,
                        ", $E using ($4 == %d ? $1 : 1/0):%d with points ls %d notitle, $E using "
                        "($4 == %d ? $1 : 1/0):($%d + $6 * %g):(sprintf('%c%%d', $5)) with labels "
                        "offset 1,1 notitle",
                        e + 1, 2 + p, 11 + e, e + 1, 2 + p, 0.09 * (yhi[p] - ylo[p]), ev[e][0][0]);
        fprintf(gp, "\n");
    }
    double s2 = c.scale2;
    if (curves) { /* the parameter plane: the LPC and PD curves through the events */
        double big = 0.0;
        for (size_t i = 0; i < c.cv->n; i++)
            if (isfinite(c.cv->v[4 * i + 1])) big = fmax(big, fabs(c.cv->v[4 * i + 1]));
        if (s2 == 1e9 && big < 0.1) { /* sub-0.1 nm drive amplitudes: in pm */
            for (size_t i = 0; i < c.cv->n; i++)
                c.cv->v[4 * i + 1] *= 1e3;
            s2 = 1e12;
        }
        char yl[128];
        /* short: the panel is low, a long label would run past its ends */
        const char *n2 = !strcmp(c.name2, "fe")   ? "fe"
                         : !strcmp(c.name2, "z")  ? "Z"
                         : !strcmp(c.name2, "ae") ? "drive Ae"
                         : c.name2[0]             ? c.name2
                                                  : "param2";
        snprintf(yl, sizeof yl, "%s (%s)", n2, scale_unit(s2));
        plot_area(gp, l, r, PX_BOTTOM / d->H, bottom - (PX_BOTTOM + 2.5 * PX_LINE) / d->H);
        fprintf(gp,
                "set autoscale y\nset offsets 0, 0, graph 0.08, graph 0.08\nset format x\nset "
                "xlabel '%s'\nset title 'the bifurcation curves "
                "in the plane "
                "of the two parameters (own scales)'\nset ylabel '%s'\nplot ",
                xl, yl);
        static const char *const kc[2] = {"red", "dark-green"};
        const char *sep = "";
        for (int kind = 1; kind <= 2; kind++)
            if (c.ncurve[kind] > 0) {
                fprintf(gp,
                        "%s$C using 1:($3 == %d || $3 != $3 ? $2 : 1/0) with linespoints lw 2 "
                        "pt 7 ps 0.5 lc rgb '%s' notitle",
                        sep, kind, kc[kind - 1]);
                sep = ", ";
            }
        /* the margin above and below: a cusp at the range's end is not drawn on the axis */
        fprintf(gp, "\nunset title\nset offsets 0, 0, 0, 0\n");
    }
    snprintf(c.cv->header, sizeof c.cv->header, "%s[%s] %s[%s] kind[1_LPC_2_PD] curve[index]",
             pname, u, c.name2[0] ? c.name2 : "param2", scale_unit(s2));
    fprintf(gp, "unset multiplot\n");
    return 0;
}
