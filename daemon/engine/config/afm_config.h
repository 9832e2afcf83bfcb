/* SPDX-License-Identifier: MIT */
/* afm_config.h -- the twin's whole configuration as plain data, and its loader.
 *
 * Layer config/ (0): nothing in the engine below this. Every later layer reads these structs and
 * never a config file. All quantities are SI; names carry the unit.
 *
 * Loader contract (afm_config_load):
 *  - libconfig file; unknown keys, missing required keys, wrong types and impossible values
 *    are rejected with "FILE:LINE: key 'path.to.key': reason" in err; cfg is then untouched.
 *  - Optional keys take the defaults that afm_config_defaults() sets.
 *  - The library never prints: the caller prints err. */
#ifndef AFM_CONFIG_H
#define AFM_CONFIG_H

#include <stdbool.h>
#include <stddef.h>

#define AFM_MAX_MODES 24       /* most modes a reduced model may keep (nk + 2) */
#define AFM_MAX_ELEMENTS 400   /* most FEM beam elements */
#define AFM_MAX_TONES 4        /* most dither tones */
#define AFM_MAX_RT_SUBSTEPS 64 /* most contact substeps per sample (sim.rt_substeps_contact) */
#define AFM_MAX_HARMONICS 16   /* most harmonics an estimator tracks */
#define AFM_ERR_LEN 512        /* size of every error-message buffer */

typedef enum { AFM_MODEL_BEAM = 0, AFM_MODEL_LUMPED = 1 } afm_model_kind;
typedef enum {
    AFM_SQUEEZE_NONE = 0,
    AFM_SQUEEZE_STARR = 1,
    AFM_SQUEEZE_LINEAR = 2
} afm_squeeze_kind;
typedef enum {
    AFM_INTEGRATOR_RT = 0,
    AFM_INTEGRATOR_REFERENCE = 1,
    AFM_INTEGRATOR_ARKODE_ERK = 2
} afm_integrator_kind;
/* The rt integrator's scheme (docs/numerics.md): accurate (the tip force cubic Hermite in
 * time, fourth order out of contact: CVODE's steady state) or fast (the force linear in
 * time, second order, cheaper). auto: accurate in the engine and every offline tool; the
 * daemon measures both before real time starts and runs accurate where it fits the budget. */
typedef enum {
    AFM_RT_SCHEME_AUTO = 0,
    AFM_RT_SCHEME_ACCURATE = 1,
    AFM_RT_SCHEME_FAST = 2
} afm_rt_scheme_kind;

/* The integrator's per-step record (integrators/afm_rt_events.h: crossings, min of x, work)
 * for the per-period metrics (sim.step_events, issue 28). on: the runner hands it to the
 * chain wherever the scheme in force records (rt accurate without thermal noise, CVODE);
 * off: the metrics from the samples alone; auto: on, but the daemon's real-time `--scheme
 * auto` drops it (rather than the accurate scheme) when only the scheme without it fits the
 * budget (daemon/scheme.c). AFMTWIN_STEP_EVENTS=0 in the environment turns it off too. */
typedef enum {
    AFM_STEP_EVENTS_AUTO = 0,
    AFM_STEP_EVENTS_ON = 1,
    AFM_STEP_EVENTS_OFF = 2
} afm_step_events_kind;

/* Euler-Bernoulli beam (thesis ch. 3.2, Table E.1). Width and height vary linearly from
 * the clamp (index 0) to the free end (index 1); equal values give a uniform beam. */
typedef struct {
    double youngs_modulus_pa; /* Ec */
    double density_kg_m3;     /* rho_c */
    double poisson_ratio;     /* nu, only for the eq. E.1 stiffness estimate; default 0.28 */
    double length_m;          /* L */
    double width_m[2];        /* W0 (clamp), W1 (free end) */
    double height_m[2];       /* H0, H1 */
    double tip_mass_kg;       /* mt, point mass on the last transversal DOF; may be 0 */
    int n_elements;           /* FEM elements, 1..AFM_MAX_ELEMENTS */
    int n_kept;               /* nk, free-interface elastic modes kept in Rubin CMS, >= 0 */
} afm_cfg_beam;

