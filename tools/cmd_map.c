/* SPDX-License-Identifier: MIT */
/* cmd_map.c -- `afmtwin map` (issue 31): a plane of settled orbits over two operating
 * parameters, one `afmtwin sweep` per map line, the lines spread over MPI ranks.
 *
 * Each line (one value of y) is a sweep along x with the state carried from point to point
 * (afm_sweep_step / afm_sweep_dwell of runner/afm_twin.h, the settle loop `sweep` and
 * `approach` use), up and then, continuing from where up ended, down. A line depends on
 * nothing but its y and the arguments, so any rank can run it: rank 0 runs every size-th
 * line and writes all of them in order (map_file.h: text, %.17g), the others send their
 * finished blocks to it; the file is the same bytes whatever the number of ranks. MPI stays
 * here, in the tools layer: the engine knows nothing of it. Without mpirun the same binary
 * runs as one process (MPI singleton). */
#include "afmtwin_cmds.h"
#include "lcm_tool.h"
#include "map_file.h"
#include "opts.h"

#include "config/afm_config.h"
#include "estimators/afm_cycle.h"
#include "estimators/afm_orbit.h"
#include "forces/afm_force.h"
#include "integrators/afm_sim.h"
#include "integrators/afm_sim_live.h"
#include "runner/afm_cmd.h"
#include "runner/afm_twin.h"

#if AFMT_NO_MPI
/* A build without MPI (AFMTWIN_MPI=0, e.g. the arm64 cross build, which has no arm64 Open
 * MPI): one process, rank 0 of 1; the other ranks' calls are never reached. */
typedef int MPI_Status, MPI_Request;
#define MPI_COMM_WORLD 0
#define MPI_INT 0
#define MPI_CHAR 0
#define MPI_STATUS_IGNORE NULL
#define MPI_STATUSES_IGNORE NULL
#define MPI_Init(c, v) ((void)(c), (void)(v))
#define MPI_Finalize() ((void)0)
#define MPI_Comm_rank(c, r) (*(r) = 0)
#define MPI_Comm_size(c, s) (*(s) = 1)
#define MPI_Bcast(b, n, t, r, c) ((void)(b))
#define MPI_Abort(c, e) exit(e)
#define MPI_Probe(a, b, c, s) ((void)(a), (void)(s))
#define MPI_Get_count(s, t, n) (*(n) = 0)
#define MPI_Recv(b, n, t, a, g, c, s) ((void)(b))
#define MPI_Isend(b, n, t, a, g, c, r) ((void)(b), (void)(r))
#define MPI_Waitall(n, r, s) ((void)(r))
#else
#include <mpi.h>
#endif

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define DEFAULT_MAX_PERIODS 10000
#define DEFAULT_TOL 1e-6
#define DEFAULT_JUMP_TOL 0.3
#define DEFAULT_BISTABLE_TOL 0.05
#define DEFAULT_JUMP_DEG 40.0
#define DEFAULT_BISTABLE_DEG 10.0
#define TWO_PI 6.283185307179586476925286766559

static const int default_harmonics[] = {1, 6, 17};

typedef struct {
    const char *config, *out;
    int dirs; /* --direction: AFMT_MAP_UP, AFMT_MAP_DOWN or AFMT_MAP_BOTH */
    afmt_map_axis x, y;
    bool have_x, have_y, resume;
    int integrator, scheme, max_periods, stop_after;
    double tol, jump_tol, jump_deg, bistable_tol, bistable_deg;
} map_opts;

