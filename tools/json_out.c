/* SPDX-License-Identifier: MIT */
/* json_out.c -- one JSON object per line on stdout (see json_out.h). */
#include "json_out.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

int afmt_json_emit(cJSON *o) {
    char *s = o ? cJSON_PrintUnformatted(o) : NULL;
    if (s) puts(s);
    free(s);
    cJSON_Delete(o);
    return s ? 0 : -1;
}

void afmt_json_num(cJSON *o, const char *key, double v) {
    if (isfinite(v))
        cJSON_AddNumberToObject(o, key, v);
    else
        cJSON_AddNullToObject(o, key);
}
