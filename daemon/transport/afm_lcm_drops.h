/* SPDX-License-Identifier: MIT */
/* afm_lcm_drops.h -- counting the command messages that LCM drops before any handler sees
 * them, as far as LCM and the kernel let them be seen.
 *
 * Two places lose messages under a flood: (1) LCM's per-subscription queue: when every
 * subscriber of a channel already holds its queue capacity, LCM's receive thread frees the
 * message (lcm_try_enqueue_message returns 0) and counts it nowhere; (2) the kernel: when
 * the UDP socket's receive buffer is full, the datagram is dropped and counted in the
 * socket's drop counter (the last column of /proc/net/udp).
 *
 * (1) LCM 1.3 has no API for it. lcm_try_enqueue_message is an exported function of
 * liblcm that its providers call through the PLT; this file defines the same symbol,
 * which the dynamic linker binds ahead of liblcm's, calls liblcm's own (dlsym
 * RTLD_NEXT) and counts the messages it refused on the channels being watched. A self-test
 * (afm_lcm_drops_visible) says whether the interposition is in effect; if a liblcm is ever
 * built so that it is not, the counts stay 0 and the status says they are not visible.
 * (2) is read from /proc/self/net/udp and udp6 for the sockets LCM opened for the command
 * instance (their inodes, found in /proc/self/fd), bound to the command port. */
#ifndef AFM_LCM_DROPS_H
#define AFM_LCM_DROPS_H

#include <lcm/lcm.h>
#include <stdbool.h>

#define AFM_LCM_DROPS_CHANNELS 8
#define AFM_LCM_DROPS_SOCKETS 8

/* Count LCM's queue drops on channels[0..n) of lcm (n <= AFM_LCM_DROPS_CHANNELS; the
 * strings must outlive the watch). Returns a watch id >= 0, or -1 (all slots taken). */
int afm_lcm_drops_watch(lcm_t *lcm, const char *const *channels, int n);
void afm_lcm_drops_unwatch(int id);
/* Messages LCM dropped on channel i of watch id so far. */
long long afm_lcm_drops_queue(int id, int i);
/* Whether the interposition is in effect (run once; cheap afterwards). */
bool afm_lcm_drops_visible(void);

/* The UDP sockets of this process now (their inodes), for a before/after difference. */
int afm_udp_sockets(unsigned long *inode, int max);
/* Datagrams the kernel dropped on the sockets inode[0..n) bound to local port `port`
 * (1..65535), summed; -1 when /proc cannot be read. */
long long afm_udp_drops(const unsigned long *inode, int n, int port);

#endif
