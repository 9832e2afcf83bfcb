/* SPDX-License-Identifier: MIT */
/* afm_lcm_wire.h -- LCM messages from untrusted bytes: a length check of the whole wire
 * format before lcm-gen's decoder runs, and a decode that cleans up on every path.
 *
 * Why: lcm-gen's decoders trust the bytes. An array count is used for malloc before it is
 * checked against the message (a negative count becomes a huge size_t), sizeof(T) * count
 * is computed in int and wraps (a samples_t with n = 0x40000010 passes the length check
 * and reads past the buffer), a string length of 0xffffffff ends in a memcpy of SIZE_MAX,
 * string terminators are never checked, and a decode that fails half-way returns without
 * freeing what it allocated (and its cleanup would then free uninitialised pointers).
 *
 * afm_wire_check walks the bytes with the type's layout (generated at build time from
 * the msgtypes/ files by tools/lcm-wire-gen.sh, so it cannot drift from lcm-gen's): fingerprint,
 * every field present, every array count >= 0 and within the bytes left, every string
 * 1..AFM_WIRE_MAX_STRING bytes with exactly one NUL, at its end, and no trailing bytes.
 * Only then does afm_wire_decode call lcm-gen's decoder, which can then neither read out
 * of bounds nor allocate more than a few times the message size. Both are pure (no state),
 * for any thread but the real-time ones (the decoder allocates). */
#ifndef AFM_LCM_WIRE_H
#define AFM_LCM_WIRE_H

#include <stddef.h>
#include <stdint.h>

#define AFM_WIRE_MAX_BYTES (1u << 24) /* larger messages are rejected unread */
#define AFM_WIRE_MAX_STRING 65536     /* bytes of one string, its NUL included */

typedef enum {
    AFM_WIRE_I8,
    AFM_WIRE_I16,
    AFM_WIRE_I32,
    AFM_WIRE_I64,
    AFM_WIRE_F32,
    AFM_WIRE_F64,
    AFM_WIRE_BOOL,
    AFM_WIRE_BYTE,
    AFM_WIRE_STRING
} afm_wire_kind;

typedef struct {
    const char *name;
    afm_wire_kind kind;
    int dim_field; /* >= 0: the element count is that earlier (integer) field's value */
    int dim_const; /* else this many elements (1: a scalar) */
} afm_wire_field;

typedef struct {
    const char *name;            /* "status_t" */
    size_t size;                 /* sizeof the generated struct */
    const afm_wire_field *field; /* in wire order */
    int n_fields;
    int64_t (*fingerprint)(void);
    int (*decode)(const void *buf, int len, void *msg);
    void (*cleanup)(void *msg);
    int (*encode)(void *buf, int len, const void *msg); /* lcm-gen's encoder: bytes or < 0 */
    int (*encoded_size)(const void *msg);
} afm_wire_type;

/* One per struct of msgtypes/ (generated), and all of them, NULL-terminated. */
extern const afm_wire_type afm_wire_control_t, afm_wire_dither_t, afm_wire_harmonics_t,
    afm_wire_param_t, afm_wire_samples_t, afm_wire_setpoint_t, afm_wire_status_t, afm_wire_tick_t,
    afm_wire_tick_done_t, afm_wire_scan_t;
extern const afm_wire_type *const afm_wire_all[];

/* 0 when data[0..len) is exactly one well-formed message of type t; else -1 with the
 * reason, without the type name ("string last_reject has a bad length -1 (1..65536)"). */
int afm_wire_check(const afm_wire_type *t, const void *data, size_t len, char *err, size_t errlen);

/* afm_wire_check, then lcm-gen's decoder into msg (a t->size struct, zeroed first). 0: msg
 * holds the message, release it with afm_wire_free. -1 with the reason: msg holds nothing
 * (whatever the decoder allocated is freed), afm_wire_free is then a harmless no-op. */
int afm_wire_decode(const afm_wire_type *t, const void *data, size_t len, void *msg, char *err,
                    size_t errlen);
void afm_wire_free(const afm_wire_type *t, void *msg);

/* The fingerprint lcm-gen writes into a message's first 8 bytes (len >= 8). */
int64_t afm_wire_fingerprint(const void *data);

#endif
