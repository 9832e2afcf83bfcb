/* SPDX-License-Identifier: MIT */
/* check.c -- counters and one-line reports for tests/check.h. */
#include "check.h"

#include <math.h>
#include <stdio.h>

static int n_pass, n_fail;

static bool report(bool ok, const char *what, double got, double want, double tol,
                   const char *kind) {
    if (ok)
        n_pass++;
    else
        n_fail++;
    printf("%-4s %s: got %.10g want %.10g (%s tol %.3g)\n", ok ? "ok" : "FAIL", what, got, want,
           kind, tol);
    return ok;
}

bool check_true(bool cond, const char *what) {
    if (cond)
        n_pass++;
    else
        n_fail++;
    printf("%-4s %s\n", cond ? "ok" : "FAIL", what);
    return cond;
}

bool check_rel(double got, double want, double tol_rel, const char *what) {
    bool ok = isfinite(got) && fabs(got - want) <= tol_rel * fabs(want);
    return report(ok, what, got, want, tol_rel, "rel");
}

bool check_abs(double got, double want, double tol_abs, const char *what) {
    bool ok = isfinite(got) && fabs(got - want) <= tol_abs;
    return report(ok, what, got, want, tol_abs, "abs");
}

bool check_thesis(const char *table, const char *item, double ours, double thesis, double tol_rel) {
    char what[256];
    snprintf(what, sizeof what, "%s %s", table, item);
    bool ok = check_rel(ours, thesis, tol_rel, what);
    printf("VALIDATION|%s|%s|%.10g|%.10g|%.2e|%.1e|%s\n", table, item, thesis, ours,
           fabs(ours - thesis) / fabs(thesis), tol_rel, ok ? "ok" : "FAIL");
    return ok;
}

bool check_thesis_abs(const char *table, const char *item, double ours, double thesis,
                      double tol_abs, const char *unit) {
    char what[256];
    snprintf(what, sizeof what, "%s %s", table, item);
    bool ok = check_abs(ours, thesis, tol_abs, what);
    printf("VALIDATION|%s|%s|%.10g|%.10g|%.3g %s|%.3g %s|%s\n", table, item, thesis, ours,
           fabs(ours - thesis), unit, tol_abs, unit, ok ? "ok" : "FAIL");
    return ok;
}

int check_done(void) {
    printf("%d passed, %d failed\n", n_pass, n_fail);
    return n_fail == 0 ? 0 : 1;
}
