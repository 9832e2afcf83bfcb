/* SPDX-License-Identifier: MIT */
/* map_file.h -- the file of `afmtwin map` (issue 31): its header, one block of text per map
 * line (every point of the line in each direction, the line's jumps and bistable points,
 * closed by a checksum), writing, resuming and reading it. No MPI and no engine here: the
 * format alone, shared by `afmtwin map`, `afmtwin plot map` and the tests.
 *
 * The format (text, one record a line, fields separated by one space, every float printed
 * %.17g so that it reads back to the same bits; docs/map.md describes it for users):
 *   afmtwin-map 1
 *   config PATH
 *   config_fnv1a64 HEX          the config file's bytes, FNV-1a 64
 *   x NAME FROM TO N [UNIT]     NAME fe (Hz), z (m) or ae (m); value i = FROM + (TO - FROM)
 *   y NAME FROM TO N [UNIT]     i / (N - 1), the last one TO exactly (N 1: FROM); or a live
 *                               parameter (forces.vdw_contact.hamaker_j; on x a force one),
 *                               then followed by its unit ("-" for none)
 *   direction up|down|both
 *   integrator NAME scheme NAME
 *   tol X max_periods N jump_tol X jump_deg X bistable_tol X bistable_deg X
 *   columns ...                 the names of a P record's fields
 *   end_header
 * then per line iy = 0 .. Ny - 1, in order:
 *   L iy Y
 *   P iy DIR ix X Y amplitude_m phase_lag_deg peak_force_n attractive_force_n min_gap_m
 *     indentation_m contact_time_s dissipated_energy_j periodicity settled settle_periods
 *                               (one line; DIR u or d; for each direction asked, up first,
 *                                ix ascending)
 *   J iy DIR ix_before ix_after amplitude_before_m amplitude_after_m lag_before_deg
 *     lag_after_deg             a jump between two neighbours of the pass, in pass order
 *   B iy ix                     bistable: up and down differ (direction both only)
 *   E iy HEX                    FNV-1a 64 of the block's bytes from its L record up to
 *                               and including the newline before this record */
#ifndef AFMT_MAP_FILE_H
#define AFMT_MAP_FILE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#define AFMT_MAP_MAX_N 100000 /* points per axis */

/* AFMT_MAP_NAMED: a live parameter of `afmtwin send param` (afm_cmd.h's table) by its name:
 * on y any (set in each line's config), on x a tip-sample force one (set at once, the state
 * carried: `afmtwin map`). */
typedef enum { AFMT_MAP_FE = 0, AFMT_MAP_Z, AFMT_MAP_AE, AFMT_MAP_NAMED } afmt_map_param;

typedef struct {
    afmt_map_param param;
    double from, to; /* from < to, or from == to with n == 1 */
    int n;
    char name[80]; /* AFMT_MAP_NAMED: the table's name (e.g. forces.vdw_contact.hamaker_j) */
    char unit[16]; /* AFMT_MAP_NAMED: its SI unit ("-" for none) */
} afmt_map_axis;

enum { AFMT_MAP_UP = 1, AFMT_MAP_DOWN = 2, AFMT_MAP_BOTH = 3 };

/* What identifies a map: a resumed file must carry exactly this header. */
typedef struct {
    const char *config_path;
    uint64_t config_hash;
    afmt_map_axis x, y;
    int dirs; /* AFMT_MAP_UP | AFMT_MAP_DOWN */
    const char *integrator, *scheme;
    double tol, jump_tol, jump_deg, bistable_tol, bistable_deg;
    int max_periods;
} afmt_map_spec;

/* One settled (or given-up) point. */
typedef struct {
    double amplitude_m;   /* harmonic 1 of the deflection over the analysed orbit */
    double lag_deg;       /* its lag behind the drive (90 free at resonance) */
    double peak_force_n;  /* afm_cycle over the last whole drive period */
    double attractive_n;  /* min tip force over that period (< 0: attractive) */
    double min_gap_m;     /* min d = x cos(alpha) + Z over that period */
    double indentation_m; /* max a0 - d, 0 without contact */
    double contact_time_s;
    double energy_j; /* dissipated, -int F v dt */
    int periodicity; /* 0: not settled */
    int settled;     /* 1 settled, 0 gave up at max_periods */
    int settle_periods;
} afmt_map_point;

const char *afmt_map_param_name(afmt_map_param p); /* "fe", "z", "ae" ("named") */
const char *afmt_map_param_unit(afmt_map_param p); /* "Hz", "m", "m" */
/* An axis's parameter name and unit: fe/z/ae's, or a named one's own. */
const char *afmt_map_axis_name(const afmt_map_axis *a);
const char *afmt_map_axis_unit(const afmt_map_axis *a);
/* -1 for an unknown name. */
int afmt_map_param_parse(const char *s);
/* Value i of an axis. */
double afmt_map_axis_value(const afmt_map_axis *a, int i);

uint64_t afmt_map_fnv(uint64_t h, const void *p, size_t n);
#define AFMT_MAP_FNV_INIT 0xcbf29ce484222325ULL
/* The FNV-1a 64 of a file's bytes: 0, or -1 (errno). */
int afmt_map_hash_file(const char *path, uint64_t *h);

/* The header text of spec (malloc'd, NUL-terminated), NULL on allocation failure. */
char *afmt_map_header(const afmt_map_spec *spec);

/* The text block of line iy (malloc'd, NUL-terminated; NULL on allocation failure). pts[d]
 * are the points of direction d (0 up, 1 down; NULL when not asked), nx each, index ix. */
char *afmt_map_block(const afmt_map_spec *spec, int iy, const afmt_map_point *const pts[2]);

/* Resume: check the file at path against header: the same header bytes, then whole,
 * checksummed line blocks 0, 1, ... in order; a last block cut short (an interrupted
 * write) is dropped. *lines_done: the complete blocks, *keep_bytes: where they end. 0 ok;
 * -1 with err (cannot read it, another map, a corrupt block): nothing is changed. */
int afmt_map_resume_check(const char *path, const char *header, int ny, int *lines_done,
                          long *keep_bytes, char *err, size_t errlen);

/* A whole map read back (for plot and gsf): the points of every line and direction. */
typedef struct {
    afmt_map_axis x, y;
    int dirs;
    char config[512];
    int lines;               /* complete lines read (may be < y.n for a partial map) */
    afmt_map_point *pts[2];  /* [d][iy * x.n + ix], NULL when direction d was not run */
    unsigned char *bistable; /* [iy * x.n + ix] */
    int n_jumps;             /* jump records */
    struct afmt_map_jump {
        int iy, dir, ix_before, ix_after; /* dir 0 up, 1 down */
    } * jumps;                            /* n_jumps of them, in file order */
} afmt_map_data;

/* Read a map file: 0, or -1 with err. */
int afmt_map_read(const char *path, afmt_map_data *m, char *err, size_t errlen);
void afmt_map_data_destroy(afmt_map_data *m);

#endif