static void map_usage(FILE *f) {
    fprintf(
        f,
        "usage: [mpirun -np N] afmtwin map --config FILE --x fe|z|ae FROM TO N\n"
        "                 --y fe|z|ae FROM TO N --out FILE [--direction up|down|both]\n"
        "                 [--integrator rt|reference|arkode-erk] [--scheme accurate|fast]\n"
        "                 [--max-periods N] [--tol X] [--jump-tol X] [--jump-deg D]\n"
        "                 [--bistable-tol X] [--bistable-deg D] [--resume]\n\n"
        "A map of settled orbits over two operating parameters (drive frequency fe, separation\n"
        "Z, drive amplitude Ae): for every y value a sweep along x, the state carried from\n"
        "point to point as in `afmtwin sweep` (each point dwelt until the orbit repeats itself),\n"
        "up (x from FROM to TO), then down (TO to FROM) continuing from where up ended. Per\n"
        "point: the amplitude and phase lag of harmonic 1 of the deflection (lag behind the\n"
        "drive: 90 deg free at resonance, below 90 when repulsive), over the last p drive\n"
        "periods (the orbit's period) the peak and the attractive (most negative) tip force,\n"
        "the minimum gap x cos(alpha) + Z, the indentation, and per period the contact time\n"
        "and the dissipated energy (-int F v dt); the periodicity p and whether it settled. Per "
        "line the jumps (neighbours\n"
        "of a pass whose amplitudes differ by more than --jump-tol of the larger, or whose\n"
        "lags by more than --jump-deg) and, with --direction both, the bistable points (up and\n"
        "down amplitudes differ by more than --bistable-tol of the larger, or their lags by\n"
        "more than --bistable-deg).\n\n"
        "The lines run on MPI ranks: under mpirun -np N (one machine or a hostfile) rank 0\n"
        "writes every line in order; without mpirun one process runs all. The file (format in\n"
        "docs/map.md) is the same bytes whatever N; each line is written once, whole, with a\n"
        "checksum, and flushed to disk.\n\n"
        "options:\n"
        "  --config FILE       libconfig model file\n"
        "  --x NAME FROM TO N  the axis swept within a line: fe (Hz), z (m), ae (m) or a\n"
        "                      force or damping parameter of `afmtwin send param` (its unit),\n"
        "                      set at once with the state kept, as that command does; N >= 1\n"
        "                      points FROM + (TO - FROM) i / (N - 1), FROM < TO (N 1: FROM)\n"
        "  --y NAME FROM TO N  the axis across lines (another parameter than x): fe, z, ae, or\n"
        "                      any live parameter of `afmtwin send param` by its name and in\n"
        "                      its unit (e.g. forces.vdw_contact.hamaker_j 5e-20 2e-19 4), set\n"
        "                      in each line's config as that command would set it\n"
        "  --out FILE          the map file (overwritten, unless --resume)\n"
        "  --direction D       up, down or both (default both)\n"
        "  --integrator NAME   rt, reference or arkode-erk; default the "
        "config's\n" AFMT_OPT_SCHEME_HELP
        "  --max-periods N     most drive periods dwelt per point, >= 2 (default %d)\n"
        "  --periods N         the same\n"
        "  --tol X             steady state tolerance as `sweep --tol`, 0 < X < 1 (default %g)\n"
        "  --jump-tol X        relative amplitude change that is a jump, 0 < X < 1 (default %g)\n"
        "  --jump-deg D        lag change that is a jump, degrees (default %g)\n"
        "  --bistable-tol X    relative up/down amplitude difference that is bistable, 0 < X < 1\n"
        "                      (default %g)\n"
        "  --bistable-deg D    up/down lag difference that is bistable, degrees (default %g)\n"
        "  --resume            keep the whole lines FILE already holds (a map of the same\n"
        "                      arguments and config bytes: else an error and FILE unchanged),\n"
        "                      drop a last line cut short, run the rest\n"
        "  --stop-after K      (for tests) stop after K more lines, as if interrupted\n"
        "  --help              this text\n\n" AFMT_OPT_SI_HELP
        "FROM and TO of fe take Hz suffixes, of z and ae length suffixes.\n"
        "Exit status 0 ok, 1 simulation failure, 2 bad usage or bad input (nothing written).\n",
        DEFAULT_MAX_PERIODS, DEFAULT_TOL, DEFAULT_JUMP_TOL, DEFAULT_JUMP_DEG, DEFAULT_BISTABLE_TOL,
        DEFAULT_BISTABLE_DEG);
#if AFMT_NO_MPI
    fprintf(f, "This afmtwin is built without MPI (AFMTWIN_MPI=0): one process; under mpirun "
               "it refuses to run.\n");
#endif
}

