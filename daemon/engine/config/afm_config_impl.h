/* SPDX-License-Identifier: MIT */
/* afm_config_impl.h -- what the config loader (afm_config.c) and the struct checks
 * (afm_config_check.c) share. Internal: not part of the afm_config.h contract. */
#ifndef AFM_CONFIG_IMPL_H
#define AFM_CONFIG_IMPL_H

#include "config/afm_config.h"

#define AFM_CONFIG_KEY_LEN 128 /* longest config key path, "drive.tones[1].frequency_hz" */

/* Every range/consistency check on c. 0 if valid; else -1 with the failing key's config
 * path in key (AFM_CONFIG_KEY_LEN) and the reason in why. */
int afm_config_check_all(const afm_config *c, char *key, char *why, size_t why_len);

#endif
