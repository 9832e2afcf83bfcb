/* SPDX-License-Identifier: MIT */
/* test_config.c -- the config loader: every shipped config loads with the thesis values,
 * and every kind of bad file is refused with "FILE:LINE: key 'KEY': reason" and leaves the
 * caller's struct untouched. Runs from the repository root (tests/run.sh does that).
 *
 * Fixtures in tests/bad-configs/ mark the offending line with "# BAD"; the expected line
 * number is read from the fixture, so editing a fixture cannot silently shift it. */
#include "config/afm_config.h"
#include "check.h"

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

static const double deg = 3.14159265358979323846 / 180.0;

/* Line number of the "# BAD" marker, or 1 when the fixture has none (missing group). */
static int bad_line(const char *path) {
    FILE *f = fopen(path, "r");
    char buf[512];
    int line = 0, found = 1;
    if (!f) return -1;
    while (fgets(buf, sizeof buf, f)) {
        line++;
        if (strstr(buf, "# BAD") && !strstr(buf, "marked BAD")) {
            found = line;
            break;
        }
    }
    fclose(f);
    return found;
}

/* Load a bad fixture; check failure, the "FILE:LINE:" prefix, the key and the reason. */
static void expect_bad(const char *name, const char *key, const char *reason) {
    char path[256], what[1400], prefix[300], keytxt[160], err[AFM_ERR_LEN];
    snprintf(path, sizeof path, "tests/bad-configs/%s.conf", name);
    afm_config cfg, before;
    memset(&cfg, 0xA5, sizeof cfg); /* sentinel: must survive the failed load */
    before = cfg;
    int rc = afm_config_load(path, &cfg, err, sizeof err);
    snprintf(what, sizeof what, "%s: rejected", name);
    check_true(rc == -1, what);
    snprintf(what, sizeof what, "%s: cfg untouched", name);
    check_true(memcmp(&cfg, &before, sizeof cfg) == 0, what);
    snprintf(prefix, sizeof prefix, "%s:%d: ", path, bad_line(path));
    snprintf(what, sizeof what, "%s: message starts with '%s' (got: %s)", name, prefix, err);
    check_true(strncmp(err, prefix, strlen(prefix)) == 0, what);
    if (key) {
        snprintf(keytxt, sizeof keytxt, "key '%s': ", key);
        snprintf(what, sizeof what, "%s: message names %s", name, keytxt);
        check_true(strstr(err, keytxt) != NULL, what);
    }
    snprintf(what, sizeof what, "%s: reason says '%s'", name, reason);
    check_true(strstr(err, reason) != NULL, what);
}

static int load(const char *path, afm_config *cfg) {
    char err[AFM_ERR_LEN], what[AFM_ERR_LEN + 300];
    int rc = afm_config_load(path, cfg, err, sizeof err);
    snprintf(what, sizeof what, "%s loads%s%s", path, rc ? ": " : "", rc ? err : "");
    check_true(rc == 0, what);
    return rc;
}

/* Every .conf file in config/ loads and passes afm_config_validate. */
static void all_shipped_configs(void) {
    DIR *d = opendir("config");
    int n = 0;
    check_true(d != NULL, "config/ directory found (run from repository root)");
    if (!d) return;
    struct dirent *e;
    while ((e = readdir(d))) {
        size_t len = strlen(e->d_name);
        if (len < 6 || strcmp(e->d_name + len - 5, ".conf") != 0) continue;
        char path[300], err[AFM_ERR_LEN];
        afm_config cfg;
        snprintf(path, sizeof path, "config/%s", e->d_name);
        if (load(path, &cfg) == 0) {
            int rc = afm_config_validate(&cfg, err, sizeof err);
            check_true(rc == 0, "loaded config passes afm_config_validate");
        }
        n++;
    }
    closedir(d);
    /* default, nchv, 1dof, table-3-1, fig-4-2, -4-8, -4-13, -4-20 */
    check_true(n >= 8, "at least 8 shipped configs");
}