/* --x / --y NAME FROM TO N at argv[i..i+4]. 0, or -1 (said). */
static int parse_axis(char **argv, int argc, int i, afmt_map_axis *a) {
    const char *opt = argv[i];
    (void)argc; /* the caller checked that four words follow */
    int p = afmt_map_param_parse(argv[i + 1]);
    if (p == AFMT_MAP_NAMED) p = -1; /* the file's word for a named axis, not a name */
    if (p < 0) {
        /* a live parameter of `afmtwin send param` (afm_cmd.h's table): any on --y, a force
         * or damping one on --x */
        int entry, index;
        char perr[AFM_ERR_LEN];
        if (afm_param_lookup(argv[i + 1], &entry, &index, perr, sizeof perr) != 0) {
            fprintf(stderr, "afmtwin map: %s: '%s' is not fe, z, ae or a live parameter: %s\n", opt,
                    argv[i + 1], perr);
            return -1;
        }
        int nd;
        const afm_param_def *d = &afm_param_table(&nd)[entry];
        if (strcmp(opt, "--y") != 0 && d->effect != AFM_PARAM_FORCE &&
            d->effect != AFM_PARAM_DAMPING) {
            fprintf(stderr,
                    "afmtwin map: --x %s: along x the state is carried from point to point, so "
                    "x takes fe, z, ae, a tip-sample force or a damping parameter (as `afmtwin "
                    "send param` applies them, the state kept); a geometry parameter changes "
                    "the modes, whose state cannot be carried: put it on --y\n",
                    argv[i + 1]);
            return -1;
        }
        p = AFMT_MAP_NAMED;
        afm_param_name(entry, index, a->name, sizeof a->name);
        snprintf(a->unit, sizeof a->unit, "%s", d->unit && d->unit[0] ? d->unit : "-");
    }
    a->param = (afmt_map_param)p;
    char what[32];
    snprintf(what, sizeof what, "%s FROM", opt);
    if (p == AFMT_MAP_NAMED) { /* plain numbers in the parameter's unit; its range below */
        if (afmt_parse_double(argv[i + 2], &a->from) || afmt_parse_double(argv[i + 3], &a->to) ||
            !isfinite(a->from) || !isfinite(a->to)) {
            fprintf(stderr, "afmtwin map: %s %s: FROM and TO must be numbers, got '%s' '%s'\n", opt,
                    a->name, argv[i + 2], argv[i + 3]);
            return -1;
        }
    } else {
        afmt_unit u = p == AFMT_MAP_FE ? AFMT_UNIT_HZ : AFMT_UNIT_M;
        if (afmt_opt_si_value("map", what, argv[i + 2], u, &a->from)) return -1;
        snprintf(what, sizeof what, "%s TO", opt);
        if (afmt_opt_si_value("map", what, argv[i + 3], u, &a->to)) return -1;
    }
    char *end;
    errno = 0;
    long n = strtol(argv[i + 4], &end, 10);
    if (end == argv[i + 4] || *end || errno || n < 1 || n > AFMT_MAP_MAX_N) {
        fprintf(stderr, "afmtwin map: %s N wants an integer in 1..%d, got '%s'\n", opt,
                AFMT_MAP_MAX_N, argv[i + 4]);
        return -1;
    }
    a->n = (int)n;
    double hi = p == AFMT_MAP_Z ? 1e-3 : p == AFMT_MAP_AE ? 1e-6 : HUGE_VAL;
    if (p != AFMT_MAP_NAMED && (!(a->from >= 0 && a->to >= 0 && a->from <= hi && a->to <= hi) ||
                                (p == AFMT_MAP_FE && a->from <= 0))) {
        fprintf(stderr, "afmtwin map: %s %s: values must be in %s (got %g .. %g)\n", opt,
                argv[i + 1],
                p == AFMT_MAP_FE  ? "(0, rate / 2) Hz"
                : p == AFMT_MAP_Z ? "0..1e-3 m"
                                  : "0..1e-6 m",
                a->from, a->to);
        return -1;
    }
    if (a->n == 1 ? a->from != a->to : !(a->from < a->to)) {
        fprintf(stderr,
                "afmtwin map: %s %s: FROM must be below TO (FROM = TO with N 1), got %g .. %g "
                "with N %d\n",
                opt, argv[i + 1], a->from, a->to, a->n);
        return -1;
    }
    return 0;
}

static const afmt_choice direction_choices[] = {
    {"up", AFMT_MAP_UP}, {"down", AFMT_MAP_DOWN}, {"both", AFMT_MAP_BOTH}, {NULL, 0}};

/* 0 ok, 1 --help, -1 bad usage (said). */
static int parse_args(int argc, char **argv, map_opts *o) {
    memset(o, 0, sizeof *o);
    o->integrator = o->scheme = -1;
    o->max_periods = DEFAULT_MAX_PERIODS;
    o->tol = DEFAULT_TOL;
    o->jump_tol = DEFAULT_JUMP_TOL;
    o->bistable_tol = DEFAULT_BISTABLE_TOL;
    o->jump_deg = DEFAULT_JUMP_DEG;
    o->bistable_deg = DEFAULT_BISTABLE_DEG;
    o->dirs = AFMT_MAP_BOTH;
    /* the axes take four words each: taken out here, the rest to the table parser */
    char **rest = malloc((size_t)(argc + 1) * sizeof *rest);
    if (!rest) return -1;
    int nr = 0;
    rest[nr++] = argv[0];
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
            free(rest);
            return 1;
        }
        bool isx = !strcmp(argv[i], "--x"), isy = !strcmp(argv[i], "--y");
        if (isx || isy) {
            if (i + 4 >= argc) {
                fprintf(stderr, "afmtwin map: %s wants NAME FROM TO N (NAME fe, z or ae)\n",
                        argv[i]);
                free(rest);
                return -1;
            }
            if (parse_axis(argv, argc, i, isx ? &o->x : &o->y)) {
                free(rest);
                return -1;
            }
            *(isx ? &o->have_x : &o->have_y) = true;
            i += 4;
            continue;
        }
        rest[nr++] = argv[i];
    }
    rest[nr] = NULL;
    const afmt_opt opts[] = {
        AFMT_STRING("--config", &o->config),
        AFMT_STRING("--out", &o->out),
        AFMT_CHOICE("--direction", &o->dirs, direction_choices),
        AFMT_CHOICE("--integrator", &o->integrator, afmt_integrator_choices),
        AFMT_CHOICE("--scheme", &o->scheme, afmt_scheme_choices),
        AFMT_INT("--max-periods", &o->max_periods, 2, 100000000, NULL),
        AFMT_INT("--periods", &o->max_periods, 2, 100000000, NULL),
        AFMT_DOUBLE_ABOVE("--tol", &o->tol, 0, 1, "a number in (0, 1)"),
        AFMT_DOUBLE_ABOVE("--jump-tol", &o->jump_tol, 0, 1, "a number in (0, 1)"),
        AFMT_DOUBLE_ABOVE("--bistable-tol", &o->bistable_tol, 0, 1, "a number in (0, 1)"),
        AFMT_DOUBLE_ABOVE("--jump-deg", &o->jump_deg, 0, 360, "degrees in (0, 360]"),
        AFMT_DOUBLE_ABOVE("--bistable-deg", &o->bistable_deg, 0, 360, "degrees in (0, 360]"),
        AFMT_FLAG("--resume", &o->resume),
        AFMT_INT("--stop-after", &o->stop_after, 1, 100000000, NULL),
        AFMT_OPTS_END,
    };
    int rc = afmt_opts_parse("map", opts, nr, rest, 1);
    free(rest);
    if (rc) return rc == AFMT_OPTS_HELP ? 1 : -1;
    if (!o->config || !o->out || !o->have_x || !o->have_y) {
        fprintf(stderr, "afmtwin map: --config, --x, --y and --out are required\n");
        return -1;
    }
    if (o->x.param == o->y.param &&
        (o->x.param != AFMT_MAP_NAMED || !strcmp(o->x.name, o->y.name))) {
        fprintf(stderr, "afmtwin map: --x and --y must be different parameters (both %s)\n",
                afmt_map_axis_name(&o->x));
        return -1;
    }
    if (o->tol >= 1 || o->jump_tol >= 1 || o->bistable_tol >= 1) {
        fprintf(stderr, "afmtwin map: --tol, --jump-tol and --bistable-tol must be below 1\n");
        return -1;
    }
    return 0;
}

