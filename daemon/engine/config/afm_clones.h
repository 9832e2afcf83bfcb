/* SPDX-License-Identifier: MIT */
/* afm_clones.h -- AFM_CLONES marks the functions that carry the cost per sample: the
 * integrator's loop and out-of-line helpers (afm_rt.c), the output chain's hot loops (the
 * estimators' fast paths, the decimators, the OBD and its noise pool). In a portable build
 * (AFMTWIN_MARCH=portable: -march=x86-64 and AFM_MULTIVERSION) each of them is compiled
 * twice, for the baseline and for x86-64-v3 (AVX2, FMA), and the dynamic loader picks the
 * copy the CPU can run (an ifunc per function: gcc and clang target_clones). Elsewhere it
 * is empty and the whole build targets one -march. README "Portable builds" has the cost of
 * each choice (make bench). The code inside is written with GNU vectors and fma, never
 * with compile-time intrinsics (those would take the baseline's path in both copies): see
 * afm_v4 in estimators/afm_est_internal.h. In the config layer (the lowest) so that every
 * layer can use it. */
#ifndef AFM_CLONES_H
#define AFM_CLONES_H

/* AFM_CLONES_NOINLINE: for a function that must stay out of line; a multiversioned one
 * always is (called through its ifunc), and clang refuses noinline beside target_clones. */
/* clang before 16 names the ifunc "f.ifunc" and leaves "f" undefined for the callers in
 * other files (the link fails): there the portable build is one baseline copy. */
#if defined(AFM_MULTIVERSION) && defined(__x86_64__) && defined(__GNUC__) &&                       \
    (!defined(__clang__) || __clang_major__ >= 16)
#define AFM_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#define AFM_CLONES_NOINLINE AFM_CLONES
#else
#define AFM_CLONES
#define AFM_CLONES_NOINLINE __attribute__((noinline))
#endif

#endif
