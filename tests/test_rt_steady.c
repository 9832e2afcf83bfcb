/* SPDX-License-Identifier: MIT */
/* test_rt_steady.c -- the steady states of the rt integrator against CVODE along whole
 * approach + retract curves (run from the repository root; the CLI is
 * AFMTWIN_BUILD/bin/afmtwin, default build/).
 *
 * Why: the accurate scheme of rt (the tip force cubic Hermite in time, contact samples redone
 * in substeps) is the offline default because it claims CVODE's steady state; the daemon's
 * fast scheme is its second-order fallback. test_rt_accuracy compares single orbits; this suite
 * compares what a user reads off an approach curve -- amplitude, phase lag, peak force, energy
 * per period, whether a step settled and where the regime jumps -- step by step, with the same
 * arguments run three times: --integrator reference (CVODE, the truth), --scheme accurate and
 * --scheme fast. Steps are matched by index (same Z and direction).
 *
 * The cases: the Q 300 probe with conservative forces (attractive only, 2 Q dk/k turns any
 * bias of the force into phase), the same probe through the attractive/repulsive jump at
 * A0 20 nm, the 1-DOF thesis model with a viscoelastic contact, sample rates other than the
 * config's 14.06 MHz (12 MHz is a whole 40 samples per period: the contact then falls on the
 * same sample phase every period) and the NCHV beam with and without its squeeze film.
 *
 * The per-period metrics (energy, contact time, min deflection, the peak's contact part) come
 * from each integrator's own record of its steps, approach's default (issue 28): rt's pieces,
 * CVODE's dense output (afm_sundials_ev.c), so the reference is CVODE's continuous solution
 * and not the samples' estimator on both sides. Worst measured with them: energy 0.031 eV
 * (NCHV, squeeze film off; on: 0.022; both with rt's mean over 4096 periods, see nchv_rt:
 * over the default 16 it was 0.0497, the sample grid's beat), contact time 0.022 ns, min
 * deflection 0.144 pm (through the jump); asserted at
 * 0.05 ns and 0.3 pm (docs/numerics.md). AFMTWIN_STEADY_ONLY=TEXT runs only the cases whose
 * name contains TEXT.
 *
 * Asserted for the accurate scheme (every case): phase lag within 0.02 deg, amplitude 1e-4
 * relative, peak force 2e-3 relative (where CVODE's exceeds 1 nN), energy per period within
 * 0.05 eV (0.005 eV on the attractive Q 300 curve, conservative: ENERGY_CONSERVATIVE_EV), the
 * regime jumps between the same two steps; and, for the cases flagged "must
 * settle", a settled orbit at every step CVODE settled. The fast scheme is pinned at today's
 * level only, loosely (phase 2 deg, amplitude 5e-3): it is ~0.1-0.5 deg off (1.46 deg at 15 MHz, 50
 * samples per period, in the full grid), so its figures in place of the accurate ones fail the
 * accurate bounds, which shows the bounds bite. make test runs the two Q 300 curves, the 1-DOF
 * model and 12 MHz; AFMTWIN_VALIDATE=full (make validate) adds 20 MHz, 15 MHz, both NCHV
 * curves and 0.5 nm steps on the two Q 300 curves.
 *
 * Measured with 32 contact substeps (the accurate scheme's default; worst over the curve):
 * phase 0.0001-0.003 deg (12 MHz, 40 samples per period: 0.0030; with 16 substeps it was
 * 0.0224, over the bound, because a whole multiple of fe puts the contact on the same cell of
 * the crossing grid every period and its rounding does not average out), amplitude <= 2.3e-5,
 * peak force <= 1.5e-4, energy <= 0.034 eV (NCHV), jumps the same, every Q 300 step settled.
 * Of the steps CVODE settles, rt leaves NCHV's and some of the 1-DOF model's unsettled at
 * 1e-6 (not asserted there). Fast: 0.02-0.52 deg, amplitude <= 2.3e-3; at 15 MHz (50 per
 * period, full only) 1.46 deg.
 *
 * The time: CVODE is nearly all of it (~95 s of CPU: 35, 29, 14 and 17 s for the four make test
 * curves). Each step runs 12 lock-in time constants past its dwell (1.2 ms, 360 periods of
 * the Q 300 probe); that tail is settling too: with the lock-in at 1e-6 s (the analysed 17
 * periods right after the 1e-6 dwell) the 11 -> 3 nm curve read contact time 0.076 ns off
 * CVODE's (0.022 with it; bound 0.05), phase 0.0031 deg (0.0002). Not a saving to take. */