static void shipped_values(void) {
    afm_config c;
    /* NCHV, Table F.2: Er from eq. 2.22 with tip (112.5 GPa, 0.28), sapphire (345 GPa,
     * 0.29). Same arithmetic, so only rounding differs: 1e-12. */
    if (load("config/nchv.conf", &c) == 0) {
        double er = 1.0 / ((1 - 0.28 * 0.28) / 112.5e9 + (1 - 0.29 * 0.29) / 345e9);
        check_rel(c.forces.reduced_modulus_pa, er, 1e-12, "nchv Er by eq. 2.22");
        check_rel(c.forces.reduced_modulus_pa, 92.1932e9, 1e-6, "nchv Er = 92.1932 GPa");
        check_rel(c.model.beam.width_m[1], 33e-6 * (1 - 0.094), 1e-12, "nchv W1 = W0 (1 + sigma)");
        check_rel(c.model.beam.width_m[0], 33e-6, 1e-15, "nchv W0");
        check_rel(c.model.beam.height_m[1], 4e-6, 1e-15, "nchv H uniform");
        check_true(c.model.beam.n_kept == 3 && c.model.n_damping == 5, "nchv nk 3, 5 xi");
        check_rel(c.model.damping_ratio[1], 0.00172, 1e-15, "nchv xi2");
        check_true(c.forces.squeeze == AFM_SQUEEZE_LINEAR, "nchv squeeze linear");
        check_rel(c.forces.p1_n_s_m2, -1.695e-3, 1e-15, "nchv p1 (eq. 5.3)");
        check_rel(c.forces.inclination_rad, 12 * deg, 1e-15, "nchv alpha 12 deg in rad");
        check_rel(c.drive.tones[0].frequency_hz, 338.112e3, 1e-15, "nchv drive at the model's f1");
    }
    /* default.conf: the OBD and output groups as written there. */
    if (load("config/default.conf", &c) == 0) {
        check_true(c.obd.enabled && c.obd.adc_bits == 16 && c.output.n_outputs == 2 &&
                       c.output.decimation[0] == 16 && c.output.decimation[1] == 256,
                   "default.conf: obd 16-bit ADC, outputs 16 and 256");
        check_rel(c.obd.noise_density_m_rthz, 50e-15, 1e-15, "default.conf: OBD noise 50 fm/rtHz");
        check_rel(c.obd.full_scale_m, 200e-9, 1e-15, "default.conf: ADC full scale 200 nm");
        check_true(!c.thermal.enabled, "default.conf: thermal noise off");
    }
    /* Figure 4.13: Q1 200, Q3 350, Qi 5; Starr squeeze with default gas data. */
    if (load("config/thesis-fig-4-13.conf", &c) == 0) {
        const double xi[5] = {0.0025, 0.1, 0.00143, 0.1, 0.1};
        for (int i = 0; i < 5; i++)
            check_rel(c.model.damping_ratio[i], xi[i], 1e-15, "fig 4-13 xi_i");
        check_true(c.model.beam.n_kept == 3, "fig 4-13 nk = 3 (5-DOF)");
        check_true(c.forces.squeeze == AFM_SQUEEZE_STARR, "fig 4-13 Starr squeeze");
        check_rel(c.forces.gas_constant_j_kg_k, 286.9, 1e-15, "default gas constant");
        check_rel(c.forces.temperature_k, 293.15, 1e-15, "default temperature");
        check_rel(c.forces.pressure_pa, 101325, 1e-15, "default pressure");
        check_rel(c.model.beam.poisson_ratio, 0.28, 1e-15, "poisson 0.28");
        check_rel(c.sim.ref_rtol, 1e-10, 1e-15, "default ref_rtol");
        check_true(c.sim.integrator == AFM_INTEGRATOR_RT, "integrator rt");
        check_true(c.sim.step_events == AFM_STEP_EVENTS_AUTO, "default sim.step_events auto");
    }
    /* Table 3.1: no tip mass (section 3.2.1), no tip forces. */
    if (load("config/thesis-table-3-1.conf", &c) == 0) {
        check_abs(c.model.beam.tip_mass_kg, 0, 0, "table 3.1 without tip mass");
        check_true(!c.forces.vdw_contact && !c.forces.viscoelastic && !c.forces.capillary &&
                       !c.forces.electrostatic && c.forces.squeeze == AFM_SQUEEZE_NONE,
                   "table 3.1 has no tip forces");
        check_rel(c.model.beam.youngs_modulus_pa, 176e9, 1e-15, "table 3.1 Ec");
    }
    /* Table C.1: lumped, Q = 100 -> xi = 1/(2 Q) = 0.005; Ae = Fe/k = 2e-10 m. */
    if (load("config/thesis-1dof.conf", &c) == 0) {
        check_true(c.model.kind == AFM_MODEL_LUMPED, "1dof is lumped");
        check_rel(c.model.damping_ratio[0], 0.005, 1e-15, "1dof xi from Q = 100");
        check_rel(c.model.lumped.stiffness_n_m, 40, 1e-15, "1dof k");
        check_rel(c.drive.tones[0].amplitude_m, 8e-9 / 40, 1e-12, "1dof Ae = Fe/k");
        check_rel(c.forces.eta_pa_s, 2200, 1e-15, "1dof eta (Table C.1 footnote 1)");
        check_abs(c.forces.inclination_rad, 0, 0, "1dof alpha 0");
    }
    if (load("config/thesis-fig-4-2.conf", &c) == 0) {
        check_rel(c.model.beam.tip_mass_kg, 2.5e-13, 1e-15, "fig 4-2 tip mass");
        check_rel(c.forces.kappa, 0.95, 1e-15, "fig 4-2 kappa");
        check_rel(c.forces.eta0_pa_s, 1.81e-5, 1e-15, "fig 4-2 eta0");
        check_rel(c.drive.separation_m, 30e-9, 1e-15, "fig 4-2 Z");
        check_rel(c.forces.inclination_rad, 15 * deg, 1e-15, "fig 4-2 alpha");
    }
}

