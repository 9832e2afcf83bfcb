/* SPDX-License-Identifier: MIT */
/* map_file.c -- the map file of `afmtwin map`: header, line blocks, resume check, reading
 * (the format is described in map_file.h). */
#include "map_file.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

static const char *const param_names[] = {"fe", "z", "ae", "named"};
static const char *const param_units[] = {"Hz", "m", "m", "-"};

const char *afmt_map_param_name(afmt_map_param p) {
    return param_names[p];
}

const char *afmt_map_param_unit(afmt_map_param p) {
    return param_units[p];
}

const char *afmt_map_axis_name(const afmt_map_axis *a) {
    return a->param == AFMT_MAP_NAMED ? a->name : param_names[a->param];
}

const char *afmt_map_axis_unit(const afmt_map_axis *a) {
    return a->param == AFMT_MAP_NAMED ? a->unit : param_units[a->param];
}

int afmt_map_param_parse(const char *s) {
    for (int i = 0; i < 3; i++)
        if (!strcmp(s, param_names[i])) return i;
    return -1;
}

double afmt_map_axis_value(const afmt_map_axis *a, int i) {
    if (a->n <= 1 || i == 0) return a->from;
    if (i == a->n - 1) return a->to;
    return a->from + (a->to - a->from) * (double)i / (double)(a->n - 1);
}

uint64_t afmt_map_fnv(uint64_t h, const void *p, size_t n) {
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++) {
        h ^= b[i];
        h *= 0x100000001b3ULL;
    }
    return h;
}

int afmt_map_hash_file(const char *path, uint64_t *h) {
    FILE *f = fopen(path, "rb");
    if (!f) return -1;
    unsigned char buf[65536];
    size_t n;
    *h = AFMT_MAP_FNV_INIT;
    while ((n = fread(buf, 1, sizeof buf, f)) > 0)
        *h = afmt_map_fnv(*h, buf, n);
    int e = ferror(f);
    fclose(f);
    return e ? -1 : 0;
}

/* A growing string (appends with printf formats). */
typedef struct {
    char *s;
    size_t len, cap;
    bool fail;
} sbuf;

static void sb_printf(sbuf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void sb_printf(sbuf *b, const char *fmt, ...) {
    if (b->fail) return;
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        size_t room = b->cap - b->len;
        int n = vsnprintf(b->s ? b->s + b->len : NULL, b->s ? room : 0, fmt, ap);
        va_end(ap);
        if (n < 0) {
            b->fail = true;
            return;
        }
        if (b->s && (size_t)n < room) {
            b->len += (size_t)n;
            return;
        }
        size_t cap = (b->cap ? 2 * b->cap : 4096) + (size_t)n;
        char *s = realloc(b->s, cap);
        if (!s) {
            b->fail = true;
            return;
        }
        b->s = s;
        b->cap = cap;
    }
}

static char *sb_done(sbuf *b) {
    if (b->fail || !b->s) {
        free(b->s);
        return NULL;
    }
    return b->s;
}

static const char *dir_word(int dirs) {
    return dirs == AFMT_MAP_BOTH ? "both" : dirs == AFMT_MAP_UP ? "up" : "down";
}

#define COLUMNS                                                                                    \
    "line dir ix x y amplitude_m phase_lag_deg peak_force_n attractive_force_n min_gap_m "         \
    "indentation_m contact_time_s dissipated_energy_j periodicity settled settle_periods"

char *afmt_map_header(const afmt_map_spec *sp) {
    sbuf b = {0};
    sb_printf(&b, "afmtwin-map 1\nconfig %s\nconfig_fnv1a64 %016llx\n", sp->config_path,
              (unsigned long long)sp->config_hash);
    sb_printf(&b, "x %s %.17g %.17g %d", afmt_map_axis_name(&sp->x), sp->x.from, sp->x.to, sp->x.n);
    if (sp->x.param == AFMT_MAP_NAMED) sb_printf(&b, " %s", sp->x.unit);
    sb_printf(&b, "\n");
    sb_printf(&b, "y %s %.17g %.17g %d", afmt_map_axis_name(&sp->y), sp->y.from, sp->y.to, sp->y.n);
    if (sp->y.param == AFMT_MAP_NAMED) sb_printf(&b, " %s", sp->y.unit);
    sb_printf(&b, "\n");
    sb_printf(&b, "direction %s\nintegrator %s scheme %s\n", dir_word(sp->dirs), sp->integrator,
              sp->scheme);
    sb_printf(&b,
              "tol %.17g max_periods %d jump_tol %.17g jump_deg %.17g bistable_tol %.17g "
              "bistable_deg %.17g\n",
              sp->tol, sp->max_periods, sp->jump_tol, sp->jump_deg, sp->bistable_tol,
              sp->bistable_deg);
    sb_printf(&b, "columns " COLUMNS "\nend_header\n");
    return sb_done(&b);
}

