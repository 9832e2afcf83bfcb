/* SPDX-License-Identifier: MIT */
/* afm_clones.h -- AFM_CLONES marks the functions that carry the integrator's cost per
 * sample (afm_rt.c: its loop and out-of-line helpers). In a portable build
 * (AFMTWIN_MARCH=portable: -march=x86-64 and AFM_MULTIVERSION) each of them is compiled
 * twice, for the baseline and for x86-64-v3 (AVX2, FMA), and the dynamic loader picks the
 * copy the CPU can run (an ifunc per function: gcc and clang target_clones). Elsewhere it
 * is empty and the whole build targets one -march. README "Portable builds" has the cost of
 * each choice (make bench). Not the output chain: its estimators choose AVX2 intrinsics at
 * compile time (afm_est_internal.h, afm_harm.c), so a clone of them would run their portable
 * fallback (libm fma per lane), measured no faster than the baseline build. */
#ifndef AFM_CLONES_H
#define AFM_CLONES_H

/* AFM_CLONES_NOINLINE: for a function that must stay out of line; a multiversioned one
 * always is (called through its ifunc), and clang refuses noinline beside target_clones. */
#if defined(AFM_MULTIVERSION) && defined(__x86_64__) && defined(__GNUC__)
#define AFM_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#define AFM_CLONES_NOINLINE AFM_CLONES
#else
#define AFM_CLONES
#define AFM_CLONES_NOINLINE __attribute__((noinline))
#endif

#endif
