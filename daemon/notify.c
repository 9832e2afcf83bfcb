/* SPDX-License-Identifier: MIT */
/* notify.c -- systemd notifications (READY, STATUS, WATCHDOG, STOPPING); sd_notify does
 * nothing when NOTIFY_SOCKET is unset, i.e. outside systemd. */
#include "twind.h"

#include <stdio.h>
#include <systemd/sd-daemon.h>

void twind_notify_ready(void) {
    sd_notify(0, "READY=1");
}

void twind_notify_status(const char *text) {
    char buf[512];
    snprintf(buf, sizeof buf, "STATUS=%s", text);
    sd_notify(0, buf);
}

void twind_notify_watchdog(void) {
    sd_notify(0, "WATCHDOG=1");
}

void twind_notify_stopping(void) {
    sd_notify(0, "STOPPING=1");
}
