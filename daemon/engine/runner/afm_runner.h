/* SPDX-License-Identifier: MIT */
/* afm_runner.h -- the twin as the daemon and the replay tool run it: simulator + output
 * chain (OBD, decimators, estimators), commands applied at block boundaries, n samples at
 * a time. No LCM, no threads, no clock: the caller decides when to run and what to apply.
 *
 * Layer runner/ (5) (top of the engine; uses afm_twin, afm_sim, afm_chain and the command
 * struct of runner/afm_cmd.h, which is plain data).
 *
 * Life cycle: afm_runner_create (allocates everything) -> { afm_runner_apply, afm_runner_run,
 * afm_runner_take_* , afm_runner_status } ... -> afm_runner_destroy. Nothing after create
 * allocates, locks or blocks, except afm_runner_model_build / _destroy, which exist to be
 * called on another thread (or, in replay, inline).
 *
 * Two stages: the integrator (front: apply, run, budget, status_get) writes its samples,
 * blocks of AFM_RUNNER_SLOT_SAMPLES, and every change the output chain must follow into a
 * lock-free ring; the output chain (back: chain_run, take_*, chain_status_get,
 * take_trash) consumes them in order. afm_runner_create runs the back inline, inside run
 * and apply, on the caller's thread. afm_runner_create_pipelined(..., true, ...) leaves it
 * to a second thread: the front's functions on one thread, the back's on one other
 * (afm_runner_take_trash on any one thread). The chain gets the same calls with the same
 * data in both cases, so the outputs are bit-identical. Pipelined, run advances fewer
 * samples than asked when the ring is full (the chain stage is behind: status.stalls),
 * and never waits.
 *
 * Determinism: the output depends only on the config and on which commands were applied
 * after how many samples since create. The setpoint ramp moves Z every
 * AFM_RUNNER_RAMP_SAMPLES samples counted from create, so how the caller slices
 * afm_runner_run does not matter either: same commands at the same sample counts ->
 * bit-identical outputs (replay depends on it).
 *
 * Commands (validated with afm_cmd_validate first, with the running model in the limits;
 * afm_runner_apply re-checks what depends on the running state and changes nothing on
 * rejection):
 *  - dither: tone j < n_tones set phase-continuously (afm_sim_set_tone); a tone this
 *    command starts begins at phase_rad; running tones past n_tones stop (they are removed
 *    from the drive; naming them again starts them at that command's phase_rad).
 *  - setpoint: ramp rate 0 -> Z now; else Z moves linearly towards the target.
 *  - param: SEPARATION and FORCE names apply now (afm_param_apply on the runner's config,
 *    then the force constants are swapped into the simulator, no allocation); DAMPING and
 *    GEOMETRY names need a model built by afm_runner_model_build from the config the
 *    command leads to (passed to afm_runner_apply in *model).
 *  - control: RUN, PAUSE, RESET (state to rest, chain cleared, drive and Z kept),
 *    STEP n (pauses; the next n samples run although paused).
 *  - tick: adds n samples to the lockstep budget (see afm_runner_run).
 *  - reload: swaps in *model (built from a whole new config): new simulator and chain,
 *    model time continues, state at rest, drive and Z from the new config (and its FM
 *    control, restarted; its sample, the tip holding where it was).
 *  - scan (issue 18): moves the tip laterally (hold, move to, velocity, raster); refused
 *    without a sample group (below).
 *
 * The sample under the tip (the config's `sample` group; forces/afm_surface.h): without one
 * nothing below runs and the twin is what it was before (bit for bit). With one, the
 * simulator's separation is the gap Z - z_s(x, y) (held at 0 where the surface rises past
 * the stage Z) and its forces those of the material under the tip (every material's terms
 * on, afm_surface_material_forces; a force param change moves every material with the base
 * sample); Z (setpoint, ramp, status, outputs) stays the stage's. The tip starts at (0, 0);
 * while it moves its position is recomputed every AFM_RUNNER_SCAN_SAMPLES samples counted
 * from create, at the middle of the samples that follow (afm_scan's convention: a raster is
 * afm_scan_position of the time since the command), so the gap moves on that grid within a
 * block and never steps at a block boundary. A material change commits the open ring item
 * and is an IT_FORCES change for the chain. No allocation: the surface's queries are
 * bounded (afm_surface.h).
 *
 * Internal FM control (the config's fm.control = "internal", issue 32; runner/afm_fm.h): the
 * front runs the PLL and the amplitude PI on tone 0 itself, with a lock-in of its own fed
 * the tip deflection of every sample (the chain's lock-in is on the other thread and its
 * outputs come later). Every fm.update_samples samples counted from create the loops update
 * and set tone 0 phase-continuously (afm_sim_set_tone); the open ring item is committed
 * first, so that every item still carries the one drive its samples ran with. The NCO
 * starts at mode 1's f0 of the model, which is also the frequency shift's reference, and the
 * drive at tone 0's amplitude of the config (at most fm.drive_max_m); with
 * fm.amplitude_setpoint_m 0 the amplitude first locked at is held. Dither commands are
 * rejected while it runs (nothing changed). No allocation: a few tens of flops per update
 * plus the lock-in per sample and, per NCO step, the integrator's tone change.
 * Self-excited (fm.drive = "self", runner/afm_fm_self.h) the front also stores every sample
 * in the delay line (one store), counts the oscillation's frequency at each update before
 * the loops (afm_fm_run's order) and re-synthesises tone 0 at the deflection's phase plus
 * the set-point every update (afm_sim_set_tone_phase: a phase jump, the item committed
 * first; the lock-ins here and in the chain retune), with no NCO quantum; a reset or a
 * blow-up refills the delay line. The status's fm_frequency_hz is then the counted
 * frequency and fm_phase_error_deg the lock-in's check (~0), not a control input.
 *
 * Internal AM Z control (the config's am.control = "internal", issue 18; runner/afm_pi.h):
 * the front runs the reference PI of `afmtwin scan` (afm_scan.h) on Z itself, fed the
 * amplitude of a lock-in of its own at tone 0 (the FM loops' lock-in: the two controls
 * exclude each other), with am's gains, slew limit, range and set-point am.setpoint_ratio x
 * A0 (runner/afm_a0.h, computed by afm_runner_model_build off the real-time thread). It
 * updates every AFM_RUNNER_SCAN_SAMPLES samples counted from create, on the moving tip's
 * grid: the tip is placed at the middle of the next samples, they run, the PI takes the
 * amplitude and sets the stage Z (the gap is Z - z_s under the tip) -- afm_scan_run's order,
 * so a raster through the daemon images as the offline scan does. After create, a reset, a
 * blow-up and a reload it waits for the lock-in to settle (12 time constants per order plus
 * 5 Q / (pi f0)) before moving Z. Setpoint commands and params that set Z are rejected while
 * it runs (nothing changed). A0 is the free amplitude: what sets it sets the reference
 * again, from an A0 computed off the real-time thread -- a new model (damping, geometry)
 * brings its own at the drive in force, a squeeze-film param and a dither that moves tone 0
 * come with one (afm_runner_dither_moves_a0); a tip-sample force constant does not move it.
 * Every applied command but a reload sets seq_applied = its seq (a reload keeps it); the
 * outputs carry the seq_applied of the samples they come from (chain_status_get).
 *
 * A numerical blow-up (AFM_SIM_EBLOWUP from the integrator) resets the state to rest and
 * the chain, is counted (status.blowups, last_blowup_t_s); the samples of that slice are
 * dropped and the run goes on with the rest of it from rest. A blow-up that recurs --
 * AFM_RUNNER_BLOWUP_PAUSE of them, each within AFM_RUNNER_BLOWUP_WINDOW_S of model time of
 * the one before, with no command applied in between -- pauses the twin (status.auto_paused,
 * afm_runner_pause_reason says why) instead of spinning through resets; control RUN resumes.
 * The plausibility limits (afm_limits.h) keep single commands from running away; this
 * catches what they cannot see, e.g. the damping taken away under a resonant drive. */