/* The axis's parameter at value v in cfg. A named one goes through afm_param_apply, as
 * `afmtwin send param` would apply it (its range, the config's validity). 0, or -1 with err
 * (cfg unchanged). */
static int set_param(afm_config *cfg, const afmt_map_axis *a, double v, char *err, size_t errlen) {
    if (a->param == AFMT_MAP_FE)
        cfg->drive.tones[0].frequency_hz = v;
    else if (a->param == AFMT_MAP_Z)
        cfg->drive.separation_m = v;
    else if (a->param == AFMT_MAP_AE)
        cfg->drive.tones[0].amplitude_m = v;
    else {
        afm_cmd_param cp = {.n = 1};
        if (afm_param_lookup(a->name, &cp.entry[0], &cp.index[0], err, errlen) != 0) return -1;
        cp.value[0] = v;
        if (afm_param_apply(cfg, &cp, NULL, err, errlen) != 0) return -1;
    }
    return 0;
}

/* Everything a line needs, the same on every rank. */
typedef struct {
    afm_config base; /* the config with the options applied */
    afmt_map_spec spec;
    int ks[AFM_MAX_HARMONICS], nk, k1; /* harmonics analysed; k1: index of harmonic 1 */
    double fe_min;
} map_ctx;

/* Per-sample estimators: afm_cycle (as `sweep`'s) and the period's minimum tip-sample force
 * (the squeeze film apart, as afm_cycle does), the last
 * AFM_ORBIT_MAX_P completed periods of each kept, so that a point reports its whole p-period
 * orbit (a period-2 orbit may touch the sample in one period of two). */
typedef struct {
    afm_cycle cycle;
    double th_prev, f_min;
    bool have, active;
    long n_cyc, n_fmin; /* completed periods so far */
    afm_cycle_metrics cyc[AFM_ORBIT_MAX_P];
    double fmin[AFM_ORBIT_MAX_P];
} line_est;

static void on_samples(void *ctx, const afm_sim *s, const afm_sample *smp, int n) {
    line_est *e = ctx;
    const afm_drive *d = afm_sim_drive(s);
    for (int i = 0; i < n; i++) {
        double th = afm_drive_phase(d, 0, smp[i].t_s);
        if (afm_cycle_push_ev(&e->cycle, &smp[i], th, afm_sim_events_at(s, smp[i].t_s)) == 1)
            e->cyc[e->n_cyc++ % AFM_ORBIT_MAX_P] = e->cycle.out;
        if (e->have && floor(th / TWO_PI) > floor(e->th_prev / TWO_PI)) {
            if (e->active) e->fmin[e->n_fmin++ % AFM_ORBIT_MAX_P] = e->f_min;
            e->active = true;
            e->f_min = HUGE_VAL;
        }
        afm_force_parts fp; /* the tip-sample force: the total less the squeeze film's */
        afm_force_parts_at(afm_sim_forces(s), afm_sim_separation(s), smp[i].x_m, smp[i].v_m_s, &fp);
        double fts = smp[i].f_n - fp.squeeze_n;
        if (fts < e->f_min) e->f_min = fts;
        e->th_prev = th;
        e->have = true;
    }
}