/* Two orbits differ: amplitudes by more than rel of the larger, or lags by more than deg. */
static bool differs(const afmt_map_point *a, const afmt_map_point *b, double rel, double deg) {
    return fabs(a->amplitude_m - b->amplitude_m) >
               rel * fmax(fabs(a->amplitude_m), fabs(b->amplitude_m)) ||
           fabs(a->lag_deg - b->lag_deg) > deg;
}

char *afmt_map_block(const afmt_map_spec *sp, int iy, const afmt_map_point *const pts[2]) {
    sbuf b = {0};
    const int nx = sp->x.n;
    const double y = afmt_map_axis_value(&sp->y, iy);
    sb_printf(&b, "L %d %.17g\n", iy, y);
    for (int d = 0; d < 2; d++) {
        if (!pts[d]) continue;
        for (int ix = 0; ix < nx; ix++) {
            const afmt_map_point *p = &pts[d][ix];
            sb_printf(&b,
                      "P %d %c %d %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %d "
                      "%d %d\n",
                      iy, d ? 'd' : 'u', ix, afmt_map_axis_value(&sp->x, ix), y, p->amplitude_m,
                      p->lag_deg, p->peak_force_n, p->attractive_n, p->min_gap_m, p->indentation_m,
                      p->contact_time_s, p->energy_j, p->periodicity, p->settled,
                      p->settle_periods);
        }
    }
    for (int d = 0; d < 2; d++) {
        if (!pts[d]) continue;
        for (int k = 1; k < nx; k++) { /* pass order: up ix ascending, down descending */
            int i0 = d ? nx - k : k - 1, i1 = d ? nx - 1 - k : k;
            const afmt_map_point *a = &pts[d][i0], *c = &pts[d][i1];
            if (differs(a, c, sp->jump_tol, sp->jump_deg))
                sb_printf(&b, "J %d %c %d %d %.17g %.17g %.17g %.17g\n", iy, d ? 'd' : 'u', i0, i1,
                          a->amplitude_m, c->amplitude_m, a->lag_deg, c->lag_deg);
        }
    }
    if (pts[0] && pts[1])
        for (int ix = 0; ix < nx; ix++)
            if (differs(&pts[0][ix], &pts[1][ix], sp->bistable_tol, sp->bistable_deg))
                sb_printf(&b, "B %d %d\n", iy, ix);
    if (b.fail) return sb_done(&b);
    uint64_t h = afmt_map_fnv(AFMT_MAP_FNV_INIT, b.s, b.len);
    sb_printf(&b, "E %d %016llx\n", iy, (unsigned long long)h);
    return sb_done(&b);
}

/* The whole file into memory (NUL-terminated): its length, or -1 with err. */
static long slurp(const char *path, char **out, char *err, size_t errlen) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errlen, "cannot open %s: %s", path, strerror(errno));
        return -1;
    }
    char *s = NULL;
    size_t len = 0, cap = 0, n;
    for (;;) {
        if (cap - len < 65536) {
            char *t = realloc(s, cap = cap + 65536 + cap / 2);
            if (!t) {
                free(s);
                fclose(f);
                snprintf(err, errlen, "%s: out of memory", path);
                return -1;
            }
            s = t;
        }
        n = fread(s + len, 1, cap - len - 1, f);
        if (n == 0) break;
        len += n;
    }
    bool bad = ferror(f);
    fclose(f);
    if (bad) {
        free(s);
        snprintf(err, errlen, "cannot read %s", path);
        return -1;
    }
    s[len] = '\0';
    if (strlen(s) != len) {
        free(s);
        snprintf(err, errlen, "%s: corrupt map file (a NUL byte in it)", path);
        return -1;
    }
    *out = s;
    return (long)len;
}

/* Walk the line blocks from s + pos (after the header). Calls on_line for each record of a
 * complete block (may be NULL). Returns 0 with *lines, *end (the end of the last complete
 * block), or -1 with err for a corrupt block. A last block cut short is not counted. */
typedef int (*record_fn)(void *ctx, const char *rec, size_t len, char *err, size_t errlen);

