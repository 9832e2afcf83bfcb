/* SPDX-License-Identifier: MIT */
/* cmd_plan.c -- `afmtwin plan` (issue 31): from a map with fe along x, the pairs of an
 * imaging point (peak force at most the imaging limit) and a patterning point (at least the
 * patterning force) at the same y that differ in the drive frequency alone, ranked by how
 * far the switch stays from the jumps it does not need.
 *
 * The map's passes are the paths: a switch from fe_i up to fe_p follows the up pass (the
 * lever arrived at fe_i sweeping up from the map's FROM), one down follows the down pass.
 * The jumps of that pass between the two points are the ones the switch crosses (it may
 * need them: the jump onto the high-force branch); the others are hazards, and the margin
 * of a pair is the distance in fe from its interval to the nearest of them. */
#include "afmtwin_cmds.h"
#include "map_file.h"
#include "opts.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const char *map;
    double peak_n, imaging_n;
    int top;
} plan_opts;

static void plan_usage(FILE *f) {
    fprintf(f, "usage: afmtwin plan --map FILE --peak-force F [--imaging-force F] [--top N]\n\n"
               "Operating-point pairs for patterning from an `afmtwin map` file whose x axis is\n"
               "fe: an imaging point (settled, peak force <= --imaging-force) and a patterning\n"
               "point (settled, peak force >= --peak-force) on the same map line (same Z or Ae),\n"
               "reached from each other by changing the drive frequency alone. For each imaging\n"
               "point and pass direction, the nearest patterning point in that direction; the\n"
               "path is the map's pass (up: sweep fe up from the map's first frequency to the\n"
               "imaging point, then on to the patterning point; down: from the last one down).\n"
               "Listed by their margin: the distance in fe from the switch's interval to the\n"
               "nearest jump of that pass that the switch does not cross (larger is safer), then\n"
               "by the frequency step; with the jumps the switch crosses. Each point's A and lag\n"
               "are the map's (lag of the deflection behind the drive, 90 deg free at\n"
               "resonance).\n\n"
               "options:\n"
               "  --map FILE            an `afmtwin map` file (a partial one: its whole lines)\n"
               "  --peak-force F        the patterning force (N) > 0\n"
               "  --imaging-force F     the imaging limit (N), 0 < F < --peak-force (default a\n"
               "                        fifth of it)\n"
               "  --top N               how many pairs to list (default 10)\n"
               "Exit status 0 ok (also when no pair exists: said on stdout), 2 bad usage or "
               "input.\n");
}

typedef struct {
    int iy, dir, i, p;
    double margin_hz, step_hz;
} plan_pair;

static int cmp_pair(const void *a, const void *b) {
    const plan_pair *x = a, *y = b;
    if (x->margin_hz != y->margin_hz) return x->margin_hz < y->margin_hz ? 1 : -1;
    if (x->step_hz != y->step_hz) return x->step_hz > y->step_hz ? 1 : -1;
    if (x->iy != y->iy) return x->iy - y->iy;
    if (x->dir != y->dir) return x->dir - y->dir;
    return x->i - y->i;
}

/* Position of ix along pass dir (0 first). */
static int pos(const afmt_map_data *m, int dir, int ix) {
    return dir ? m->x.n - 1 - ix : ix;
}