/* The per-period metrics over the last np periods (the analysed orbit's): the largest peak
 * force and indentation, the smallest gap and force, the mean contact time and energy per
 * period. NAN when no period completed. */
static void orbit_metrics(const line_est *e, int np, double cos_a, double z, afmt_map_point *p) {
    int n = np < 1 ? 1 : np;
    if (n > e->n_cyc) n = (int)e->n_cyc;
    p->peak_force_n = p->min_gap_m = p->indentation_m = p->contact_time_s = p->energy_j = NAN;
    p->attractive_n = NAN;
    if (n > 0) {
        const afm_cycle_metrics *m0 = &e->cyc[(e->n_cyc - 1) % AFM_ORBIT_MAX_P];
        double pk = m0->peak_force_n, xmin = m0->min_deflection_m, ind = m0->indentation_m;
        double tc = 0.0, en = 0.0;
        for (int j = 0; j < n; j++) {
            const afm_cycle_metrics *m = &e->cyc[(e->n_cyc - 1 - j) % AFM_ORBIT_MAX_P];
            pk = fmax(pk, m->peak_force_n);
            xmin = fmin(xmin, m->min_deflection_m);
            ind = fmax(ind, m->indentation_m);
            tc += m->contact_time_s;
            en += m->dissipated_energy_j;
        }
        p->peak_force_n = pk;
        p->min_gap_m = xmin * cos_a + z;
        p->indentation_m = ind;
        p->contact_time_s = tc / n;
        p->energy_j = en / n;
    }
    int nf = np < 1 ? 1 : np;
    if (nf > e->n_fmin) nf = (int)e->n_fmin;
    for (int j = 0; j < nf; j++) {
        double f = e->fmin[(e->n_fmin - 1 - j) % AFM_ORBIT_MAX_P];
        p->attractive_n = j ? fmin(p->attractive_n, f) : f;
    }
}

/* Line iy into pts[0] (up) and pts[1] (down). 0, or -1 with err. */
static int run_line(const map_ctx *c, int iy, afmt_map_point *pts[2], char *err, size_t errlen) {
    static afm_config cfg;
    cfg = c->base;
    const afmt_map_axis *xa = &c->spec.x;
    const int nx = xa->n;
    const bool up = c->spec.dirs & AFMT_MAP_UP;
    if (set_param(&cfg, &c->spec.y, afmt_map_axis_value(&c->spec.y, iy), err, errlen) != 0 ||
        set_param(&cfg, xa, up ? xa->from : xa->to, err, errlen) != 0)
        return -1;
    if (afm_config_validate(&cfg, err, errlen) != 0) return -1;
    afm_sim *sim = afm_twin_create(&cfg, NULL, NULL, err, errlen);
    if (!sim) return -1;
    static afm_sweep sw;
    static line_est est;
    static afm_orbit ob;
    memset(&est, 0, sizeof est);
    est.f_min = HUGE_VAL;
    double z = afm_sim_separation(sim);
    const double cos_a = afm_sim_forces(sim)->cos_alpha;
    if (afm_sweep_init(&sw, cfg.sim.sample_rate_hz, c->fe_min, c->spec.tol, c->spec.max_periods,
                       c->ks, c->nk, err, errlen) != 0) {
        afm_sim_destroy(&sim);
        return -1;
    }
    /* the per-period metrics from the integrator's record (afmt_step_events) */
    afm_step_events *ev_ring = afmt_step_events_ring(sim, sw.cap);
    int rc = -1;
    if (afm_cycle_init(&est.cycle, afm_force_contact_x(afm_sim_forces(sim), z), cos_a, err,
                       errlen) != 0 ||
        afm_cycle_set_forces(&est.cycle, afm_sim_forces(sim), z) != 0)
        goto out;
    sw.on_samples = on_samples;
    sw.on_samples_ctx = &est;
    double fe = cfg.drive.tones[0].frequency_hz, ae = cfg.drive.tones[0].amplitude_m;
    bool x_damping = false;
    if (xa->param == AFMT_MAP_NAMED) {
        int entry, index, nd;
        if (afm_param_lookup(xa->name, &entry, &index, err, errlen) != 0) goto out;
        x_damping = afm_param_table(&nd)[entry].effect == AFM_PARAM_DAMPING;
    }
    for (int d = 0; d < 2; d++) {
        if (!pts[d]) continue;
        for (int k = 0; k < nx; k++) {
            int ix = d ? nx - 1 - k : k;
            double xv = afmt_map_axis_value(xa, ix);
            int settled;
            if (xa->param == AFMT_MAP_NAMED && x_damping) {
                /* a damping parameter: a new simulator of the new model that continues the
                 * old one's drive, Z, time and modal state, as the daemon swaps one in */
                if (set_param(&cfg, xa, xv, err, errlen) != 0) goto out;
                afm_sim *ns = afm_twin_create(&cfg, NULL, NULL, err, errlen);
                if (!ns) goto out;
                if (afm_sim_continue(ns, sim, AFM_SIM_KEEP_DRIVE | AFM_SIM_KEEP_STATE) !=
                    AFM_SIM_OK) {
                    snprintf(err, errlen, "cannot carry the state to %s = %g", xa->name, xv);
                    afm_sim_destroy(&ns);
                    goto out;
                }
                if (ev_ring) afm_sim_set_events(ns, ev_ring, 2 * sw.cap);
                afm_sim_destroy(&sim);
                sim = ns;
                afm_cycle_set_forces(&est.cycle, afm_sim_forces(sim), z);
                settled = afm_sweep_dwell(&sw, sim, &ob, err, errlen);
            } else if (xa->param == AFMT_MAP_NAMED) { /* a force parameter: state kept */
                static afm_force_params f;
                if (set_param(&cfg, xa, xv, err, errlen) != 0 ||
                    afm_twin_forces(&cfg, afm_sim_model(sim), NULL, &f, err, errlen) != 0)
                    goto out;
                if (afm_sim_set_forces(sim, &f) != AFM_SIM_OK) {
                    snprintf(err, errlen, "cannot set %s = %g", xa->name, xv);
                    goto out;
                }
                afm_cycle_set_forces(&est.cycle, afm_sim_forces(sim), z);
                settled = afm_sweep_dwell(&sw, sim, &ob, err, errlen);
            } else if (xa->param == AFMT_MAP_Z) {
                if (afm_sim_set_separation(sim, xv) != AFM_SIM_OK) {
                    snprintf(err, errlen, "cannot set Z = %g m", xv);
                    goto out;
                }
                z = xv;
                afm_cycle_set_forces(&est.cycle, afm_sim_forces(sim), z);
                settled = afm_sweep_dwell(&sw, sim, &ob, err, errlen);
            } else {
                if (xa->param == AFMT_MAP_FE)
                    fe = xv;
                else
                    ae = xv;
                settled = afm_sweep_step(&sw, sim, fe, ae, &ob, err, errlen);
            }
            if (settled < 0) goto out;
            afmt_map_point *p = &pts[d][ix];
            const afm_orbit_harmonic *h = &ob.harmonics[c->k1];
            p->amplitude_m = h->x_amp_m;
            p->lag_deg = afm_orbit_lag_deg(h->x_phase_deg);
            orbit_metrics(&est, ob.p, cos_a, z, p);
            p->settled = settled == 1;
            p->periodicity = settled == 1 ? sw.st.p : 0;
            p->settle_periods = sw.st.periods;
        }
    }
    rc = 0;
out:
    afm_sweep_destroy(&sw);
    afm_sim_destroy(&sim);
    free(ev_ring);
    return rc;
}