#include "check.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define MAXSTEP 128
#define MAXJUMP 16
#define EV_J 1.602176634e-19
/* The energy bound (eV) where the tip dissipates (contact, squeeze film): issue 11's. */
#define ENERGY_EV 0.05
/* The Q 300 probe at A0 10 nm from 11 to 3 nm (attractive branch throughout: the vdW pulse
 * at the turning point, a shallow DMT touch; no viscous term): conservative, so the energy per
 * period is exactly 0, and CVODE's and the accurate scheme's agree within 0.00054 eV (worst
 * step). Without the work of the free steps in rt's step record (pieces kept whole clear of
 * the contact line, where the vdW tail still acts near the turning point: afm_rt_evrec.h
 * rt_ev_free) the record's energy reads 0.0287 eV off, inside ENERGY_EV, and no other bound
 * moves. Asserted at 0.005 eV: 9x the worst measured, 1/6 of that mutation. (The cases that
 * jump into repulsive contact, conservative too, read 0.009-0.016 eV: the kink's rounding,
 * kept at ENERGY_EV.) */
#define ENERGY_CONSERVATIVE_EV 0.005

typedef struct {
    const char *name;
    const char *config;
    const char *from, *to; /* text replaced in the config (a temp copy), NULL: none */
    const char *args;      /* approach arguments besides --config, --integrator, --scheme */
    bool must_settle;
    const char *rt_args; /* more arguments for the two rt runs only, NULL: none (below) */
    double energy_ev;    /* the accurate scheme's energy bound (eV), 0: ENERGY_EV */
} steady_case;

typedef struct {
    double z, amp, phase, peak, energy, contact, xmin;
    bool retract, settled;
} step_rec;

typedef struct {
    int after; /* the number of steps before the jump line */
    bool retract;
    char to[16]; /* the regime jumped to */
} jump_rec;

typedef struct {
    int n_step, n_jump;
    step_rec s[MAXSTEP];
    jump_rec j[MAXJUMP];
    bool ok;
} curve;

/* The figures of one scheme against CVODE over one curve. */
typedef struct {
    double phase_deg, amp_rel, peak_rel, energy_ev;
    double contact_s, xmin_m; /* max |difference| where CVODE's orbit is in contact */
    int n_peak, n_contact, unsettled, n_settled;
    bool jumps_same, steps_match;
} figures;

static char bin[512];

static double num(const cJSON *o, const char *k) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
    return cJSON_IsNumber(v) ? v->valuedouble : NAN;
}

static const char *str(const cJSON *o, const char *k) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
    return cJSON_IsString(v) ? v->valuestring : "";
}

/* AFMTWIN_STEADY_REF_CACHE=DIR (a mutation run): CVODE's curves are kept in DIR, named by a
 * hash of the config's text and the arguments, and read back instead of rerun (CVODE is
 * nearly all of the suite's time, and a mutant of rt does not change it). Fill the cache from
 * an unmutated build. Returns false when unset or the config is unreadable. */
static bool ref_cache_name(const char *config, const char *args, const char *extra, char *out,
                           size_t cap) {
    const char *dir = getenv("AFMTWIN_STEADY_REF_CACHE");
    if (!dir || !*dir) return false;
    FILE *f = fopen(config, "r");
    if (!f) return false;
    unsigned long long h = 1469598103934665603ULL; /* FNV-1a 64 */
    int ch;
    while ((ch = fgetc(f)) != EOF)
        h = (h ^ (unsigned char)ch) * 1099511628211ULL;
    fclose(f);
    for (const char *t = args; *t; t++)
        h = (h ^ (unsigned char)*t) * 1099511628211ULL;
    h = (h ^ '|') * 1099511628211ULL;
    for (const char *t = extra; *t; t++)
        h = (h ^ (unsigned char)*t) * 1099511628211ULL;
    snprintf(out, cap, "%s/ref-%016llx.jsonl", dir, h);
    return true;
}