#ifndef AFM_RUNNER_H
#define AFM_RUNNER_H

#include "estimators/afm_chain.h"
#include "runner/afm_cmd.h"
#include "config/afm_config.h"
#include "integrators/afm_sim.h"

#include <stdint.h>

#define AFM_RUNNER_RAMP_SAMPLES 64     /* Z ramp update interval (samples; 4.6 us at 14.06 MHz) */
#define AFM_RUNNER_SCAN_SAMPLES 64     /* the moving tip's update interval (samples) */
#define AFM_RUNNER_SLOT_SAMPLES 1024   /* samples per ring item (73 us at 14.06 MHz) */
#define AFM_RUNNER_BLOWUP_PAUSE 3      /* recurring blow-ups before the twin pauses itself */
#define AFM_RUNNER_BLOWUP_WINDOW_S 1.0 /* ... each within this model time of the last */
#define AFM_RUNNER_FM_NCO_HZ 1e-3      /* internal FM: the NCO's frequency resolution (Hz) */
#define AFM_RUNNER_FM_DRIVE_REL 1e-6   /* ... and the drive's, relative to the drive in force */

typedef struct afm_runner afm_runner;
/* A simulator (and, for geometry changes and reloads, a chain) built for a config, ready
 * to be swapped in. After afm_runner_apply the same handle holds what was swapped out. */
