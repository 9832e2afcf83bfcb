/* SPDX-License-Identifier: MIT */
/* afm_lcm_log.h -- reading LCM log files (lcm-logger's format) that may come from
 * anywhere: every event header is checked before anything is allocated for it.
 *
 * Why not liblcm's lcm_eventlog_read_next_event: it callocs whatever the header's
 * datalen says and freads into the result unchecked (datalen 0x7fffffff: calloc fails,
 * fread writes to NULL), so `afmtwin replay` and `listen --log` crashed on a crafted log.
 * Writing logs stays with liblcm (lcm_eventlog_write_event): the format is its.
 *
 * The format: per event, big-endian, a sync word 0xEDA1DA01, int64 event number, int64
 * time stamp (us), int32 channel length, int32 data length, the channel bytes (no NUL),
 * the data bytes. Checked for every event, before the buffer grows: channel length in
 * 1..AFM_LCM_LOG_MAX_CHANNEL, data length in 0..max_data and not past the end of the file.
 * Bytes before a sync word are skipped, as liblcm does, but counted (skipped_bytes). One
 * buffer per reader, grown to the largest event read: no allocation per event. */
#ifndef AFM_LCM_LOG_H
#define AFM_LCM_LOG_H

#include <stdint.h>
#include <stdio.h>

#define AFM_LCM_LOG_MAX_CHANNEL 256 /* LCM's own limit is 63 */

typedef struct afm_lcm_log afm_lcm_log;

typedef struct {
    int64_t eventnum;
    int64_t timestamp;   /* us, as the logger wrote it (any value: callers check) */
    const char *channel; /* NUL-terminated (a NUL inside the name is rejected) */
    const uint8_t *data;
    uint32_t datalen;
    long long offset; /* byte offset of the event's sync word in the file */
} afm_lcm_log_event;

/* Open path for reading. max_data: largest data length accepted (0: 16 MiB). NULL with
 * err (cannot open, a directory). */
afm_lcm_log *afm_lcm_log_open(const char *path, uint32_t max_data, char *err, size_t errlen);
/* The same on an open stream (read from its current position; it is closed with the reader).
 * For tests and fuzzing (fmemopen). */
afm_lcm_log *afm_lcm_log_from_file(FILE *f, uint32_t max_data, char *err, size_t errlen);

/* The next event into *ev (valid until the next call). 1: an event; 0: the end of the log;
 * -1: a bad or truncated event, with the reason and its offset in err; the reader stays at
 * the end (further calls return 0). */
int afm_lcm_log_next(afm_lcm_log *l, afm_lcm_log_event *ev, char *err, size_t errlen);

/* 1 when channel ends with suffix (the channel's kind without the daemon's --prefix:
 * "AFMTWIN_HARMONICS" and "LAB2_HARMONICS" both end with "HARMONICS"), else 0. */
int afm_lcm_log_channel_is(const char *channel, const char *suffix);

/* Bytes skipped so far while looking for a sync word (junk between events). */
long long afm_lcm_log_skipped(const afm_lcm_log *l);

void afm_lcm_log_close(afm_lcm_log **l);

#endif
