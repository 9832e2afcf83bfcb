/* SPDX-License-Identifier: MIT */
/* cmd_modes.c -- `afmtwin modes`: the linear model's frequencies, MAC, stiffness, mass. */
#include "afmtwin_cmds.h"
#include "json_out.h"
#include "opts.h"

#include "config/afm_config.h"
#include "beam/afm_model.h"

#include <cjson/cJSON.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void modes_usage(FILE *f) {
    fprintf(
        f, "usage: afmtwin modes --config FILE [--json]\n\n"
           "Builds the reduced-order model of FILE and prints:\n"
           "  analytical  clamped-free Euler-Bernoulli frequencies (uniform beams, no tip mass)\n"
           "  unreduced   full FEM frequencies (clamped base, with tip mass)\n"
           "  reduced     frequencies of the Rubin method-2 model (nk + 2 modes)\n"
           "  MAC         reduced modes (rows) against unreduced modes (columns), eq. 3.8-3.10\n"
           "  static tip stiffness (N/m) and the effective mass of mode 1 at the tip (eq. 2.14)\n\n"
           "options:\n"
           "  --config FILE  libconfig model file (see config/README.md)\n"
           "  --json         one JSON object: frequencies_hz {analytical, unreduced, reduced},\n"
           "                 mac, tip_static_stiffness_n_per_m, effective_mass_kg\n"
           "  --help         this text\n");
}

static cJSON *array_of(const double *v, int n) {
    return cJSON_CreateDoubleArray(v, n);
}

static int print_json(const afm_modes_report *r) {
    cJSON *o = cJSON_CreateObject(), *f = cJSON_CreateObject(), *mac = cJSON_CreateArray();
    cJSON_AddItemToObject(f, "analytical", array_of(r->analytical_hz, r->n_analytical));
    cJSON_AddItemToObject(f, "unreduced", array_of(r->unreduced_hz, r->n_unreduced));
    cJSON_AddItemToObject(f, "reduced", array_of(r->reduced_hz, r->n_reduced));
    cJSON_AddItemToObject(o, "frequencies_hz", f);
    for (int i = 0; i < r->n_reduced && r->n_unreduced > 0; i++)
        cJSON_AddItemToArray(mac, array_of(r->mac[i], r->n_unreduced));
    cJSON_AddItemToObject(o, "mac", mac);
    cJSON_AddNumberToObject(o, "tip_static_stiffness_n_per_m", r->static_stiffness_n_m);
    cJSON_AddNumberToObject(o, "effective_mass_kg", r->effective_mass_kg);
    return afmt_json_emit(o) ? 1 : 0;
}

static void print_text(const char *path, const afm_modes_report *r) {
    printf("model %s\n\n%4s %16s %16s %16s\n", path, "mode", "analytical_hz", "unreduced_hz",
           "reduced_hz");
    int n = r->n_reduced > r->n_unreduced ? r->n_reduced : r->n_unreduced;
    for (int i = 0; i < n; i++) {
        printf("%4d", i + 1);
        if (i < r->n_analytical)
            printf(" %16.8g", r->analytical_hz[i]);
        else
            printf(" %16s", "-");
        if (i < r->n_unreduced)
            printf(" %16.8g", r->unreduced_hz[i]);
        else
            printf(" %16s", "-");
        if (i < r->n_reduced)
            printf(" %16.8g", r->reduced_hz[i]);
        else
            printf(" %16s", "-");
        printf("\n");
    }
    if (r->n_unreduced > 0) {
        printf("\nMAC (reduced rows, unreduced columns)\n");
        for (int i = 0; i < r->n_reduced; i++) {
            for (int j = 0; j < r->n_unreduced; j++)
                printf(" %.10f", r->mac[i][j]);
            printf("\n");
        }
    }
    printf("\ntip static stiffness  %.6g N/m\neffective mass mode 1 %.6g kg\n",
           r->static_stiffness_n_m, r->effective_mass_kg);
}

int afm_cmd_modes(int argc, char **argv) {
    const char *path = NULL;
    bool json = false;
    const afmt_opt opts[] = {
        AFMT_STRING("--config", &path),
        AFMT_FLAG("--json", &json),
        AFMT_OPTS_END,
    };
    int rc = afmt_opts_parse("modes", opts, argc, argv, 1);
    if (rc == AFMT_OPTS_HELP) modes_usage(stdout);
    if (rc == AFMT_OPTS_BAD) modes_usage(stderr);
    if (rc) return rc == AFMT_OPTS_HELP ? 0 : 2;
    if (!path) {
        fprintf(stderr, "afmtwin modes: --config FILE is required\n");
        modes_usage(stderr);
        return 2;
    }
    static afm_config cfg;
    static afm_modes_report rep;
    char err[AFM_ERR_LEN];
    if (afmt_config_load("modes", path, &cfg)) return 2;
    if (afm_model_report(&cfg.model, &rep, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin modes: %s\n", err);
        return 1;
    }
    if (json) return print_json(&rep);
    print_text(path, &rep);
    return 0;
}