/* Lumped 1-DOF model (eq. 3.1, Table C.1): me x'' + c x' + k x = k x_dit(t) + F_tip.
 * The thesis drives it with a force Fe sin(we t); that is the same as a base amplitude
 * Ae = Fe / k here. me follows from k and the resonance: me = k / (2 pi f0)^2. */
typedef struct {
    double stiffness_n_m; /* k */
    double resonance_hz;  /* f0 = sqrt(k/me) / 2pi */
} afm_cfg_lumped;

typedef struct {
    afm_model_kind kind;
    afm_cfg_beam beam;
    afm_cfg_lumped lumped;
    /* Modal damping ratio xi_i of reduced mode i (ascending frequency). Modes past the
     * list take its last value. Config gives damping_ratio = [...] or quality_factor =
     * [...] (Q = 1/(2 xi)); each xi in (0, 1). */
    int n_damping;
    double damping_ratio[AFM_MAX_MODES];
} afm_cfg_model;

/* Tip-sample forces (eq. 3.2, 3.3, 3.6, 5.3, 2.18-2.20). d = x cos(alpha) + Z. */
typedef struct {
    double inclination_rad;    /* alpha; config key inclination_deg */
    double radius_m;           /* R */
    bool vdw_contact;          /* vdW + Hertz/DMT contact (eq. 3.2) */
    double hamaker_j;          /* Ha */
    double a0_m;               /* intermolecular distance a0 */
    double reduced_modulus_pa; /* Er; given directly or from tip/sample moduli (eq. 2.22) */
    bool viscoelastic;         /* eq. 3.3 term */
    double eta_pa_s;           /* eta_n, normal viscosity of the contact */
    afm_squeeze_kind squeeze;
    double eta0_pa_s;           /* Starr: medium viscosity at STP (air 1.81e-5) */
    double gas_constant_j_kg_k; /* Starr: R_a for Kn (air 286.9) */
    double temperature_k;       /* Starr: T for Kn (default 293.15) */
    double pressure_pa;         /* Starr: p_a for Kn (default 101325) */
    double kappa;               /* Starr: fraction of tip length in h (eq. 3.6), 0..1 */
    double tip_length_m;        /* l */
    double plate_length_m;      /* Starr: L of the squeezing plate (beam length; set from model) */
    double plate_width_m;       /* Starr: W (mean beam width; set from model) */
    double p1_n_s_m2, p2_n_s_m; /* linear fit csq = p1 (Z + x) + p2 (eq. 5.3) */
    bool capillary;             /* eq. 2.18 */
    double surface_energy_j_m2; /* gamma_L */
    double contact_angle_rad;   /* theta; config key contact_angle_deg */
    double meniscus_d_m;        /* d of Fig. 2.3 */
    bool electrostatic;         /* eq. 2.19-2.20 */
    double voltage_v;           /* Delta V */
    double cone_half_angle_rad; /* theta of eq. 2.20; config key cone_half_angle_deg */
    double cone_length_m;       /* l of eq. 2.19 */
} afm_cfg_forces;

typedef struct {
    double amplitude_m;  /* A_j >= 0 */
    double frequency_hz; /* f_j > 0, below half the sample rate */
    double phase_rad;    /* phi_j; config key phase_deg */
} afm_cfg_tone;

/* Base excitation x_dit(t) = sum_j A_j sin(2 pi f_j t + phi_j) and the set-point Z. */
typedef struct {
    double separation_m; /* Z >= 0: tip-sample distance at rest */
    int n_tones;         /* 1..AFM_MAX_TONES */
    afm_cfg_tone tones[AFM_MAX_TONES];
} afm_cfg_drive;

typedef struct {
    double sample_rate_hz; /* OBD sample rate; integrator output step = 1/rate. 14.06e6 */
    afm_integrator_kind integrator;
    int rt_substeps_contact; /* substeps per sample while in contact (rt); default set by engine */
    afm_rt_scheme_kind rt_scheme;     /* sim.rt_scheme: auto (default), accurate, fast */
    afm_step_events_kind step_events; /* sim.step_events: auto (default), on, off */
    double ref_rtol;                  /* CVODE relative tolerance; default 1e-10 */
    int n_harmonics;                  /* 0: the estimators choose 1, 2, 3 and the harmonics
                                         nearest f2/fe and f3/fe */
    int harmonics[AFM_MAX_HARMONICS]; /* harmonic numbers k >= 1 to estimate */
} afm_cfg_sim;

