/* SPDX-License-Identifier: MIT */
/* afm_lcm_url.c -- command and output LCM URLs (contract in afm_lcm_url.h). */
#include "transport/afm_lcm_url.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int copy(const char *s, char *out, size_t len, char *err, size_t errlen) {
    if (strlen(s) >= len) {
        snprintf(err, errlen, "LCM URL too long (%zu characters, at most %zu)", strlen(s), len - 1);
        return -1;
    }
    memcpy(out, s, strlen(s) + 1);
    return 0;
}

int afm_lcm_cmd_url(const char *url, char *out, size_t len, char *err, size_t errlen) {
    if (!url || !*url) url = getenv("LCM_DEFAULT_URL");
    if (!url || !*url) url = AFM_LCM_DEFAULT_URL;
    return copy(url, out, len, err, errlen);
}

/* udpm://ADDR:PORT[?OPTS] -> udpm://ADDR:PORT+offset[?OPTS]; other providers: cmd_url. */
static int port_plus(const char *cmd_url, int offset, char *out, size_t len, char *err,
                     size_t errlen) {
    static const char udpm[] = "udpm://";
    if (strncmp(cmd_url, udpm, sizeof udpm - 1) != 0) return copy(cmd_url, out, len, err, errlen);
    const char *host = cmd_url + sizeof udpm - 1;
    const char *q = strchr(host, '?');
    size_t hl = q ? (size_t)(q - host) : strlen(host);
    const char *colon = NULL;
    for (const char *c = host; c < host + hl; c++)
        if (*c == ':') colon = c;
    char *end = NULL;
    long port = colon ? strtol(colon + 1, &end, 10) : -1;
    if (!colon || end != host + hl || port < 1 || port > 65535 - AFMTWIN_SAMPLES_PORT_OFFSET) {
        snprintf(err, errlen,
                 "LCM URL '%s': udpm needs ADDR:PORT with a port in 1..%d (the "
                 "outputs go to PORT + %d, the samples to PORT + %d)",
                 cmd_url, 65535 - AFMTWIN_SAMPLES_PORT_OFFSET, AFMTWIN_OUT_PORT_OFFSET,
                 AFMTWIN_SAMPLES_PORT_OFFSET);
        return -1;
    }
    int n = snprintf(out, len, "%s%.*s:%ld%s", udpm, (int)(colon - host), host, port + offset,
                     q ? q : "");
    if (n < 0 || (size_t)n >= len) {
        snprintf(err, errlen, "LCM URL too long");
        return -1;
    }
    return 0;
}

int afm_lcm_out_url(const char *cmd_url, char *out, size_t len, char *err, size_t errlen) {
    return port_plus(cmd_url, AFMTWIN_OUT_PORT_OFFSET, out, len, err, errlen);
}

int afm_lcm_samples_url(const char *cmd_url, char *out, size_t len, char *err, size_t errlen) {
    return port_plus(cmd_url, AFMTWIN_SAMPLES_PORT_OFFSET, out, len, err, errlen);
}

int afm_lcm_urls(const char *url, const char *out_url, char *cmd, char *out, size_t len, char *err,
                 size_t errlen) {
    if (afm_lcm_cmd_url(url, cmd, len, err, errlen)) return -1;
    if (out_url && *out_url) return copy(out_url, out, len, err, errlen);
    return afm_lcm_out_url(cmd, out, len, err, errlen);
}

int afm_lcm_samples_urls(const char *cmd_url, const char *samples_url, char *out, size_t len,
                         char *err, size_t errlen) {
    if (samples_url && *samples_url) return copy(samples_url, out, len, err, errlen);
    return afm_lcm_samples_url(cmd_url, out, len, err, errlen);
}
