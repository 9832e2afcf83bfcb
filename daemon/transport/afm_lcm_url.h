/* SPDX-License-Identifier: MIT */
/* afm_lcm_url.h -- the daemon's three LCM URLs (msgtypes/afmtwin_lcm_layout.h): commands on
 * one (the --lcm-url every tool shares), harmonics, status and tick_done on another, the
 * high-rate sample stream on a third, so that the command socket carries commands only and
 * a subscriber of the status is not flooded by the samples. With udpm the output URL is the
 * command URL with the port + 1, the samples URL with the port + 2 (same group, same
 * options); other providers (memq, file) use the same URL for all. */
#ifndef AFM_LCM_URL_H
#define AFM_LCM_URL_H

#include "afmtwin_lcm_layout.h"

#include <stddef.h>

#define AFM_LCM_DEFAULT_URL AFMTWIN_DEFAULT_URL /* LCM's own default */
#define AFM_LCM_URL_LEN 512

/* The command URL: url if given, else $LCM_DEFAULT_URL if set, else AFM_LCM_DEFAULT_URL.
 * 0, or -1 with err (too long). */
int afm_lcm_cmd_url(const char *url, char *out, size_t len, char *err, size_t errlen);

/* The output URL for the (resolved) command URL: udpm://ADDR:PORT[?OPTS] ->
 * udpm://ADDR:PORT+1[?OPTS]; any other provider: cmd_url itself. 0, or -1 with err (a
 * udpm URL without a port in 1..65533). */
int afm_lcm_out_url(const char *cmd_url, char *out, size_t len, char *err, size_t errlen);
/* The same for the sample stream: PORT+2. */
int afm_lcm_samples_url(const char *cmd_url, char *out, size_t len, char *err, size_t errlen);

/* Both at once: out_url given -> taken as it is; else derived. */
int afm_lcm_urls(const char *url, const char *out_url, char *cmd, char *out, size_t len, char *err,
                 size_t errlen);
/* The samples URL for the resolved command URL: samples_url if given, else derived. */
int afm_lcm_samples_urls(const char *cmd_url, const char *samples_url, char *out, size_t len,
                         char *err, size_t errlen);

#endif