/* Optical beam deflection sensor (issue 4): it measures the tip slope, calibrated so that
 * mode 1 reads as deflection (m), plus a white noise floor and ADC quantisation. */
typedef struct {
    bool enabled;                /* false: outputs carry the tip displacement itself */
    double noise_density_m_rthz; /* white floor, one-sided, in calibrated m/sqrt(Hz); 0 = none */
    int adc_bits;                /* NOB; 0 = no quantisation; else 2..32 */
    double full_scale_m;         /* ADC input range +-full_scale (calibrated m) */
    unsigned long seed;          /* noise generator seed (runs are reproducible) */
} afm_cfg_obd;

/* Thermal (Langevin) force per mode at temperature T (fluctuation-dissipation). */
typedef struct {
    bool enabled;
    double temperature_k; /* T > 0 */
    unsigned long seed;
} afm_cfg_thermal;

/* Lock-in amplifier at tone 0's frequency (the controller's view). */
typedef struct {
    double time_constant_s; /* tau of each first-order low-pass stage, > 0 */
    int order;              /* 1..8 cascaded stages (6 dB/octave each) */
} afm_cfg_lockin;

#define AFM_MAX_OUTPUTS 4
/* Decimated output streams: integer factors from the OBD sample rate. */
typedef struct {
    int n_outputs;                   /* 1..AFM_MAX_OUTPUTS */
    int decimation[AFM_MAX_OUTPUTS]; /* R >= 1 (1 = no decimation) */
    double passband_fraction;        /* kept band, as a fraction of the output Nyquist
                                        rate (0 < p < 1, default 0.8); aliases into it
                                        are rejected by >= 80 dB */
} afm_cfg_output;

/* CAN input from a piezo driver (issue 6; map and frames in docs/can.md). Off unless the
 * config has a `can` group. Signals, in the order of ids[]: */
typedef enum {
    AFM_CAN_DITHER_FREQUENCY = 0, /* [tone u8][3 reserved][frequency: 4 bytes] */
    AFM_CAN_DITHER_AMPLITUDE = 1, /* [tone u8][3 reserved][amplitude: 4 bytes] */
    AFM_CAN_DITHER_PHASE = 2,     /* [tone u8][3 reserved][start phase: 4 bytes] */
    AFM_CAN_SETPOINT = 3,         /* [separation: 4 bytes][ramp rate: 4 bytes] */
    AFM_CAN_ENABLE = 4,           /* [u8: 1 enable (run), 0 disable (pause)] */
    AFM_CAN_HEARTBEAT = 5,        /* [u8: driver state, any value] */
    AFM_CAN_N_SIGNALS = 6
} afm_can_signal;

typedef enum { AFM_CAN_SCALED = 0, AFM_CAN_FLOAT32 = 1 } afm_can_encoding;

typedef struct {
    bool enabled;
    char interface[16];             /* IFNAMSIZ, e.g. "can0", "vcan0" */
    bool fd;                        /* accept CAN FD frames too (CAN_RAW_FD_FRAMES) */
    bool extended_ids;              /* 29-bit identifiers (else 11-bit) */
    bool big_endian;                /* byte order of 4-byte values: false Intel, true Motorola */
    afm_can_encoding encoding;      /* scaled integers (u32, phase i32) or IEEE float32 (SI) */
    unsigned id[AFM_CAN_N_SIGNALS]; /* frame id per afm_can_signal, all different */
    /* Scaled encoding: physical value = raw * scale (SI per bit). */
    double scale_frequency_hz, scale_amplitude_m, scale_phase_rad, scale_separation_m,
        scale_ramp_m_s;
    double heartbeat_timeout_s;              /* > 0; 0: heartbeat not monitored */
    double reconnect_min_s, reconnect_max_s; /* retry backoff, doubling from min to max */
} afm_cfg_can;