static void bad_configs(void) {
    expect_bad("syntax-error", NULL, "cannot parse");
    expect_bad("unknown-key", "model.beam.lenght_m", "unknown key");
    expect_bad("unknown-key-tone", "drive.tones[1].amplitude", "unknown key");
    expect_bad("unknown-top", "simulation", "unknown key");
    expect_bad("missing-key", "model.beam.length_m", "missing required key");
    expect_bad("missing-drive", "drive", "missing required group");
    expect_bad("wrong-type-string", "model.beam.elements", "expected an integer");
    expect_bad("wrong-type-float", "model.beam.elements", "expected an integer");
    expect_bad("wrong-type-bool", "forces.viscoelastic.enabled", "expected true or false");
    expect_bad("bad-kind", "model.kind", "not one of");
    expect_bad("bad-step-events", "sim.step_events",
               "\"yes\" is not one of \"auto\", \"on\", \"off\"");
    expect_bad("lumped-with-beam", "model.beam", "not used");
    expect_bad("negative-length", "model.beam.length_m", "must be in [1e-06, 0.01] m");
    expect_bad("negative-width", "model.beam.width_m[1]", "must be in [1e-08, 0.001] m");
    expect_bad("negative-width-scalar", "model.beam.width_m", "must be in [1e-08, 0.001] m");
    expect_bad("q-too-many", "model.quality_factor", "model has 4 modes");
    expect_bad("zero-modulus", "model.beam.youngs_modulus_pa", "must be in [1e+06, 1e+13] Pa");
    expect_bad("negative-tip-mass", "model.beam.tip_mass_kg", "must be in [0, 1e-06] kg");
    expect_bad("elements-range", "model.beam.elements", "must be in [1, 400]");
    expect_bad("xi-range", "model.damping_ratio[1]", "must be in (0, 1)");
    expect_bad("q-range", "model.quality_factor[0]", "> 0.5");
    expect_bad("both-damping", "model.quality_factor", "not both");
    expect_bad("too-many-xi", "model.damping_ratio", "model has 4 modes");
    expect_bad("nk-negative", "model.beam.kept_modes", "must be >= 0");
    expect_bad("nk-too-large", "model.beam.kept_modes", "at most 2 kept modes");
    expect_bad("nk-max-modes", "model.beam.kept_modes", "must be <= 24");
    expect_bad("infinite", "model.beam.density_kg_m3", "not a finite number");
    expect_bad("inclination", "forces.inclination_deg", "[0, 90)");
    expect_bad("kappa-range", "forces.squeeze.kappa", "[0, 1]");
    expect_bad("plate-on-beam", "forces.squeeze.plate_length_m", "only for kind");
    expect_bad("negative-hamaker", "forces.vdw_contact.hamaker_j", "must be >= 0");
    expect_bad("er-and-parts", "forces.vdw_contact.reduced_modulus_pa", "not both");
    expect_bad("bad-sample-poisson", "forces.vdw_contact.sample_poisson", "(-1, 0.5)");
    expect_bad("visco-without-contact", "forces.viscoelastic.enabled", "needs vdw_contact");
    expect_bad("negative-separation", "drive.separation_m", "must be in [0, 0.001] m");
    expect_bad("tone-frequency", "drive.tones[0].frequency_hz", "sample_rate_hz/2");
    /* physical plausibility (afm_limits.h, issue 13): the exact inputs that ran the twin
     * into a livelock, and lengths and moduli far outside any cantilever */
    expect_bad("sample-rate-tiny", "sim.sample_rate_hz", "must be in [1000, 1e+09] Hz");
    expect_bad("tone-frequency-tiny", "drive.tones[0].frequency_hz", "must be in [1, ");
    expect_bad("tone-sum", "drive.tones", "amplitudes add up to 4e-06 m");
    expect_bad("length-huge", "model.beam.length_m", "must be in [1e-06, 0.01] m");
    expect_bad("modulus-tiny", "forces.vdw_contact.reduced_modulus_pa", "must be in [100, 1e+13]");
    expect_bad("lumped-stiffness", "model.lumped.stiffness_n_m", "must be in [0.0001, 1e+06]");
    expect_bad("tone-amplitude", "drive.tones[0].amplitude_m", "[0, 1e-06]");
    expect_bad("no-tones", "drive.tones", "needs 1 to 4 tones");
    expect_bad("too-many-tones", "drive.tones", "needs 1 to 4 tones");
    expect_bad("harmonic-range", "sim.harmonics[2]", "[1, 64]");
    expect_bad("bad-integrator", "sim.integrator", "not one of");
    /* obd, thermal, lockin, output (issue 4) */
    expect_bad("obd-unknown-key", "obd.noise_density", "unknown key");
    expect_bad("obd-adc-bits", "obd.adc_bits", "[2, 32]");
    expect_bad("obd-negative-noise", "obd.noise_density_m_rthz", "must be >= 0");
    expect_bad("obd-seed-negative", "obd.seed", "must be >= 0");
    expect_bad("obd-full-scale-type", "obd.full_scale_m", "expected a number");
    expect_bad("thermal-temperature", "thermal.temperature_k", "must be > 0");
    expect_bad("lockin-order", "lockin.order", "[1, 8]");
    expect_bad("rt-substeps", "sim.rt_substeps_contact", "[0, 64]");
    expect_bad("lockin-tau-short", "lockin.time_constant_s", "one sample interval");
    expect_bad("output-decimation-zero", "output.decimation[1]", "[1, 65536]");
    expect_bad("output-decimation-float", "output.decimation[0]", "expected an integer");
    expect_bad("output-decimation-repeat", "output.decimation[2]", "repeats decimation[0]");
    expect_bad("output-too-many", "output.decimation", "needs 1 to 4 values");
    expect_bad("output-passband", "output.passband_fraction", "(0, 0.95]");
    expect_bad("output-not-group", "output", "expected a group");
}