static int walk_blocks(const char *path, const char *s, long len, long pos, int ny, int *lines,
                       long *end, record_fn on_rec, void *ctx, char *err, size_t errlen) {
    int iy = 0;
    *lines = 0;
    *end = pos;
    while (pos < len) {
        if (iy >= ny) {
            snprintf(err, errlen, "%s: corrupt map file: data after the last line (byte %ld)", path,
                     pos);
            return -1;
        }
        long start = pos;
        uint64_t h = AFMT_MAP_FNV_INIT;
        bool first = true, closed = false;
        while (pos < len) {
            const char *nl = memchr(s + pos, '\n', (size_t)(len - pos));
            if (!nl) {
                pos = len; /* a record cut short: an interrupted write */
                break;
            }
            const char *rec = s + pos;
            long rlen = nl - rec + 1;
            if (first) {
                int li;
                if (sscanf(rec, "L %d ", &li) != 1 || li != iy) {
                    snprintf(err, errlen,
                             "%s: corrupt map file: line %d should start at byte %ld, found "
                             "'%.40s'",
                             path, iy, start, rec);
                    return -1;
                }
                first = false;
            }
            if (rec[0] == 'E') {
                int ei;
                unsigned long long want;
                if (sscanf(rec, "E %d %llx", &ei, &want) != 2 || ei != iy || want != h) {
                    snprintf(err, errlen,
                             "%s: corrupt map file: line %d (bytes %ld..%ld) fails its "
                             "checksum",
                             path, iy, start, (long)(nl - s));
                    return -1;
                }
                pos += rlen;
                closed = true;
                break;
            }
            if (!strchr("LPJB", rec[0]) || rec[1] != ' ') {
                snprintf(err, errlen, "%s: corrupt map file: unknown record '%.40s' at byte %ld",
                         path, rec, pos);
                return -1;
            }
            h = afmt_map_fnv(h, rec, (size_t)rlen);
            pos += rlen;
        }
        if (!closed) break; /* the last block was cut short: dropped */
        if (on_rec) {       /* a checked block: its records */
            long p = start;
            while (p < pos) {
                const char *nl = memchr(s + p, '\n', (size_t)(pos - p));
                if (on_rec(ctx, s + p, (size_t)(nl - (s + p)), err, errlen)) return -1;
                p = nl - s + 1;
            }
        }
        *end = pos;
        *lines = ++iy;
    }
    return 0;
}

int afmt_map_resume_check(const char *path, const char *header, int ny, int *lines_done,
                          long *keep_bytes, char *err, size_t errlen) {
    char *s;
    long len = slurp(path, &s, err, errlen);
    if (len < 0) return -1;
    size_t hl = strlen(header);
    if ((size_t)len < hl || memcmp(s, header, hl) != 0) {
        /* say which header line differs */
        const char *a = s, *b = header;
        while (*a && *a == *b && *b) {
            a++;
            b++;
        }
        while (a > s && a[-1] != '\n')
            a--;
        while (b > header && b[-1] != '\n')
            b--;
        int la = (int)strcspn(a, "\n"), lb = (int)strcspn(b, "\n");
        if (strncmp(s, "afmtwin-map ", 12) != 0)
            snprintf(err, errlen, "%s is not an afmtwin map file (cannot resume it)", path);
        else
            snprintf(err, errlen,
                     "%s is a map of other arguments or another config: it has '%.*s' where "
                     "this run has '%.*s' (cannot resume it)",
                     path, la > 120 ? 120 : la, a, lb > 120 ? 120 : lb, b);
        free(s);
        return -1;
    }
    int rc =
        walk_blocks(path, s, len, (long)hl, ny, lines_done, keep_bytes, NULL, NULL, err, errlen);
    free(s);
    return rc;
}

/* ---- reading a whole map ---- */

static int read_axis(const char *line, const char *key, afmt_map_axis *a) {
    char name[80];
    char fmt[48];
    char one[256]; /* this line alone: a named axis's unit is the rest of it ("Pa s") */
    snprintf(one, sizeof one, "%.*s", (int)strcspn(line, "\n"), line);
    snprintf(fmt, sizeof fmt, "%s %%79s %%lf %%lf %%d%%n", key);
    int used = 0;
    if (sscanf(one, fmt, name, &a->from, &a->to, &a->n, &used) != 4 || used <= 0 || a->n < 1 ||
        a->n > AFMT_MAP_MAX_N)
        return -1;
    const char *unit = one + used;
    while (*unit == ' ')
        unit++;
    int p = afmt_map_param_parse(name);
    if (p == AFMT_MAP_NAMED) return -1;
    if (p < 0) { /* a named parameter, with its unit */
        if (!*unit || strlen(unit) >= sizeof a->unit) return -1;
        p = AFMT_MAP_NAMED;
        snprintf(a->name, sizeof a->name, "%s", name);
        snprintf(a->unit, sizeof a->unit, "%s", unit);
    } else if (*unit)
        return -1;
    a->param = (afmt_map_param)p;
    return 0;
}