/* The sample under the tip (issue 18): a height map z_s(x, y) (m, up = towards the tip)
 * summed from analytic features and an optional height image, and material regions. Off
 * (a flat, uniform sample at height 0) unless the config has a `sample` group. */
#define AFM_MAX_FEATURES 16
#define AFM_MAX_MATERIALS 8
typedef enum {
    AFM_FEATURE_TILT = 0,    /* z = slope_x x + slope_y y */
    AFM_FEATURE_STEP = 1,    /* height_m on the side u > position_m (u along angle_deg) */
    AFM_FEATURE_GRATING = 2, /* lines of height_m, period pitch_m, duty (top fraction) */
    AFM_FEATURE_SPHERE = 3   /* a particle of radius_m at (x_m, y_m) on the plane */
} afm_feature_kind;

typedef struct {
    afm_feature_kind kind;
    double height_m;         /* step, grating: height of the upper level over the lower */
    double position_m;       /* step: edge position along u; grating: u of a rising edge */
    double angle_deg;        /* step, grating: u = x cos(angle) + y sin(angle) */
    double pitch_m;          /* grating period */
    double duty;             /* grating: fraction of a period on top, 0 < duty < 1 */
    double edge_m;           /* step, grating: width of an edge (smooth, C1), > 0 */
    double x_m, y_m;         /* sphere centre */
    double radius_m;         /* sphere */
    double slope_x, slope_y; /* tilt (dimensionless) */
    int material;            /* region on the feature's upper part: 0 = the forces group's sample,
                                i = materials[i - 1] */
} afm_cfg_feature;

/* A material: what differs from the forces group's sample (NAN = the same). */
typedef struct {
    double reduced_modulus_pa; /* Er */
    double hamaker_j;          /* Ha */
    double a0_m;               /* intermolecular distance (sets the DMT adhesion Ha R/6a0^2) */
    double eta_pa_s;           /* contact viscosity (viscoelastic term; > 0 turns it on) */
} afm_cfg_material;

typedef struct {
    bool enabled;
    int n_features;
    afm_cfg_feature features[AFM_MAX_FEATURES];
    int n_materials;
    afm_cfg_material materials[AFM_MAX_MATERIALS];
    char image_file[256]; /* height image, PGM (P2 or P5) or a whitespace table; "" none */
    double image_pixel_m; /* pixel pitch of the image, > 0 */
    double image_height_per_level_m; /* height of one grey level (PGM) or of 1.0 (table) */
    double image_x0_m, image_y0_m;   /* position of the image's first pixel (top left) */
} afm_cfg_sample;

/* Frequency-modulation control (issue 32; runner/afm_fm.h): a PLL on the lock-in's phase
 * that moves tone 0's frequency, and a PI on the lock-in amplitude that moves tone 0's
 * drive amplitude. Off (fm.enabled false) unless the config has an `fm` group; the offline
 * tools (`afmtwin approach --mode fm`) use these values, or the defaults, either way.
 * 0 for a gain or a time means "derived" (see config/README.md). */
/* fm.control: AFM_FM_CONTROL_NONE, the daemon's tone 0 is what commands set (an outside FM
 * controller streams dither commands); AFM_FM_CONTROL_INTERNAL, the daemon's runner runs the
 * PLL and amplitude loops on tone 0 (runner/afm_runner.h) and refuses dither commands. */
typedef enum { AFM_FM_CONTROL_NONE = 0, AFM_FM_CONTROL_INTERNAL = 1 } afm_fm_control;

/* fm.drive: what drives tone 0 (runner/afm_fm.h). AFM_FM_DRIVE_PLL, the PLL's NCO at the
 * lock-in phase set-point; AFM_FM_DRIVE_SELF, self-excitation: the deflection phase-shifted
 * by phase_setpoint_deg (90: on resonance) and amplitude-limited by the amplitude controller,
 * the oscillation finding its own frequency. */
typedef enum { AFM_FM_DRIVE_PLL = 0, AFM_FM_DRIVE_SELF = 1 } afm_fm_drive;