/* issue 13: a directory given as config read as "I/O error"; text in memory parses as the
 * file does (afm_config_parse, the config fuzzer's entry). */
static void load_edges(void) {
    afm_config c, f;
    char err[AFM_ERR_LEN];
    check_true(afm_config_load("config", &c, err, sizeof err) == -1 &&
                   strstr(err, "config: is a directory, not a config file"),
               "a directory as config: says so");
    FILE *fp = fopen("config/default.conf", "r");
    static char text[65536];
    size_t n = fp ? fread(text, 1, sizeof text - 1, fp) : 0;
    if (fp) fclose(fp);
    text[n] = 0;
    check_true(afm_config_load("config/default.conf", &f, err, sizeof err) == 0 &&
                   afm_config_parse(text, "config/default.conf", &c, err, sizeof err) == 0 &&
                   !memcmp(&c.model, &f.model, sizeof c.model) &&
                   !memcmp(&c.drive, &f.drive, sizeof c.drive),
               "afm_config_parse(text of default.conf) = afm_config_load(default.conf)");
    check_true(afm_config_parse("model = {", "x", &c, err, sizeof err) == -1 &&
                   strstr(err, "x:1: cannot parse"),
               "afm_config_parse of broken text: line and reason");
}

/* issue 18: the am group (the reference Z controller): defaults without it, its keys, its
 * ranges, and control = "internal" not beside fm.control = "internal". */