/* Run `afmtwin approach --config config args extra --json` into c. want_integrator and
 * want_scheme: what every step record must report (the option was honoured). */
static void run(const char *config, const char *args, const char *extra,
                const char *want_integrator, const char *want_scheme, curve *c) {
    char cmd[1024], what[1200], cache[600] = "", part[620] = "";
    snprintf(cmd, sizeof cmd, "%s approach --config %s %s %s --json", bin, config, args, extra);
    memset(c, 0, sizeof *c);
    FILE *keep = NULL; /* the reference's records on their way into the cache */
    if (!want_scheme && ref_cache_name(config, args, extra, cache, sizeof cache)) {
        if (access(cache, R_OK) == 0) {
            snprintf(cmd, sizeof cmd, "cat %s", cache);
        } else {
            snprintf(part, sizeof part, "%s.part", cache);
            keep = fopen(part, "w");
        }
    }
    FILE *p = popen(cmd, "r");
    if (!check_true(p != NULL, cmd)) {
        if (keep) fclose(keep);
        return;
    }
    static char line[1 << 16];
    bool labels = true, room = true;
    while (fgets(line, sizeof line, p)) {
        if (keep) fputs(line, keep);
        cJSON *o = cJSON_Parse(line);
        if (!o) continue;
        const cJSON *jp = cJSON_GetObjectItemCaseSensitive(o, "jump");
        if (jp && c->n_jump < MAXJUMP) {
            jump_rec *j = &c->j[c->n_jump++];
            j->after = c->n_step;
            j->retract = !strcmp(str(jp, "direction"), "retract");
            snprintf(j->to, sizeof j->to, "%s", str(jp, "to"));
        } else if (!jp && c->n_step < MAXSTEP) {
            step_rec *s = &c->s[c->n_step++];
            s->z = num(o, "z_m");
            s->amp = num(o, "amplitude_m");
            s->phase = num(o, "phase_lag_deg");
            s->peak = num(o, "peak_force_n");
            s->energy = num(o, "dissipated_energy_j");
            s->contact = num(o, "contact_time_s");
            s->xmin = num(o, "min_deflection_m");
            s->retract = !strcmp(str(o, "direction"), "retract");
            s->settled = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(o, "settled"));
            labels = labels && !strcmp(str(o, "integrator"), want_integrator) &&
                     (!want_scheme || !strcmp(str(o, "scheme"), want_scheme));
        } else {
            room = false;
        }
        cJSON_Delete(o);
    }
    int rc = pclose(p);
    if (keep) { /* only a whole run is kept */
        bool kept = fclose(keep) == 0 && rc == 0;
        if (!(kept && rename(part, cache) == 0)) unlink(part);
    }
    snprintf(what, sizeof what, "exit 0, records in room: %s", cmd);
    c->ok = check_true(rc == 0 && room && c->n_step > 0, what);
    snprintf(what, sizeof what, "every step reports integrator %s, scheme %s", want_integrator,
             want_scheme ? want_scheme : "-");
    check_true(labels, what);
}