/* Line iy as its text block (malloc'd), or an error text starting with '!'. */
static char *line_block(const map_ctx *c, int iy) {
    const int nx = c->spec.x.n;
    afmt_map_point *pts[2] = {NULL, NULL};
    char err[AFM_ERR_LEN];
    char *b = NULL;
    for (int d = 0; d < 2; d++)
        if (c->spec.dirs & (1 << d)) {
            pts[d] = calloc((size_t)nx, sizeof(afmt_map_point));
            if (!pts[d]) {
                snprintf(err, sizeof err, "out of memory");
                goto fail;
            }
        }
    if (run_line(c, iy, pts, err, sizeof err) != 0) goto fail;
    b = afmt_map_block(&c->spec, iy, (const afmt_map_point *const *)pts);
    if (!b) snprintf(err, sizeof err, "out of memory");
fail:
    free(pts[0]);
    free(pts[1]);
    if (b) return b;
    size_t n = strlen(err) + 64;
    b = malloc(n);
    if (b) snprintf(b, n, "!line %d: %s", iy, err);
    return b;
}

/* The config with the options, checked at the map's corners. 0, or -1 (said). */
static int map_setup(const map_opts *o, map_ctx *c) {
    afm_config *cfg = &c->base;
    if (afmt_config_load("map", o->config, cfg)) return -1;
    if (o->integrator >= 0) cfg->sim.integrator = (afm_integrator_kind)o->integrator;
    if (o->scheme >= 0) cfg->sim.rt_scheme = (afm_rt_scheme_kind)o->scheme;
    c->spec.config_path = o->config;
    if (afmt_map_hash_file(o->config, &c->spec.config_hash)) {
        fprintf(stderr, "afmtwin map: cannot read %s: %s\n", o->config, strerror(errno));
        return -1;
    }
    c->spec.x = o->x;
    c->spec.y = o->y;
    c->spec.dirs = o->dirs;
    c->spec.tol = o->tol;
    c->spec.jump_tol = o->jump_tol;
    c->spec.bistable_tol = o->bistable_tol;
    c->spec.jump_deg = o->jump_deg;
    c->spec.bistable_deg = o->bistable_deg;
    c->spec.max_periods = o->max_periods;
    static const char *const integ[] = {"rt", "reference", "arkode-erk"};
    c->spec.integrator = integ[cfg->sim.integrator];
    c->spec.scheme = cfg->sim.integrator != AFM_INTEGRATOR_RT   ? "-"
                     : cfg->sim.rt_scheme == AFM_RT_SCHEME_FAST ? "fast"
                                                                : "accurate";
    /* harmonics as `sweep`: the config's list, else 1,6,17; harmonic 1 added if missing */
    if (cfg->sim.n_harmonics > 0) {
        c->nk = cfg->sim.n_harmonics;
        memcpy(c->ks, cfg->sim.harmonics, (size_t)c->nk * sizeof c->ks[0]);
    } else {
        c->nk = (int)(sizeof default_harmonics / sizeof default_harmonics[0]);
        memcpy(c->ks, default_harmonics, sizeof default_harmonics);
    }
    c->k1 = -1;
    for (int k = 0; k < c->nk; k++)
        if (c->ks[k] == 1) c->k1 = k;
    if (c->k1 < 0) {
        if (c->nk == AFM_MAX_HARMONICS) c->nk--;
        c->ks[c->nk] = 1;
        c->k1 = c->nk++;
    }
    double fe_lo = cfg->drive.tones[0].frequency_hz, fe_hi = fe_lo;
    const afmt_map_axis *ax[2] = {&o->x, &o->y};
    for (int a = 0; a < 2; a++)
        if (ax[a]->param == AFMT_MAP_FE) {
            fe_lo = ax[a]->from;
            fe_hi = ax[a]->to;
        }
    c->fe_min = fe_lo;
    const double fs = cfg->sim.sample_rate_hz;
    for (int k = 0; k < c->nk; k++)
        if ((double)c->ks[k] * fe_hi >= 0.5 * fs) {
            fprintf(stderr,
                    "afmtwin map: harmonic %d of %g Hz is not below half the sample rate, %g Hz "
                    "(config sim.harmonics)\n",
                    c->ks[k], fe_hi, 0.5 * fs);
            return -1;
        }
    static afm_config t;
    char err[AFM_ERR_LEN];
    for (int corner = 0; corner < 4; corner++) {
        t = *cfg;
        if (set_param(&t, &o->y, corner & 2 ? o->y.to : o->y.from, err, sizeof err) != 0 ||
            set_param(&t, &o->x, corner & 1 ? o->x.to : o->x.from, err, sizeof err) != 0 ||
            afm_config_validate(&t, err, sizeof err) != 0) {
            fprintf(stderr, "afmtwin map: at x %s = %g, y %s = %g: %s\n", afmt_map_axis_name(&o->x),
                    corner & 1 ? o->x.to : o->x.from, afmt_map_axis_name(&o->y),
                    corner & 2 ? o->y.to : o->y.from, err);
            return -1;
        }
    }
    return 0;
}

