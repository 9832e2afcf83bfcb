/* SPDX-License-Identifier: MIT */
/* cmd_plot.h -- what the files of `afmtwin plot` share (internal to them): the options, the
 * data sets a kind fills, the legend, the picture's layout in pixels, and the helpers that
 * read the inputs and lay out the panels (cmd_plot.c). Each kind's loader reads its input
 * into data sets and writes its gnuplot commands; cmd_plot.c parses the options, calls the
 * loader KIND names and hands the script (the sets as inline data) to gnuplot. The kinds
 * with a boundary of their own live in their own files: continue (cmd_plot_continue.c),
 * trace (cmd_plot_trace.c) and fm (cmd_plot_fm.c). */
#ifndef AFMT_CMD_PLOT_H
#define AFMT_CMD_PLOT_H

#include "plot_info.h"

#include <cjson/cJSON.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

#define PLOT_MAX_INPUTS 8
#define PLOT_MAX_COLS 16
#define PLOT_MAX_SETS 24
#define PLOT_MAX_KEYS 40
#define PLOT_LINE_MAX (1 << 20)
#define PLOT_EV 1.602176634e-19 /* J per eV */

/* Text in pixels (pngcairo's default font): a line, and a character of a legend entry
 * (generous: a legend that needs more rows than planned would run into the panels). */
#define PX_LINE 19.0
#define PX_CHAR 9.0
/* The panels' margins in pixels: left (tic labels and the y label), right, bottom (tic
 * labels and the x label), and between panels that share x (one set of tic labels). */
#define PX_LEFT 85.0
#define PX_RIGHT 25.0
#define PX_BOTTOM 55.0
#define PX_GAP 18.0

typedef struct {
    const char *kind, *out, *data, *csv, *script, *fit, *title, *config;
    const char *in[PLOT_MAX_INPUTS];
    int n_in, index, stream, width, height;
    double t_from_s, t_to_s, z_m, fe_hz, ae_m;
    /* continue's zoom, in the picture's units (kHz or nm for the parameter, nm for y): x,
     * then y of the top (min xr) and of the lower (amplitude) panel; NAN: not given */
    double range_lo[3], range_hi[3];
    bool zoom_pd; /* continue --zoom-pd: the window of the period-doubled branches */
} plot_opts;

/* A data set: rows of ncol numbers (NAN prints as "NaN", which gnuplot skips). The header
 * names the columns as NAME[UNIT]; a set with seg_col >= 0 is cut into line segments (a
 * blank line for gnuplot) where that column changes. The sets marked csv are the curves
 * --csv writes, label naming each in the CSV's first column. */
typedef struct {
    char name[16], label[48], header[320];
    int ncol, seg_col;
    bool csv;
    size_t n, cap;
    double *v;
} plot_set;

typedef struct {
    plot_set set[PLOT_MAX_SETS];
    int nset;
    char title[512], sub[512];  /* the title's two lines (sub may be empty) */
    char note[256], note2[256]; /* more lines under them (may be empty; no quotes) */
    plot_info info;
    double W, H; /* the picture, pixels */
} plot_data;

/* Legend entries: a gnuplot style ("with linespoints ls 1") and a title. */
typedef struct {
    int n;
    char with[PLOT_MAX_KEYS][128], title[PLOT_MAX_KEYS][96];
} plot_key;

/* "afmtwin plot: " fmt (with a) on stderr; -1. */
int plot_err(const char *fmt, const char *a);
/* A log with no LCM event in it (text, JSON, an empty file): "FILE: not an LCM log (...)"
 * with what the reader saw: the bytes it skipped looking for an event's sync word, or the
 * first event's fault (NULL: none). -1. */
int plot_not_lcm_log(const char *path, long long skipped, const char *fault);
/* o's string key is want */
bool plot_str_is(const cJSON *o, const char *key, const char *want);
/* max(v, 0) and min(v, 0), NAN kept */
double plot_clip_pos(double v);
double plot_clip_neg(double v);
/* Panel p of a 2 x 2 grid (0 top left, 1 top right, 2, 3 below), or with split the last
 * cell cut into two panels sharing x, p 3 over p 4; sets the x tic labels and xlabel as
 * plot_shared_x; returns the panel's height in pixels. */
double plot_grid_cell(FILE *gp, const plot_data *d, int p, bool split, double l, double r,
                      double top, const char *xlabel);

/* ---- data sets ---- */

/* A new set of d (NULL: PLOT_MAX_SETS reached or ncol > PLOT_MAX_COLS). */
plot_set *plot_set_new(plot_data *d, const char *name, const char *header, int ncol);
/* A curve of the CSV, named label there. */
plot_set *plot_curve_new(plot_data *d, const char *name, const char *label, const char *header,
                         int ncol);
/* Append a row of s->ncol numbers: 0, or -1 (out of memory). */
int plot_set_row(plot_set *s, const double *row);
/* Row r's column c. */
double plot_cell(const plot_set *s, size_t r, int c);

/* ---- JSON input ---- */

/* o's number key (NAN: none). */
double plot_num(const cJSON *o, const char *key);
/* o's key is true. */
bool plot_is_true(const cJSON *o, const char *key);
/* Each JSON line of path into fn (objects only; a line that is no JSON is an error). */
int plot_each_json(const char *path, int (*fn)(const cJSON *, void *), void *ctx);

/* ---- the figure ---- */

/* A legend entry (title cleaned for gnuplot; none past PLOT_MAX_KEYS). */
void plot_key_add(plot_key *k, const char *with, const char *title);
/* The plot area of the next panel, screen fractions. */
void plot_area(FILE *gp, double l, double r, double b, double t);
/* The title and, in a strip under it from l to r, the legend k: an empty plot of its
 * entries. Returns the top of the panels (screen); the panels have no key of their own. */
double plot_figure(FILE *gp, plot_data *d, const plot_key *k, double l, double r);
/* Panel i of n stacked from top to bottom (screen), gap between them. */
void plot_stack(FILE *gp, int i, int n, double l, double r, double bottom, double top, double gap);
/* Panels sharing x: tic labels and the x label only under the last. */
void plot_shared_x(FILE *gp, int i, int n, const char *xlabel);
/* y tics for a short panel of column col of the sets: 2 to 5 labels over px pixels (the
 * default would crowd them); the default where the column has no span. */
void plot_short_ytics(FILE *gp, plot_set *const *sets, int n, int col, double px);

/* ---- the kinds in files of their own: 0, or -1 (said) ---- */

int load_continue(const plot_opts *o, plot_data *d, FILE *gp); /* cmd_plot_continue.c */
int load_trace(const plot_opts *o, plot_data *d, FILE *gp);    /* cmd_plot_trace.c */
int load_fm(const plot_opts *o, plot_data *d, FILE *gp);       /* cmd_plot_fm.c */
int load_scan(const plot_opts *o, plot_data *d, FILE *gp);     /* cmd_plot_scan.c */
int load_approach(const plot_opts *o, plot_data *d, FILE *gp); /* cmd_plot_approach.c */

#endif