static figures compare(const curve *ref, const curve *rt) {
    figures f = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0, 0, true, true};
    f.steps_match = ref->n_step == rt->n_step;
    for (int i = 0; f.steps_match && i < ref->n_step; i++) {
        const step_rec *a = &ref->s[i], *b = &rt->s[i];
        if (fabs(a->z - b->z) > 1e-15 || a->retract != b->retract) {
            f.steps_match = false;
            break;
        }
        f.phase_deg = fmax(f.phase_deg, fabs(b->phase - a->phase));
        f.amp_rel = fmax(f.amp_rel, fabs(b->amp - a->amp) / fabs(a->amp));
        if (fabs(a->peak) > 1e-9) {
            f.peak_rel = fmax(f.peak_rel, fabs(b->peak - a->peak) / fabs(a->peak));
            f.n_peak++;
        }
        f.energy_ev = fmax(f.energy_ev, fabs(b->energy - a->energy) / EV_J);
        if (a->contact > 0.0) {
            f.contact_s = fmax(f.contact_s, fabs(b->contact - a->contact));
            f.xmin_m = fmax(f.xmin_m, fabs(b->xmin - a->xmin));
            f.n_contact++;
            if (isnan(b->contact + b->xmin + a->xmin)) f.steps_match = false;
        }
        if (a->settled) f.n_settled++;
        if (a->settled && !b->settled) f.unsettled++;
        /* NaN (a key missing) anywhere poisons the maxima: fmax would drop it */
        if (isnan(a->phase + b->phase + a->amp + b->amp + a->energy + b->energy + a->peak +
                  b->peak))
            f.steps_match = false;
    }
    f.jumps_same = ref->n_jump == rt->n_jump;
    for (int i = 0; f.jumps_same && i < ref->n_jump; i++)
        f.jumps_same = ref->j[i].after == rt->j[i].after && ref->j[i].retract == rt->j[i].retract &&
                       !strcmp(ref->j[i].to, rt->j[i].to);
    return f;
}

static void report(const steady_case *k, const char *scheme, const curve *ref, const figures *f) {
    printf("# %-34s %-8s steps %2d  phase %.5f deg  amp %.3e  peak %.3e (%d steps > 1 nN)  "
           "energy %.5f eV  contact time %.4f ns  min deflection %.4f pm (%d in contact)  "
           "unsettled %d/%d  jumps %d %s\n",
           k->name, scheme, ref->n_step, f->phase_deg, f->amp_rel, f->peak_rel, f->n_peak,
           f->energy_ev, f->contact_s * 1e9, f->xmin_m * 1e12, f->n_contact, f->unsettled,
           f->n_settled, ref->n_jump, f->jumps_same ? "same" : "DIFFER");
}

static void assert_accurate(const steady_case *k, const figures *f) {
    char what[256];
    /* issue 11's bound is 0.02 deg; asserted at 0.008, 2.6x the worst measured (0.0031 at
     * 12 MHz), so that a regression inside the bound still fails: without the split
     * at the crossing (a crossing substep one linear piece) 12 MHz reads 0.0136 */
    snprintf(what, sizeof what, "%s, accurate: max |phase lag - CVODE| (deg, issue 11: 0.02)",
             k->name);
    check_abs(f->phase_deg, 0.0, 0.008, what);
    snprintf(what, sizeof what, "%s, accurate: max |amplitude / CVODE - 1|", k->name);
    check_abs(f->amp_rel, 0.0, 1e-4, what);
    if (f->n_peak > 0) {
        snprintf(what, sizeof what, "%s, accurate: max |peak force / CVODE - 1| (> 1 nN)", k->name);
        check_abs(f->peak_rel, 0.0, 2e-3, what);
    }
    snprintf(what, sizeof what, "%s, accurate: max |energy per period - CVODE| (eV)", k->name);
    check_abs(f->energy_ev, 0.0, k->energy_ev > 0.0 ? k->energy_ev : ENERGY_EV, what);
    /* both from the integrators' records (CVODE's dense output, rt's pieces): rt's own orbit
     * (worst 0.022 ns and 0.14 pm), below what the samples' estimator resolves (0.04-0.06 ns,
     * 0.26-0.37 pm: CVODE's OBD-rate samples against 16x, docs/numerics.md) */
    if (f->n_contact > 0) {
        snprintf(what, sizeof what, "%s, accurate: max |contact time - CVODE| (ns)", k->name);
        check_abs(f->contact_s * 1e9, 0.0, 0.05, what);
        snprintf(what, sizeof what, "%s, accurate: max |min deflection - CVODE| (pm)", k->name);
        check_abs(f->xmin_m * 1e12, 0.0, 0.3, what);
    }
    snprintf(what, sizeof what, "%s, accurate: regime jumps between the same steps as CVODE",
             k->name);
    check_true(f->jumps_same, what);
    if (k->must_settle) {
        snprintf(what, sizeof what, "%s, accurate: settled at every step CVODE settled (%d)",
                 k->name, f->n_settled);
        check_true(f->unsettled == 0, what);
    }
}