/* Rank 0: open the output (fresh, or resumed after its check). lines_done < 0: error
 * (said), nothing changed. */
static FILE *open_out(const map_opts *o, const char *header, int ny, int *lines_done) {
    *lines_done = -1;
    char err[512];
    if (o->resume && access(o->out, F_OK) == 0) {
        long keep;
        int done;
        if (afmt_map_resume_check(o->out, header, ny, &done, &keep, err, sizeof err)) {
            fprintf(stderr, "afmtwin map: %s\n", err);
            return NULL;
        }
        if (truncate(o->out, keep) != 0) {
            fprintf(stderr, "afmtwin map: cannot truncate %s: %s\n", o->out, strerror(errno));
            return NULL;
        }
        FILE *f = fopen(o->out, "ab");
        if (!f) {
            fprintf(stderr, "afmtwin map: cannot write %s: %s\n", o->out, strerror(errno));
            return NULL;
        }
        fprintf(stderr, "afmtwin map: resuming %s: %d of %d lines done\n", o->out, done, ny);
        *lines_done = done;
        return f;
    }
    FILE *f = fopen(o->out, "wb");
    if (!f) {
        fprintf(stderr, "afmtwin map: cannot write %s: %s\n", o->out, strerror(errno));
        return NULL;
    }
    if (fputs(header, f) < 0 || fflush(f) != 0 || fsync(fileno(f)) != 0) {
        fprintf(stderr, "afmtwin map: cannot write %s: %s\n", o->out, strerror(errno));
        fclose(f);
        return NULL;
    }
    *lines_done = 0;
    return f;
}

static int write_block(FILE *f, const char *b) {
    size_t n = strlen(b);
    return fwrite(b, 1, n, f) == n && fflush(f) == 0 && fsync(fileno(f)) == 0 ? 0 : -1;
}

/* Silence the ranks other than 0 while the arguments are checked (every rank checks the
 * same things; one says what is wrong). */
static bool rank0_by_env(void) {
    const char *r = getenv("OMPI_COMM_WORLD_RANK");
    if (!r) r = getenv("PMIX_RANK");
    return !r || !strcmp(r, "0");
}

