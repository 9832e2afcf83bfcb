/* SPDX-License-Identifier: MIT */
/* afm_lcm_wire.c -- the wire-format check before lcm-gen's decoders (contract in
 * afm_lcm_wire.h). The layouts are generated (tools/lcm-wire-gen.sh); this walks them. */
#include "transport/afm_lcm_wire.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#define MAX_FIELDS 128 /* fields per type (status_t has 65 since issue 18) */

static int fail(char *err, size_t errlen, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static int fail(char *err, size_t errlen, const char *fmt, ...) {
    if (err && errlen) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err, errlen, fmt, ap);
        va_end(ap);
    }
    return -1;
}

static uint64_t be(const unsigned char *b, int n) {
    uint64_t v = 0;
    for (int i = 0; i < n; i++)
        v = v << 8 | b[i];
    return v;
}

int64_t afm_wire_fingerprint(const void *data) {
    return (int64_t)be(data, 8);
}

static size_t elem_size(afm_wire_kind k) {
    switch (k) {
    case AFM_WIRE_I8:
    case AFM_WIRE_BOOL:
    case AFM_WIRE_BYTE:
        return 1;
    case AFM_WIRE_I16:
        return 2;
    case AFM_WIRE_I32:
    case AFM_WIRE_F32:
        return 4;
    case AFM_WIRE_I64:
    case AFM_WIRE_F64:
        return 8;
    case AFM_WIRE_STRING:
        break;
    }
    return 0;
}

/* A signed integer scalar of n bytes (the count of a later array). */
static int64_t sval(const unsigned char *b, int n) {
    uint64_t v = be(b, n);
    if (n < 8 && (v >> (8 * n - 1)) & 1u) v |= ~(uint64_t)0 << (8 * n);
    return (int64_t)v;
}

int afm_wire_check(const afm_wire_type *t, const void *data, size_t len, char *err, size_t errlen) {
    const unsigned char *b = data;
    if (!t || t->n_fields > MAX_FIELDS) return fail(err, errlen, "no message type");
    if (!data || len < 8)
        return fail(err, errlen, "truncated message (%zu bytes, no fingerprint)", len);
    if (len > AFM_WIRE_MAX_BYTES)
        return fail(err, errlen, "message too large (%zu bytes, at most %u)", len,
                    AFM_WIRE_MAX_BYTES);
    int64_t fp = afm_wire_fingerprint(b);
    if (fp != t->fingerprint())
        return fail(err, errlen, "wrong message type (fingerprint %016llx, not %s's)",
                    (unsigned long long)fp, t->name);
    int64_t val[MAX_FIELDS]; /* integer scalars, for the array counts that follow */
    size_t pos = 8;
    for (int i = 0; i < t->n_fields; i++) {
        const afm_wire_field *f = &t->field[i];
        int64_t count = f->dim_field >= 0 ? val[f->dim_field] : f->dim_const;
        if (count < 0)
            return fail(err, errlen, "array %s has a negative count %lld (from %s)", f->name,
                        (long long)count, t->field[f->dim_field].name);
        size_t left = len - pos, es = elem_size(f->kind);
        if (es) {
            if ((uint64_t)count > left / es)
                return fail(err, errlen, "truncated at %s (%lld x %zu bytes, %zu left of %zu)",
                            f->name, (long long)count, es, left, len);
            if (f->dim_field < 0 && f->dim_const == 1) val[i] = sval(b + pos, (int)es);
            pos += (size_t)count * es;
            continue;
        }
        for (int64_t k = 0; k < count; k++) { /* strings: int32 length (with NUL), bytes */
            if (len - pos < 4)
                return fail(err, errlen, "truncated at string %s (%zu bytes)", f->name, len);
            int64_t l = sval(b + pos, 4);
            pos += 4;
            if (l < 1 || l > AFM_WIRE_MAX_STRING)
                return fail(err, errlen, "string %s has a bad length %lld (1..%d)", f->name,
                            (long long)l, AFM_WIRE_MAX_STRING);
            if ((uint64_t)l > len - pos)
                return fail(err, errlen, "truncated in string %s (%lld bytes, %zu left)", f->name,
                            (long long)l, len - pos);
            if (b[pos + (size_t)l - 1] != 0 || memchr(b + pos, 0, (size_t)l - 1))
                return fail(err, errlen, "string %s is not a proper string (one NUL, at its end)",
                            f->name);
            pos += (size_t)l;
        }
    }
    if (pos != len) return fail(err, errlen, "%zu trailing bytes after the message", len - pos);
    return 0;
}

int afm_wire_decode(const afm_wire_type *t, const void *data, size_t len, void *msg, char *err,
                    size_t errlen) {
    if (!t || !msg) return fail(err, errlen, "no message type or buffer");
    memset(msg, 0, t->size);
    if (afm_wire_check(t, data, len, err, errlen)) return -1;
    int used = t->decode(data, (int)len, msg);
    if (used != (int)len) { /* out of memory (the layout was checked) */
        t->cleanup(msg);
        memset(msg, 0, t->size);
        return fail(err, errlen, "the decoder failed (%d of %zu bytes; out of memory?)", used, len);
    }
    return 0;
}

void afm_wire_free(const afm_wire_type *t, void *msg) {
    if (!t || !msg) return;
    t->cleanup(msg);
    memset(msg, 0, t->size);
}
