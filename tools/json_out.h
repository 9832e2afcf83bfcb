/* SPDX-License-Identifier: MIT */
/* json_out.h -- how every `afmtwin` subcommand with --json writes a result: one cJSON object
 * as one line on stdout. */
#ifndef AFMT_JSON_OUT_H
#define AFMT_JSON_OUT_H

#include <cjson/cJSON.h>

/* Print o unformatted on one line of stdout, then delete it (o is no longer valid; NULL is
 * allowed and prints nothing). 0, or -1 (o NULL, or cJSON could not print it). */
int afmt_json_emit(cJSON *o);

/* Add v to o as key: a number, or null when v is not finite (JSON has no NaN nor
 * infinity; NaN is how the tools say "not measured"). */
void afmt_json_num(cJSON *o, const char *key, double v);

#endif