typedef struct afm_runner_model afm_runner_model;

/* Whether a runner of cfg hands the integrator's per-step record (integrators/afm_rt_events.h:
 * crossings, min of x, tip-sample work) to its chain's cycle metrics (afm_chain_push_ev;
 * issue 28): sim.step_events not "off", AFMTWIN_STEP_EVENTS not "0" in the environment (as
 * the offline tools, tools/opts.h), and an integrator that records: CVODE, or rt without
 * thermal noise (whose accurate scheme records; the fast scheme does not, and its samples
 * keep the sample path: a hand-over switches at the next ring item). Read once, at create. The
 * record costs the integrator thread (~+41 % per sample, docs/numerics.md); the daemon's `--scheme
 * auto` measures the accurate scheme with it (runner/afm_scheme_cost.h). */
bool afm_runner_step_events(const afm_config *cfg);

/* Build the twin of cfg. block_max: the largest slice afm_runner_run processes in one
 * integrator call (sizes the sample buffer; larger n are split). lockstep: the twin
 * advances only by tick budget (see afm_runner_run). The config's drive must pass the
 * model-dependent limits (afm_cmd_check_cfg_drive). NULL with err on failure. */
afm_runner *afm_runner_create(const afm_config *cfg, int block_max, bool lockstep, char *err,
                              size_t errlen);
/* As afm_runner_create; pipelined: the back runs on another thread (see above), through a
 * ring of ring_items (2..65536) items of AFM_RUNNER_SLOT_SAMPLES samples and their
 * integrator records (~115 kB each: 48 + 64 bytes per sample). */
afm_runner *afm_runner_create_pipelined(const afm_config *cfg, int block_max, bool lockstep,
                                        bool pipelined, int ring_items, char *err, size_t errlen);
void afm_runner_destroy(afm_runner **r);
/* Start model time at t_s instead of 0 (afm_sim_set_time), before the first run: to
 * reproduce offline what a daemon does after being up that long. 0, or -1 with err (samples
 * already run, or t_s out of range). */
int afm_runner_set_time(afm_runner *r, double t_s, char *err, size_t errlen);
bool afm_runner_pipelined(const afm_runner *r);

/* Build, for a DAMPING / GEOMETRY param command or a reload, the simulator for cfg (the
 * config the command leads to: the caller's copy after afm_param_apply, or the new file),
 * and a chain when new_chain (geometry: the OBD calibration follows the model; reload).
 * Allocates: call off the real-time thread. NULL with err. */
afm_runner_model *afm_runner_model_build(const afm_config *cfg, bool new_chain, char *err,
                                         size_t errlen);
/* The same, with the AM Z loop's A0 (am.control = "internal") at tone 0 of drive, the drive
 * in force (dither commands move it away from cfg's; NULL: cfg's tone 0). */
afm_runner_model *afm_runner_model_build_at(const afm_config *cfg, bool new_chain,
                                            const afm_cmd_dither *drive, char *err, size_t errlen);
/* For a dither that moves tone 0 under am.control = "internal"
 * (afm_runner_dither_moves_a0): a model holding only the free amplitude A0 of cfg at tone
 * 0 of drive (the command's), no simulator; pass it to afm_runner_apply with the dither,
 * the set-point becomes setpoint_ratio x A0 and the model comes back to the caller.
 * Allocates and runs a short simulation (~0.1 s): off the real-time thread. NULL with err. */