static void am_group(void) {
    static const char base[] = "model = { kind = \"lumped\"; lumped = { stiffness_n_m = 40.0; "
                               "resonance_hz = 300e3; }; quality_factor = [100.0]; };\n"
                               "drive = { separation_m = 8e-9; tones = ( { amplitude_m = 1e-10; "
                               "frequency_hz = 300e3; } ); };\n";
    static char text[2048];
    afm_config c;
    char err[AFM_ERR_LEN];
    check_true(afm_config_parse(base, "am", &c, err, sizeof err) == 0 && !c.am.enabled &&
                   c.am.control == AFM_AM_CONTROL_NONE && c.am.setpoint_ratio == 0.8 &&
                   c.am.ki_hz == 2000.0 && c.am.kp == 0.0 && c.am.z_rate_max_m_s == 1e-3 &&
                   c.am.z_min_m == 0.0 && c.am.z_max_m == 1e-5,
               "am: defaults without the group (afmtwin scan's former ones)");
    snprintf(text, sizeof text,
             "%sam = { control = \"internal\"; setpoint_ratio = 0.7; kp = 0.1; ki_hz = 500.0; "
             "z_rate_max_m_s = 2e-3; z_min_m = 1e-9; z_max_m = 2e-6; };\n",
             base);
    check_true(afm_config_parse(text, "am", &c, err, sizeof err) == 0 && c.am.enabled &&
                   c.am.control == AFM_AM_CONTROL_INTERNAL && c.am.setpoint_ratio == 0.7 &&
                   c.am.kp == 0.1 && c.am.ki_hz == 500.0 && c.am.z_rate_max_m_s == 2e-3 &&
                   c.am.z_min_m == 1e-9 && c.am.z_max_m == 2e-6,
               "am: every key read");
    static const struct {
        const char *body, *key;
    } bad[] = {{"setpoint_ratio = 1.0;", "am.setpoint_ratio"},
               {"ki_hz = 0.0;", "am.ki_hz"},
               {"kp = -1.0;", "am.kp"},
               {"z_rate_max_m_s = 11.0;", "am.z_rate_max_m_s"},
               {"z_min_m = 1e-6; z_max_m = 1e-6;", "am.z_max_m"},
               {"control = \"outside\";", "am.control"},
               {"enabled = false; control = \"internal\";", "am.control"},
               {"kd = 1.0;", "kd"}};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(text, sizeof text, "%sam = { %s };\n", base, bad[i].body);
        int rc = afm_config_parse(text, "am", &c, err, sizeof err);
        char what[160];
        snprintf(what, sizeof what, "am: bad '%s' refused naming %s", bad[i].body, bad[i].key);
        check_true(rc == -1 && strstr(err, bad[i].key) != NULL, what);
    }
    snprintf(text, sizeof text,
             "%sam = { control = \"internal\"; };\nfm = { control = \"internal\"; };\n", base);
    check_true(afm_config_parse(text, "am", &c, err, sizeof err) == -1 &&
                   strstr(err, "choose one") != NULL,
               "am: internal beside fm.control internal refused");
}