int afm_cmd_plan(int argc, char **argv) {
    plan_opts o = {.peak_n = NAN, .imaging_n = NAN, .top = 10};
    const afmt_opt opts[] = {
        AFMT_STRING("--map", &o.map),
        AFMT_DOUBLE_ABOVE("--peak-force", &o.peak_n, 0, 1, "a force in N, 0 < F <= 1"),
        AFMT_DOUBLE_ABOVE("--imaging-force", &o.imaging_n, 0, 1, "a force in N, 0 < F <= 1"),
        AFMT_INT("--top", &o.top, 1, 1000000, NULL),
        AFMT_OPTS_END,
    };
    int prc = afmt_opts_parse("plan", opts, argc, argv, 1);
    int rc = afmt_opts_done("plan", prc == AFMT_OPTS_HELP ? 1 : prc ? -1 : 0, plan_usage);
    if (rc >= 0) return rc;
    if (!o.map || isnan(o.peak_n)) {
        fprintf(stderr, "afmtwin plan: --map and --peak-force are required\n");
        return 2;
    }
    if (isnan(o.imaging_n)) o.imaging_n = 0.2 * o.peak_n;
    if (!(o.imaging_n < o.peak_n)) {
        fprintf(stderr, "afmtwin plan: --imaging-force (%g N) must be below --peak-force (%g N)\n",
                o.imaging_n, o.peak_n);
        return 2;
    }
    static afmt_map_data m;
    char err[512];
    if (afmt_map_read(o.map, &m, err, sizeof err)) {
        fprintf(stderr, "afmtwin plan: %s\n", err);
        return 2;
    }
    if (m.x.param != AFMT_MAP_FE || m.x.n < 2) {
        fprintf(stderr, "afmtwin plan: %s: the map's x axis must be fe with 2 or more points\n",
                o.map);
        afmt_map_data_destroy(&m);
        return 2;
    }
    const int nx = m.x.n;
    size_t cap = 256, n = 0;
    plan_pair *pairs = malloc(cap * sizeof *pairs);
    if (!pairs) goto oom;
    for (int iy = 0; iy < m.lines; iy++)
        for (int d = 0; d < 2; d++) {
            if (!m.pts[d]) continue;
            const afmt_map_point *row = &m.pts[d][(size_t)iy * nx];
            for (int i = 0; i < nx; i++) {
                if (!row[i].settled || !(row[i].peak_force_n <= o.imaging_n)) continue;
                int p = -1; /* the nearest patterning point after i in pass order */
                for (int k = pos(&m, d, i) + 1; k < nx && p < 0; k++) {
                    int ix = d ? nx - 1 - k : k;
                    if (row[ix].settled && row[ix].peak_force_n >= o.peak_n) p = ix;
                }
                if (p < 0) continue;
                double lo = fmin(afmt_map_axis_value(&m.x, i), afmt_map_axis_value(&m.x, p));
                double hi = fmax(afmt_map_axis_value(&m.x, i), afmt_map_axis_value(&m.x, p));
                double margin = HUGE_VAL;
                for (int j = 0; j < m.n_jumps; j++) {
                    const struct afmt_map_jump *J = &m.jumps[j];
                    if (J->iy != iy || J->dir != d) continue;
                    int a = pos(&m, d, J->ix_before), b = pos(&m, d, J->ix_after);
                    if (a >= pos(&m, d, i) && b <= pos(&m, d, p)) continue; /* crossed */
                    double f = 0.5 * (afmt_map_axis_value(&m.x, J->ix_before) +
                                      afmt_map_axis_value(&m.x, J->ix_after));
                    double dist = f < lo ? lo - f : f > hi ? f - hi : 0.0;
                    if (dist < margin) margin = dist;
                }
                if (n == cap) {
                    plan_pair *t = realloc(pairs, (cap *= 2) * sizeof *pairs);
                    if (!t) goto oom;
                    pairs = t;
                }
                pairs[n++] = (plan_pair){iy, d, i, p, margin, hi - lo};
            }
        }
    qsort(pairs, n, sizeof *pairs, cmp_pair);
    const double ys = m.y.param == AFMT_MAP_FE || m.y.param == AFMT_MAP_NAMED ? 1.0 : 1e9;
    const char *yu = m.y.param == AFMT_MAP_FE      ? "Hz"
                     : m.y.param == AFMT_MAP_NAMED ? m.y.unit
                                                   : "nm";
    printf("# afmtwin plan %s: patterning peak force >= %g N, imaging <= %g N; %zu pairs, the "
           "best %d (margin: fe distance to the nearest jump the switch does not cross)\n",
           o.map, o.peak_n, o.imaging_n, n, n < (size_t)o.top ? (int)n : o.top);
    if (n == 0) printf("# no pair: no imaging point has a patterning point on its line\n");
    for (size_t k = 0; k < n && k < (size_t)o.top; k++) {
        const plan_pair *q = &pairs[k];
        const afmt_map_point *row = &m.pts[q->dir][(size_t)q->iy * nx];
        double fi = afmt_map_axis_value(&m.x, q->i), fp = afmt_map_axis_value(&m.x, q->p);
        printf("%zu. %s %.6g %s: image at fe %.6g Hz (peak %.4g N, A %.4g nm, lag %.2f deg), "
               "pattern at fe %.6g Hz (peak %.4g N, A %.4g nm, lag %.2f deg); path: %s pass "
               "from fe %.6g Hz; margin ",
               k + 1, afmt_map_axis_name(&m.y), afmt_map_axis_value(&m.y, q->iy) * ys, yu, fi,
               row[q->i].peak_force_n, row[q->i].amplitude_m * 1e9, row[q->i].lag_deg, fp,
               row[q->p].peak_force_n, row[q->p].amplitude_m * 1e9, row[q->p].lag_deg,
               q->dir ? "down" : "up", q->dir ? m.x.to : m.x.from);
        if (isinf(q->margin_hz))
            printf("no other jump");
        else
            printf("%.6g Hz", q->margin_hz);
        printf("; crosses:");
        int nc = 0;
        for (int j = 0; j < m.n_jumps; j++) {
            const struct afmt_map_jump *J = &m.jumps[j];
            if (J->iy != q->iy || J->dir != q->dir) continue;
            int a = pos(&m, q->dir, J->ix_before), b = pos(&m, q->dir, J->ix_after);
            if (a >= pos(&m, q->dir, q->i) && b <= pos(&m, q->dir, q->p)) {
                printf(" jump fe %.6g -> %.6g Hz (A %.4g -> %.4g nm)",
                       afmt_map_axis_value(&m.x, J->ix_before),
                       afmt_map_axis_value(&m.x, J->ix_after), row[J->ix_before].amplitude_m * 1e9,
                       row[J->ix_after].amplitude_m * 1e9);
                nc++;
            }
        }
        printf("%s\n", nc ? "" : " no jump");
    }
    free(pairs);
    afmt_map_data_destroy(&m);
    return 0;
oom:
    free(pairs);
    afmt_map_data_destroy(&m);
    fprintf(stderr, "afmtwin plan: out of memory\n");
    return 1;
}