typedef struct {
    bool enabled;
    double phase_setpoint_deg;     /* lock-in lag the PLL holds, (0, 180); 90: resonance */
    double pll_bandwidth_hz;       /* closed-loop bandwidth the derived PLL gains give, > 0 */
    double pll_kp_hz_per_deg;      /* proportional gain (Hz per deg of error), >= 0; 0: derived */
    double pll_ki_hz_per_deg_s;    /* integral gain (Hz/s per deg), >= 0; 0: derived */
    double max_shift_hz;           /* |f - f_center| limit of the NCO, > 0 */
    double lock_threshold_deg;     /* |phase error| inside which the PLL counts as locked */
    double lock_time_s;            /* inside (outside) that long: locked (lost); 0: derived */
    double amplitude_setpoint_m;   /* tip amplitude held, >= 0; 0: what tone 0's drive gives at
                                      the free resonance (taken when the PLL first locks) */
    double amplitude_bandwidth_hz; /* closed-loop bandwidth of the derived amplitude gains */
    double amplitude_kp;           /* drive m per m of amplitude error, >= 0; 0: derived */
    double amplitude_ki_hz;        /* drive m/s per m of error, >= 0; 0: derived */
    double drive_max_m;            /* the drive amplitude's limit, (0, 1e-6] */
    int update_samples;            /* controller update period (samples), 1..4096 */
    afm_fm_control control;        /* the daemon: who moves tone 0 (default none) */
    afm_fm_drive drive;            /* pll (default) or self-excited */
} afm_cfg_fm;

/* Amplitude-modulation Z control (issue 18; runner/afm_pi.h): the reference PI on the lock-in
 * amplitude at tone 0 that moves Z so that A = setpoint_ratio x A0 (A0: runner/afm_a0.h).
 * `afmtwin scan` takes these values (or the defaults) as its controller's unless its options
 * say otherwise, with or without an `am` group; am.control = "internal" runs it in the daemon
 * (runner/afm_runner.h), which then refuses commands that set Z. */
typedef enum { AFM_AM_CONTROL_NONE = 0, AFM_AM_CONTROL_INTERNAL = 1 } afm_am_control;

typedef struct {
    bool enabled;
    double setpoint_ratio;   /* A_set / A0, in (0, 1) */
    double kp;               /* m of Z per m of amplitude error, [0, 1e3] */
    double ki_hz;            /* 1/s, (0, 1e8] */
    double z_rate_max_m_s;   /* the Z piezo's slew limit, (0, 10] m/s */
    double z_min_m, z_max_m; /* the range of Z (m), z_min < z_max */
    afm_am_control control;  /* the daemon: who moves Z (default none: commands) */
} afm_cfg_am;

typedef struct {
    char path[256]; /* file it came from */
    afm_cfg_model model;
    afm_cfg_forces forces;
    afm_cfg_drive drive;
    afm_cfg_sim sim;
    afm_cfg_obd obd;
    afm_cfg_thermal thermal;
    afm_cfg_lockin lockin;
    afm_cfg_output output;
    afm_cfg_can can;       /* CAN input (issue 6); can.enabled false without a can group */
    afm_cfg_sample sample; /* the sample under the tip (issue 18); off without a sample group */
    afm_cfg_fm fm;         /* FM control (issue 32); fm.enabled false without an fm group */
    afm_cfg_am am;         /* AM Z control (issue 18); am.enabled false without an am group */
} afm_config;

/* Fill every field with its default (documented in config/README.md). */
void afm_config_defaults(afm_config *cfg);

/* Load and validate FILE. Returns 0 on success, -1 with err (AFM_ERR_LEN) filled. */
int afm_config_load(const char *path, afm_config *cfg, char *err, size_t errlen);
/* The same from libconfig text in memory (name: what messages call it; libconfig 1.5
 * resolves an @include from the current directory). For tests and the config fuzzer. Not
 * thread-safe (a static work area). A file path that is a directory, or larger than 1 MiB,
 * is refused by afm_config_load before libconfig reads it. */
int afm_config_parse(const char *text, const char *name, afm_config *cfg, char *err, size_t errlen);

/* Re-check a filled struct (after CLI overrides). 0 if valid, -1 with err. */
int afm_config_validate(const afm_config *cfg, char *err, size_t errlen);

#endif
