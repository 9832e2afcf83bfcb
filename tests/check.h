/* SPDX-License-Identifier: MIT */
/* check.h -- the tiny assertion harness every test binary uses.
 *
 * Each CHECK prints one line (ok/FAIL, what, got, want, tolerance) and counts it.
 * check_done() prints "N passed, N failed" and returns the exit code, so
 * tests/run.sh can add the counts of all binaries into one closing line. */
#ifndef AFM_TEST_CHECK_H
#define AFM_TEST_CHECK_H

#include <stdbool.h>

/* Record one named check; returns cond. */
bool check_true(bool cond, const char *what);
/* |got - want| <= tol_rel * |want| (relative; want != 0). */
bool check_rel(double got, double want, double tol_rel, const char *what);
/* |got - want| <= tol_abs. */
bool check_abs(double got, double want, double tol_abs, const char *what);
/* A thesis value reproduced: checks |ours - thesis| <= tol_rel |thesis| like check_rel and
 * also prints "VALIDATION|table|item|thesis|ours|rel diff|tol" for tools/validation-doc.sh. */
bool check_thesis(const char *table, const char *item, double ours, double thesis, double tol_rel);
/* Same for an absolute tolerance (phases in degrees, values near zero). */
bool check_thesis_abs(const char *table, const char *item, double ours, double thesis,
                      double tol_abs, const char *unit);
/* Print "N passed, N failed" and return 0 when nothing failed, 1 otherwise. */
int check_done(void);

#endif