static void assert_fast(const steady_case *k, const figures *f) {
    char what[256];
    snprintf(what, sizeof what, "%s, fast (today's level): max |phase lag - CVODE| (deg)", k->name);
    check_abs(f->phase_deg, 0.0, 2.0, what);
    snprintf(what, sizeof what, "%s, fast (today's level): max |amplitude / CVODE - 1|", k->name);
    check_abs(f->amp_rel, 0.0, 5e-3, what);
}

/* A temp copy of path with the text from replaced by to (which must occur exactly once) in
 * out (a mkstemp name). Returns 0 on success. */
static int temp_config(const char *path, const char *from, const char *to, char *out, size_t cap) {
    static char text[1 << 16];
    char what[256];
    FILE *in = fopen(path, "r");
    if (!check_true(in != NULL, path)) return -1;
    size_t n = fread(text, 1, sizeof text - 1, in);
    bool whole = feof(in) != 0;
    fclose(in);
    text[n] = '\0';
    char *at = strstr(text, from);
    snprintf(what, sizeof what, "%s holds \"%s\" exactly once", path, from);
    if (!check_true(whole && at && !strstr(at + 1, from), what)) return -1;
    snprintf(out, cap, "/tmp/afmtwin-rt-steady-XXXXXX");
    int fd = mkstemp(out);
    if (!check_true(fd >= 0, "mkstemp /tmp/afmtwin-rt-steady-XXXXXX")) return -1;
    FILE *f = fdopen(fd, "w");
    if (!f) {
        close(fd);
        unlink(out);
        check_true(false, "fdopen of the temp config");
        return -1;
    }
    fwrite(text, 1, (size_t)(at - text), f);
    fputs(to, f);
    fputs(at + strlen(from), f);
    if (!check_true(fclose(f) == 0, "write the temp config")) {
        unlink(out);
        return -1;
    }
    return 0;
}

static void one_case(const steady_case *k) {
    static curve ref, acc, fast;
    char path[256];
    const char *config = k->config;
    if (k->from) {
        if (temp_config(k->config, k->from, k->to, path, sizeof path) != 0) return;
        config = path;
    }
    run(config, k->args, "--integrator reference", "reference", NULL, &ref);
    char rt_acc[256], rt_fast[256];
    snprintf(rt_acc, sizeof rt_acc, "--integrator rt --scheme accurate %s",
             k->rt_args ? k->rt_args : "");
    snprintf(rt_fast, sizeof rt_fast, "--integrator rt --scheme fast %s",
             k->rt_args ? k->rt_args : "");
    run(config, k->args, rt_acc, "rt", "accurate", &acc);
    run(config, k->args, rt_fast, "rt", "fast", &fast);
    if (k->from) unlink(path);
    if (!ref.ok || !acc.ok || !fast.ok) return;
    char what[256];
    figures fa = compare(&ref, &acc), ff = compare(&ref, &fast);
    report(k, "accurate", &ref, &fa);
    report(k, "fast", &ref, &ff);
    snprintf(what, sizeof what, "%s: accurate and fast visit CVODE's steps (Z, direction)",
             k->name);
    if (!check_true(fa.steps_match && ff.steps_match, what)) return;
    assert_accurate(k, &fa);
    assert_fast(k, &ff);
}

static const char *const q300_rate = "sample_rate_hz = 14.06e6;";
static const char *const nchv_squeeze =
    "squeeze = { model = \"linear\"; p1_n_s_m2 = -1.695e-3; p2_n_s_m = 7.21e-9; };";