afm_runner_model *afm_runner_model_a0(const afm_config *cfg, const afm_cmd_dither *drive, char *err,
                                      size_t errlen);
void afm_runner_model_destroy(afm_runner_model **m);
/* The modal model of m (for command limits: afm_cmd_limits.model), NULL without one. */
const afm_modal *afm_runner_model_modal(const afm_runner_model *m);

/* Does this (validated) command need a model from afm_runner_model_build? 1 for a reload
 * and for a param command whose strongest effect is DAMPING or GEOMETRY (then *new_chain
 * says whether the model needs a chain), and for a FORCE param of the squeeze film while
 * am.control is "internal" (only the model's A0 is used: the set-point's new reference; the
 * model comes back to the caller; the other force constants are the tip's, which A0, the
 * amplitude far from the sample, does not see), else 0. cfg: the config before the
 * command. Build the model at the drive in force (afm_runner_model_build_at). */
int afm_runner_cmd_needs_model(const afm_config *cfg, const afm_cmd *c, bool *new_chain);

/* Does dither command c, with now the drive in force (frequency and amplitude of tone 0 as
 * given), move the free amplitude A0 of the internal AM Z loop (am.control = "internal")?
 * true when tone 0's frequency or amplitude changes (to a sounding tone); then build
 * afm_runner_model_a0 for it. A0 is the FREE amplitude: the drive (tone 0), the damping,
 * the model and the squeeze film set it (a new model brings its own, afm_runner_model_build
 * at the drive in force); the tip-sample forces do not (far from the sample they vanish:
 * afm_runner_cmd_needs_model asks for no model for them). */
bool afm_runner_dither_moves_a0(const afm_config *cfg, const afm_cmd_dither *now, const afm_cmd *c);

/* Apply c now (between runs). model: NULL, or the address of a model handle for the
 * commands that need one; on success it then holds the objects swapped out (destroy them
 * off the real-time thread), or, pipelined, NULL: they come out of afm_runner_take_trash
 * once the chain thread has passed the swap. 0, or -1 with err and nothing changed (*model
 * still the caller's). AFM_RUNNER_EBUSY (pipelined only), nothing changed, when the chain
 * stage is so far behind that the changes it has to follow no longer fit: apply it again
 * after the next run (the daemon keeps it at the head of its queue). */
#define AFM_RUNNER_EBUSY (-2)
int afm_runner_apply(afm_runner *r, const afm_cmd *c, afm_runner_model **model, char *err,
                     size_t errlen);

/* Advance up to n samples. Free-running (not lockstep) and running: n. Paused: at most the
 * STEP budget. Lockstep and running: at most the tick budget. Returns the samples advanced
 * (0..n). Outputs wait in the chain's rings until taken. n = 0 only moves changes (and a
 * completion) that waited for ring space into the ring. */
long long afm_runner_run(afm_runner *r, long long n);

/* Samples the next afm_runner_run would advance at most (LLONG_MAX when not gated). */
long long afm_runner_budget(const afm_runner *r);

/* Back, pipelined only (inline, run and apply do it): process up to max_items (<= 0: all)
 * ring items; stops early before samples that follow a later command than the outputs
 * waiting, so that the caller takes those first with their seq, and before a reset (which
 * clears the chain's queues: what waits there would be lost). Returns items processed
 * (0: nothing waiting). */
int afm_runner_chain_run(afm_runner *r, int max_items);
/* Back: true when the next waiting item holds samples of a later command than the
 * outputs waiting now, or is a reset (afm_runner_chain_run would stop before it): hand
 * those out first. */
bool afm_runner_chain_seq_next(afm_runner *r);

/* Back: the completion of a tick (lockstep) or step budget. When the integrator uses up the
 * budget it runs on (ticks while running in lockstep, steps while paused), a marker follows
 * the samples; once afm_runner_chain_run has passed it (it stops right after), this returns
 * 1 with the seq of the last tick (or step) command applied, the samples run since create
 * and the model time reached, then 0 until the next one: hand out the outputs waiting first,
 * they are the budget's. Ticks sent while an earlier one still runs are completed together
 * (one marker, the last seq); ticks sent while paused run, and complete, after RUN. Inline, the
 * back does not stop there and this returns the latest marker. */