/* afm_config_validate on structs edited after loading (what CLI overrides do). */
static void validate_struct(void) {
    afm_config c;
    char err[AFM_ERR_LEN];
    if (load("config/thesis-fig-4-2.conf", &c)) return;
    afm_config v = c;
    v.model.beam.youngs_modulus_pa = NAN;
    check_true(afm_config_validate(&v, err, sizeof err) == -1, "validate: NaN modulus rejected");
    check_true(strstr(err, "config/thesis-fig-4-2.conf: key 'model.beam.youngs_modulus_pa'") !=
                   NULL,
               "validate: message names file and key");
    /* Non-finite values are refused even in a disabled feature. */
    v = c;
    v.forces.surface_energy_j_m2 = INFINITY;
    check_true(afm_config_validate(&v, err, sizeof err) == -1 &&
                   strstr(err, "key 'forces.capillary.surface_energy_j_m2'") != NULL,
               "validate: inf in disabled capillary group rejected");
    /* Lowering the sample rate below twice the tone frequency must fail. */
    v = c;
    v.sim.sample_rate_hz = 100e3;
    check_true(afm_config_validate(&v, err, sizeof err) == -1 &&
                   strstr(err, "key 'drive.tones[0].frequency_hz'") != NULL,
               "validate: tone above new Nyquist rejected");
    v = c;
    v.model.beam.n_elements = 1;
    check_true(afm_config_validate(&v, err, sizeof err) == -1 &&
                   strstr(err, "key 'model.beam.kept_modes'") != NULL,
               "validate: nk 2 with 1 element rejected");
    v = c;
    v.drive.n_tones = AFM_MAX_TONES + 1;
    check_true(afm_config_validate(&v, err, sizeof err) == -1, "validate: tone count > max");
    v = c;
    v.path[0] = '\0';
    v.forces.kappa = -0.1;
    check_true(afm_config_validate(&v, err, sizeof err) == -1 &&
                   strncmp(err, "key 'forces.squeeze.kappa'", 26) == 0,
               "validate: no path -> message starts with the key");
    check_true(afm_config_validate(&c, err, sizeof err) == 0, "validate: untouched copy valid");

    /* Documented defaults (config/README.md). */
    afm_config d;
    afm_config_defaults(&d);
    check_rel(d.sim.sample_rate_hz, 14.06e6, 1e-15, "default sample rate");
    check_rel(d.model.beam.poisson_ratio, 0.28, 1e-15, "default poisson");
    check_true(d.model.beam.n_elements == 20 && d.sim.n_harmonics == 0 &&
                   d.forces.squeeze == AFM_SQUEEZE_NONE && !d.forces.vdw_contact &&
                   d.sim.rt_substeps_contact == 0,
               "default counts and switches");
    check_true(d.obd.enabled && d.obd.noise_density_m_rthz == 0 && d.obd.adc_bits == 0 &&
                   d.obd.full_scale_m == 1e-6 && !d.thermal.enabled &&
                   d.thermal.temperature_k == 295.0 && d.lockin.time_constant_s == 1e-4 &&
                   d.lockin.order == 4 && d.output.n_outputs == 1 && d.output.decimation[0] == 16 &&
                   d.output.passband_fraction == 0.8,
               "defaults of obd, thermal, lockin, output");
    v = c;
    v.output.passband_fraction = NAN;
    check_true(afm_config_validate(&v, err, sizeof err) == -1 &&
                   strstr(err, "key 'output.passband_fraction'") != NULL,
               "validate: NaN passband rejected");
    v = c;
    v.obd.full_scale_m = 0;
    check_true(afm_config_validate(&v, err, sizeof err) == -1 &&
                   strstr(err, "key 'obd.full_scale_m'") != NULL,
               "validate: zero ADC full scale rejected");
}

int main(void) {
    all_shipped_configs();
    shipped_values();
    bad_configs();
    validate_struct();
    load_edges();
    am_group();

    char err[AFM_ERR_LEN];
    afm_config c;
    check_true(afm_config_load("tests/bad-configs/no-such-file.conf", &c, err, sizeof err) == -1 &&
                   strstr(err, "no-such-file.conf: cannot read file") != NULL,
               "missing file rejected with its name");
    return check_done();
}
