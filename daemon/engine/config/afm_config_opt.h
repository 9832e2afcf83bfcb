/* SPDX-License-Identifier: MIT */
/* afm_config_opt.h -- the loaders of the optional config groups (afm_config_opt.c), called
 * by the loader (afm_config.c) after the groups every config has. Internal to the config
 * layer: not part of afm_config.h. */
#ifndef AFM_CONFIG_OPT_H
#define AFM_CONFIG_OPT_H

#include "config/afm_config.h"
#include "config/afm_config_read.h"

/* Each reads its group of root into c when the group is there (enabled then defaults to
 * true); without the group only c->enabled changes (to false). 0, or -1 with "FILE:LINE: key
 * 'PATH': reason" in L's err. Ranges are not checked here (afm_config_check.c). */
int afm_config_opt_sample(const afm_cfgr *L, const config_setting_t *root, afm_cfg_sample *c);
int afm_config_opt_can(const afm_cfgr *L, const config_setting_t *root, afm_cfg_can *c);
int afm_config_opt_fm(const afm_cfgr *L, const config_setting_t *root, afm_cfg_fm *c);
int afm_config_opt_am(const afm_cfgr *L, const config_setting_t *root, afm_cfg_am *c);

#endif