typedef struct {
    int64_t seq;
    long long samples;
    double t_s;
} afm_runner_done;
int afm_runner_take_done(afm_runner *r, afm_runner_done *d);

/* Back: the objects a swap replaced (a model handle to afm_runner_model_destroy off the
 * real-time threads). 1 with *m, 0 when none waits. */
int afm_runner_take_trash(afm_runner *r, afm_runner_model **m);

/* The operating point some samples were made at: what a curve is built from. */
typedef struct {
    double z_m; /* separation Z at the last of them (a ramp moves it within a block) */
    int n_tones;
    double freq_hz[AFM_MAX_TONES], amp_m[AFM_MAX_TONES]; /* the drive's tones */
    /* the sample under the tip at the last of them (0 without a sample group; issue 18) */
    double tip_x_m, tip_y_m; /* the tip's lateral position */
    double true_height_m;    /* z_s there (the gap is z_m - true_height_m) */
    int material;            /* the region there: 0 the forces group's sample, i materials[i-1] */
    /* the internal FM loops (fm.control = "internal", issue 32) after their last update before
     * the samples' item began: lock state (afm_fm_lock; -1 without the loops), frequency shift
     * (tone 0's frequency, freq_hz[0], less the NCO's centre f_center) and PLL phase error
     * (lock-in lag - fm.phase_setpoint_deg); NAN without the loops; the drive they run
     * (afm_fm_drive: 0 pll, 1 self; -1 without the loops) */
    int fm_lock, fm_drive;
    double fm_shift_hz, fm_phase_error_deg;
} afm_runner_oppoint;

/* As afm_runner_take_periods(_raw), with ops[i] the operating point of out[i]: that of the
 * sample its period ended on (Z, drive, and with a sample the stage Z and the tip's place:
 * the position update in force at that sample, every AFM_RUNNER_SCAN_SAMPLES while the tip
 * moves), whenever the records are taken, so that the outputs do not depend on how often the
 * caller takes them (the daemon every block, replay every --block; issue 18: a moving tip, a
 * Z loop). ops may be NULL. */
int afm_runner_take_periods_op(afm_runner *r, afm_chain_period *out, afm_runner_oppoint *ops,
                               int max);
int afm_runner_take_periods_raw_op(afm_runner *r, afm_chain_period *out, afm_runner_oppoint *ops,
                                   int max);

typedef struct {
    int64_t seq_applied;   /* seq of the command before the last samples the chain took */
    double fe_hz;          /* tone 0 frequency of those samples */
    afm_runner_oppoint op; /* their operating point */
    double t_s;            /* model time of the last sample the chain took */
    long long samples;     /* samples the chain took */
    long long attach_errors, trash_lost; /* should stay 0 */
    long long ev_samples; /* samples whose cycle metrics took the integrator's record */
    afm_chain_stats chain;
} afm_runner_chain_status;
void afm_runner_chain_status_get(const afm_runner *r, afm_runner_chain_status *st);

/* Back: decimated blocks of stream i and per-period records, as afm_chain_take_block /
 * afm_chain_take_periods (pointers valid until the next chain_run, or run / apply inline). */
int afm_runner_n_streams(const afm_runner *r);
int afm_runner_take_block(afm_runner *r, int stream, afm_chain_block *b, int max_n);
int afm_runner_take_periods(afm_runner *r, afm_chain_period *out, int max);
/* afm_chain_take_periods_raw and afm_chain_period_finish on the runner's chain: take every
 * record, finish the ones to publish. */
int afm_runner_take_periods_raw(afm_runner *r, afm_chain_period *out, int max);
/* afm_chain_periods_waiting, afm_chain_skip_periods on the runner's chain (the skipped
 * records' operating points go with them). */
int afm_runner_periods_waiting(const afm_runner *r);
int afm_runner_skip_periods(afm_runner *r, int n);
void afm_runner_period_finish(const afm_runner *r, afm_chain_period *p);

