/* SPDX-License-Identifier: MIT */
/* cmd_bench_scheme.c -- `afmtwin bench-scheme`: which scheme of the rt integrator the
 * daemon's `--scheme auto` runs on each shipped config on this machine, from the same
 * measurement (afm_scheme_cost_measure): both schemes' cost per sample in their worst state
 * against AFM_SCHEME_FIT_SHARE of the budget 1 / rate / speed (docs/realtime.md quotes a
 * run). The measurement is wall-clock: a loaded machine reads slower. */
#include "afmtwin_cmds.h"
#include "opts.h"

#include "config/afm_config.h"
#include "runner/afm_scheme_cost.h"

#include <cjson/cJSON.h>
#include <stdio.h>
#include <string.h>

static const char *const configs[] = {"default.conf",         "nchv.conf",
                                      "thesis-1dof.conf",     "thesis-fig-4-2.conf",
                                      "thesis-fig-4-8.conf",  "thesis-fig-4-13.conf",
                                      "thesis-fig-4-20.conf", "probe-q300.conf",
                                      "lumped-vdw-fold.conf", NULL};

static void usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin bench-scheme [--config-dir DIR] [--speed X] [--json]\n\n"
            "For each shipped config: the cost per sample of the rt integrator's accurate and\n"
            "fast schemes in their worst state (the config's operating point, half its\n"
            "separation, free at Z 1 um; settled from rest, median of %d windows), the\n"
            "budget 1 / (rate x speed), and the scheme `afmtwind --scheme auto` picks: accurate\n"
            "when its worst state fits %.0f%% of the budget. Wall-clock on this machine.\n\n"
            "options:\n"
            "  --config-dir DIR  where the .conf files are (default config)\n"
            "  --speed X         the daemon's --speed (default 1)\n"
            "  --json            one JSON object per config and line\n"
            "  --help            this text\n",
            AFM_SCHEME_REPEATS, 100.0 * AFM_SCHEME_FIT_SHARE);
}

int afm_cmd_bench_scheme(int argc, char **argv) {
    const char *dir = "config";
    double speed = 1.0;
    bool json = false;
    const afmt_opt opts[] = {
        AFMT_STRING("--config-dir", &dir),
        AFMT_DOUBLE("--speed", &speed, 1e-3, 1e3, NULL),
        AFMT_FLAG("--json", &json),
        AFMT_OPTS_END,
    };
    int prc = afmt_opts_parse("bench-scheme", opts, argc, argv, 1);
    int rc = afmt_opts_done("bench-scheme", prc == AFMT_OPTS_HELP ? 1 : prc ? -1 : 0, usage);
    if (rc >= 0) return rc;
    if (!json)
        printf("# %-22s %12s %12s %10s %9s  (ns per sample, worst state; pick: afmtwind --scheme "
               "auto)\n",
               "config", "accurate_ns", "fast_ns", "budget_ns", "pick");
    for (int i = 0; configs[i]; i++) {
        char path[1024], err[512];
        static afm_config cfg;
        snprintf(path, sizeof path, "%s/%s", dir, configs[i]);
        if (afmt_config_load("bench-scheme", path, &cfg)) return 2;
        afm_scheme_cost ca, cf;
        if (afm_scheme_cost_measure(&cfg, AFM_RT_SCHEME_ACCURATE, &ca, err, sizeof err) ||
            afm_scheme_cost_measure(&cfg, AFM_RT_SCHEME_FAST, &cf, err, sizeof err)) {
            fprintf(stderr, "afmtwin bench-scheme: %s: %s\n", path, err);
            return 1;
        }
        double budget = 1e9 / cfg.sim.sample_rate_hz / speed;
        const char *pick = ca.worst_ns <= AFM_SCHEME_FIT_SHARE * budget ? "accurate" : "fast";
        if (json) {
            cJSON *o = cJSON_CreateObject();
            cJSON_AddStringToObject(o, "config", configs[i]);
            cJSON_AddNumberToObject(o, "accurate_ns", ca.worst_ns);
            cJSON_AddNumberToObject(o, "fast_ns", cf.worst_ns);
            /* per state: the operating point, half its Z, free */
            cJSON_AddItemToObject(o, "accurate_states_ns",
                                  cJSON_CreateDoubleArray(ca.ns, AFM_SCHEME_STATES));
            cJSON_AddItemToObject(o, "fast_states_ns",
                                  cJSON_CreateDoubleArray(cf.ns, AFM_SCHEME_STATES));
            cJSON_AddNumberToObject(o, "budget_ns", budget);
            cJSON_AddStringToObject(o, "pick", pick);
            char *s = cJSON_PrintUnformatted(o);
            printf("%s\n", s);
            cJSON_free(s);
            cJSON_Delete(o);
        } else {
            printf("%-24s %12.1f %12.1f %10.1f %9s\n", configs[i], ca.worst_ns, cf.worst_ns, budget,
                   pick);
        }
        fflush(stdout);
    }
    return 0;
}