int main(void) {
    const char *b = getenv("AFMTWIN_BUILD");
    snprintf(bin, sizeof bin, "%s/bin/afmtwin", b && *b ? b : "build");
    const char *v = getenv("AFMTWIN_VALIDATE");
    const bool full = v && !strcmp(v, "full");
    const char *q = "config/probe-q300.conf";
    const char *rates = "--from 9e-9 --to 5e-9 --step 2e-9 --retract --periods 3000";
    /* NCHV at 14.06 MHz is 41.584 samples a period: rt's contact falls on a slowly moving
     * phase of its sample grid, so its orbit never repeats (never "settled") and the mean of
     * the default 16 analysed periods wanders with that beat: energy at Z 36 nm 145.519,
     * 145.527, 145.581, 145.538, 145.568 eV after 6000, 12000, 20000, 30000, 60000 periods
     * (CVODE 145.569), the worst gap 0.0497 eV at 6000; not a drift. Over 4096 periods (the
     * most approach analyses) it is 145.554 / 145.551 after 6000 / 12000. At 14.200704 MHz (42
     * a period) rt settles in ~500 periods like CVODE. So the rt runs of NCHV take the mean
     * over 4096 periods (+0.3 s each); CVODE's settled orbit keeps the default 16 (its 4096
     * would cost ~6 min). */
    const char *nchv_rt = "--analyse 4096";
    /* AFMTWIN_STEADY_ONLY=TEXT: only the cases whose name contains TEXT (a mutation run) */
    const char *only = getenv("AFMTWIN_STEADY_ONLY");
    const steady_case cases[] = {
        {"Q 300, conservative, 11 -> 3 nm", q, NULL, NULL,
         full ? "--from 11e-9 --to 3e-9 --step 0.5e-9 --retract --periods 3000"
              : "--from 11e-9 --to 3e-9 --step 1e-9 --retract --periods 3000",
         true, NULL, ENERGY_CONSERVATIVE_EV},
        {"Q 300, A0 20 nm, through the jump", q, NULL, NULL,
         full ? "--ae 6.6667e-11 --from 21e-9 --to 15e-9 --step 0.5e-9 --retract --periods 4000"
              : "--ae 6.6667e-11 --from 21e-9 --to 15e-9 --step 1e-9 --retract --periods 4000",
         true, NULL, 0.0},
        {"1-DOF thesis, viscoelastic contact", "config/thesis-1dof.conf", NULL, NULL,
         "--from 16e-9 --to 12e-9 --step 2e-9 --retract --periods 6000", false, NULL, 0.0},
        {"Q 300, 12 MHz (40 per period)", q, q300_rate, "sample_rate_hz = 12e6;", rates, true, NULL,
         0.0},
        {"Q 300, 20 MHz", q, q300_rate, "sample_rate_hz = 20e6;", rates, true, NULL, 0.0},
        {"Q 300, 15 MHz", q, q300_rate, "sample_rate_hz = 15e6;", rates, true, NULL, 0.0},
        {"NCHV, squeeze film on", "config/nchv.conf", NULL, NULL,
         "--from 36e-9 --to 28e-9 --step 4e-9 --retract --periods 6000", false, nchv_rt, 0.0},
        {"NCHV, squeeze film off", "config/nchv.conf", nchv_squeeze,
         "squeeze = { model = \"none\"; };",
         "--from 36e-9 --to 28e-9 --step 4e-9 --retract --periods 6000", false, nchv_rt, 0.0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        /* make test runs the four Q 300 and 1-DOF curves (~110 s of CPU, CVODE nearly all of
         * it); the 15 and 20 MHz curves and NCHV's two (~160 s more; NCHV's orbit against
         * CVODE stays in make test's test_rt_accuracy) need AFMTWIN_VALIDATE=full (make
         * validate) or their name in AFMTWIN_STEADY_ONLY. */
        const bool validate_only = strstr(cases[i].name, "15 MHz") ||
                                   strstr(cases[i].name, "20 MHz") || strstr(cases[i].name, "NCHV");
        if (!full && validate_only && !(only && *only)) continue;
        if (only && *only && !strstr(cases[i].name, only)) continue;
        one_case(&cases[i]);
        fflush(stdout);
    }
    return check_done();
}