typedef struct {
    int64_t seq_applied; /* seq of the last command applied (-1: none yet) */
    long long samples;   /* samples advanced since create */
    double t_s;          /* model time */
    double dt_s;         /* sample interval */
    bool running;        /* not paused */
    bool lockstep;
    long long step_budget, tick_budget;
    double separation_m;        /* current Z */
    double separation_target_m; /* ramp target (= separation_m when not ramping) */
    double fe_hz;               /* tone 0 frequency */
    double amplitude_m;         /* tone 0 amplitude */
    long long blowups;          /* numerical blow-ups (state reset) */
    double last_blowup_t_s;     /* model time of the last one (NAN if none) */
    bool auto_paused;           /* paused by itself: recurring blow-ups (see above) */
    long long auto_pauses;      /* times it did */
    long long applied;          /* commands applied */
    long long swaps;            /* models swapped in (damping, geometry, reload) */
    long long stalls;           /* runs cut short by a full ring (pipelined: chain behind) */
    long long pending;          /* ring items the chain has not taken yet (a snapshot) */
    afm_chain_stats chain;      /* OBD saturation, ring drops, periods, estimator rejects
                                   (inline only; pipelined: afm_runner_chain_status_get) */
    /* internal FM control (fm.control = "internal"; NAN and 0 without it) */
    bool fm_on;
    int fm_lock;                    /* afm_fm_lock: 0 acquiring, 1 locked, 2 lost */
    int fm_drive;                   /* afm_fm_drive: the config's fm.drive (pll, self) */
    double fm_frequency_hz;         /* tone 0's frequency, the NCO */
    double fm_reference_hz;         /* the shift's reference: mode 1's f0 of the model */
    double fm_phase_error_deg;      /* lock-in lag - fm.phase_setpoint_deg, last update */
    double fm_drive_m;              /* tone 0's drive amplitude (the dissipation channel) */
    double fm_amplitude_m;          /* the FM lock-in's amplitude, last update */
    double fm_amplitude_setpoint_m; /* 0: not held yet (held from the first lock) */
    long long fm_tone_changes;      /* tone 0 changes the loops made */
    long long fm_tone_refused;      /* ... the simulator refused (should stay 0) */
    /* internal AM Z control (am.control = "internal", issue 18; NAN without it) */
    bool am_on;
    double am_z_m;         /* the PI's Z (= separation_m), last update */
    double am_error_m;     /* its error: set-point less amplitude, last update */
    double am_setpoint_m;  /* amplitude held: am.setpoint_ratio x A0 */
    double am_amplitude_m; /* the loop's lock-in amplitude, last update (NAN while settling) */
    long long am_updates;  /* updates that moved Z */
    /* the sample under the tip (issue 18; all 0 and scan_line -1 without a sample group) */
    bool sample_on;            /* the config has a sample group */
    double tip_x_m, tip_y_m;   /* the tip's lateral position now */
    double true_height_m;      /* z_s there */
    int material;              /* the region there */
    int scan_mode;             /* afm_scan_mode of the motion in force (HOLD when done) */
    int scan_line, scan_pixel; /* a raster's line and pixel (-1 without a raster running) */
    bool scan_retrace;         /* ... going back along the line */
    long long gap_clamps;      /* updates where z_s rose past Z (gap held at 0) */
} afm_runner_status;

void afm_runner_status_get(const afm_runner *r, afm_runner_status *st);
/* Why the twin paused itself ("" unless st->auto_paused), from a status: formatting stays
 * off the real-time thread. */
void afm_runner_pause_reason(const afm_runner_status *st, char *buf, size_t len);

/* The config the runner is running now (after live params and swaps). Valid until the
 * next apply. */
const afm_config *afm_runner_config(const afm_runner *r);
/* The simulator (read-only: for its drive, model, separation). */
const afm_sim *afm_runner_sim(const afm_runner *r);
/* Front stage: hand the rt integrator over to the accurate (true) or fast scheme at the
 * current sample (afm_sim_set_scheme; no allocation, no jump). A model swapped in later
 * starts in its config's scheme: the caller applies its choice again. 0, or
 * AFM_SIM_EINVAL for an integrator without schemes. */
int afm_runner_set_scheme(afm_runner *r, bool accurate);

#endif