static int on_record(void *ctx, const char *rec, size_t len, char *err, size_t errlen) {
    afmt_map_data *m = ctx;
    (void)len;
    if (rec[0] == 'P') {
        int iy, ix;
        char dir;
        double x, y;
        afmt_map_point p;
        int n = sscanf(rec, "P %d %c %d %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %d %d %d", &iy,
                       &dir, &ix, &x, &y, &p.amplitude_m, &p.lag_deg, &p.peak_force_n,
                       &p.attractive_n, &p.min_gap_m, &p.indentation_m, &p.contact_time_s,
                       &p.energy_j, &p.periodicity, &p.settled, &p.settle_periods);
        int d = dir == 'd';
        if (n != 16 || iy < 0 || iy >= m->y.n || ix < 0 || ix >= m->x.n || !m->pts[d]) {
            snprintf(err, errlen, "bad point record '%.60s'", rec);
            return -1;
        }
        m->pts[d][(size_t)iy * (size_t)m->x.n + (size_t)ix] = p;
    } else if (rec[0] == 'B') {
        int iy, ix;
        if (sscanf(rec, "B %d %d", &iy, &ix) != 2 || iy < 0 || iy >= m->y.n || ix < 0 ||
            ix >= m->x.n) {
            snprintf(err, errlen, "bad bistable record '%.60s'", rec);
            return -1;
        }
        m->bistable[(size_t)iy * (size_t)m->x.n + (size_t)ix] = 1;
    } else if (rec[0] == 'J') {
        struct afmt_map_jump j;
        char dir;
        if (sscanf(rec, "J %d %c %d %d", &j.iy, &dir, &j.ix_before, &j.ix_after) != 4 || j.iy < 0 ||
            j.iy >= m->y.n || j.ix_before < 0 || j.ix_before >= m->x.n || j.ix_after < 0 ||
            j.ix_after >= m->x.n) {
            snprintf(err, errlen, "bad jump record '%.60s'", rec);
            return -1;
        }
        j.dir = dir == 'd';
        if (m->n_jumps % 64 == 0) {
            struct afmt_map_jump *t =
                realloc(m->jumps, (size_t)(m->n_jumps + 64) * sizeof *m->jumps);
            if (!t) {
                snprintf(err, errlen, "out of memory");
                return -1;
            }
            m->jumps = t;
        }
        m->jumps[m->n_jumps++] = j;
    }
    return 0;
}

int afmt_map_read(const char *path, afmt_map_data *m, char *err, size_t errlen) {
    memset(m, 0, sizeof *m);
    char *s;
    long len = slurp(path, &s, err, errlen);
    if (len < 0) return -1;
    const char *eh = strstr(s, "\nend_header\n");
    char dirw[8] = "";
    const char *xl = strstr(s, "\nx "), *yl = strstr(s, "\ny "), *dl = strstr(s, "\ndirection ");
    const char *cl = strstr(s, "\nconfig ");
    if (strncmp(s, "afmtwin-map 1\n", 14) != 0 || !eh || !xl || !yl || !dl || xl > eh || yl > eh ||
        dl > eh || read_axis(xl + 1, "x", &m->x) || read_axis(yl + 1, "y", &m->y) ||
        sscanf(dl + 1, "direction %7s", dirw) != 1) {
        snprintf(err, errlen, "%s is not an afmtwin map file (bad or missing header)", path);
        free(s);
        return -1;
    }
    if (cl && cl < eh) {
        int n = (int)strcspn(cl + 8, "\n");
        snprintf(m->config, sizeof m->config, "%.*s", n, cl + 8);
    }
    m->dirs = !strcmp(dirw, "both") ? AFMT_MAP_BOTH
              : !strcmp(dirw, "up") ? AFMT_MAP_UP
                                    : AFMT_MAP_DOWN;
    size_t np = (size_t)m->x.n * (size_t)m->y.n;
    for (int d = 0; d < 2; d++)
        if (m->dirs & (1 << d)) {
            m->pts[d] = malloc(np * sizeof(afmt_map_point));
            if (!m->pts[d]) goto oom;
            for (size_t i = 0; i < np; i++)
                m->pts[d][i] = (afmt_map_point){NAN, NAN, NAN, NAN, NAN, NAN, NAN, NAN, 0, 0, 0};
        }
    m->bistable = calloc(np, 1);
    if (!m->bistable) goto oom;
    long end;
    char e2[256];
    if (walk_blocks(path, s, len, (long)(eh + 12 - s), m->y.n, &m->lines, &end, on_record, m, e2,
                    sizeof e2)) {
        snprintf(err, errlen, "%s", e2);
        free(s);
        afmt_map_data_destroy(m);
        return -1;
    }
    free(s);
    return 0;
oom:
    free(s);
    afmt_map_data_destroy(m);
    snprintf(err, errlen, "%s: out of memory", path);
    return -1;
}

void afmt_map_data_destroy(afmt_map_data *m) {
    free(m->pts[0]);
    free(m->pts[1]);
    free(m->bistable);
    free(m->jumps);
    m->pts[0] = m->pts[1] = NULL;
    m->bistable = NULL;
    m->jumps = NULL;
    m->n_jumps = 0;
}