int afm_cmd_map(int argc, char **argv) {
    map_opts o;
    int err_save = -1;
    if (!rank0_by_env()) { /* the other ranks: no duplicate messages about the arguments */
        fflush(stderr);
        int null = open("/dev/null", O_WRONLY);
        if (null >= 0) {
            err_save = dup(STDERR_FILENO);
            dup2(null, STDERR_FILENO);
            close(null);
        }
    }
    int rc = afmt_opts_done("map", parse_args(argc, argv, &o), map_usage);
    static map_ctx ctx;
    if (rc < 0 && map_setup(&o, &ctx) != 0) rc = 2;
    if (err_save >= 0) {
        fflush(stderr);
        dup2(err_save, STDERR_FILENO);
        close(err_save);
    }
    if (rc >= 0) return rc;
    char *header = afmt_map_header(&ctx.spec);
    if (!header) {
        fprintf(stderr, "afmtwin map: out of memory\n");
        return 1;
    }

#if AFMT_NO_MPI
    /* Under mpirun (Open MPI: OMPI_COMM_WORLD_SIZE) every copy would be rank 0 of 1 and
     * write the whole file at once. */
    const char *world = getenv("OMPI_COMM_WORLD_SIZE");
    if (!world) world = getenv("PMI_SIZE"); /* MPICH, Slurm */
    if (world && atoi(world) > 1) {
        if (rank0_by_env())
            fprintf(stderr,
                    "afmtwin map: this afmtwin is built without MPI (AFMTWIN_MPI=0): it cannot "
                    "share a map among %s ranks; run it without mpirun, or use a build with MPI\n",
                    world);
        free(header);
        return 2;
    }
#endif
    MPI_Init(&argc, &argv);
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    const int ny = o.y.n;
    int done = 0;
    FILE *out = NULL;
    if (rank == 0) out = open_out(&o, header, ny, &done);
    MPI_Bcast(&done, 1, MPI_INT, 0, MPI_COMM_WORLD);
    free(header);
    if (done < 0) {
        MPI_Finalize();
        return 2;
    }
    int last = ny;
    if (o.stop_after > 0 && done + o.stop_after < ny) last = done + o.stop_after;
    int status = 0;
    if (rank == 0) {
        afmt_progress pg;
        afmt_progress_init(&pg);
        for (int iy = done; iy < last; iy++) {
            int owner = (iy - done) % size;
            char *b = NULL;
            if (owner == 0) {
                b = line_block(&ctx, iy);
            } else {
                MPI_Status st;
                int n;
                MPI_Probe(owner, iy, MPI_COMM_WORLD, &st);
                MPI_Get_count(&st, MPI_CHAR, &n);
                b = malloc((size_t)n + 1);
                if (b) {
                    MPI_Recv(b, n, MPI_CHAR, owner, iy, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
                    b[n] = '\0';
                }
            }
            if (!b || b[0] == '!') {
                afmt_progress_end(&pg);
                fprintf(stderr, "afmtwin map: %s\n", b ? b + 1 : "out of memory");
                status = 1;
                free(b);
                break;
            }
            if (write_block(out, b) != 0) {
                afmt_progress_end(&pg);
                fprintf(stderr, "afmtwin map: cannot write %s: %s\n", o.out, strerror(errno));
                status = 1;
                free(b);
                break;
            }
            free(b);
            afmt_progress_update(&pg, "map: line %d/%d written (%d ranks)", iy + 1, ny, size);
        }
        afmt_progress_end(&pg);
        if (fclose(out) != 0 && status == 0) {
            fprintf(stderr, "afmtwin map: cannot write %s: %s\n", o.out, strerror(errno));
            status = 1;
        }
        if (status == 0 && last < ny)
            fprintf(stderr, "afmtwin map: stopped after line %d of %d (--stop-after)\n", last, ny);
        if (status != 0 && size > 1) MPI_Abort(MPI_COMM_WORLD, status); /* workers may wait */
    } else {
        int mine = 0;
        for (int iy = done; iy < last; iy++)
            if ((iy - done) % size == rank) mine++;
        char **bufs = calloc((size_t)mine + 1, sizeof *bufs);
        MPI_Request *req = calloc((size_t)mine + 1, sizeof *req);
        if (!bufs || !req) MPI_Abort(MPI_COMM_WORLD, 1);
        int k = 0;
        for (int iy = done; iy < last; iy++) {
            if ((iy - done) % size != rank) continue;
            bufs[k] = line_block(&ctx, iy);
            if (!bufs[k]) MPI_Abort(MPI_COMM_WORLD, 1);
            MPI_Isend(bufs[k], (int)strlen(bufs[k]), MPI_CHAR, 0, iy, MPI_COMM_WORLD, &req[k]);
            k++;
            if (bufs[k - 1][0] == '!') break; /* rank 0 reports it and stops */
        }
        MPI_Waitall(k, req, MPI_STATUSES_IGNORE);
        for (int i = 0; i < k; i++)
            free(bufs[i]);
        free(bufs);
        free(req);
    }
    MPI_Finalize();
    return status;
}
