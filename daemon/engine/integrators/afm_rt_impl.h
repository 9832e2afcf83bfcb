/* SPDX-License-Identifier: MIT */
/* afm_rt_impl.h -- the rt backend's state (tables, the two snapshots a step reads and writes, the
 * thermal bookkeeping), its vector helpers, the drive's tones, and the state to and from
 * struct afm_sim (phasor resync, publish). Shared by both schemes.
 * Private to the rt backend: included once, by afm_rt.c (which is compiled once per CPU copy,
 * AFM_RT_COPY), so its static functions stay in that one translation unit. */
#ifndef AFM_RT_IMPL_H
#define AFM_RT_IMPL_H

#include "forces/afm_rng.h"
#include "integrators/afm_rt_coef.h"
#include "integrators/afm_sim_impl.h"

#include <math.h>
#include <string.h>

#if defined(__FMA__) && defined(__AVX__)
#include <immintrin.h>
#endif

#define RT_GRID 8                  /* table cells per contact substep: crossing resolution */
#define RT_DEFAULT_SUBSTEPS 4      /* substeps per sample in contact (measured, numerics.md) */
#define RT_ACC_DEFAULT_SUBSTEPS 32 /* the accurate scheme's (docs/numerics.md, issue 28) */
/* The accurate scheme redoes a sample in pieces when its path comes within this many
 * travels ((|v0| + |v1|) dt) of the contact line (docs/numerics.md: 0 leaves 0.013 deg and
 * 1.3e-4 of amplitude on probe-q300, 0.5 and more 0.001 deg and 2e-5; with the graded
 * pieces, 0.25 leaves 0.011 deg at 12 MHz, 0.5 0.005 deg as 1.0 does) */
#define RT_ACC_NEAR_TRAVELS 0.5
/* Without thermal noise, a sample near or in contact is taken in this many whole Hermite
 * pieces, and only a piece that crosses the contact line, or has an end in contact within
 * RT_ACC_CLOSE_TRAVELS of its travel (|v| tau) from the line, is redone in its share of the m
 * substeps (m / RT_ACC_NEAR_PIECES; when m is no multiple of it, the whole sample in the m
 * substeps). Callgrind, NCHV tapping: 4500 -> 2700 instructions per sample for the samples
 * near the line, 2320 -> 1370 for those in contact; 4 pieces miss the suite (docs/numerics.md) */
#define RT_ACC_NEAR_PIECES 8
/* Half a travel since issue 29's tenth round (1.0 before): callgrind, bench-states tapping,
 * default.conf 995.2 -> 963.5 instructions per sample, nchv.conf 1120.9 -> 1088.0; the whole
 * suite (AFMTWIN_VALIDATE=full test_rt_steady) 172/0, its figures the same or better (NCHV's
 * energy 0.022 / 0.031 -> 0.0075 / 0.0127 eV, film on / off; docs/numerics.md) */
#ifndef RT_ACC_CLOSE_TRAVELS
#define RT_ACC_CLOSE_TRAVELS 0.5
#endif
/* Two of those pieces are taken as one where both its ends are out of contact, this many of
 * its travels (|v| dt / 4) above the contact line (0: never). Callgrind: default.conf 933 -> 873
 * instructions per sample at 4 travels, 829 at 2 (nchv.conf 1024 -> 963 -> 923), 810 at 1;
 * test_rt_steady 148/0 at each, its worst figures moved least at 2 (docs/numerics.md, third
 * round); merging in contact too NCHV's energy per period missed its bound (0.14 eV) */
#ifndef RT_ACC_MERGE_TRAVELS
#define RT_ACC_MERGE_TRAVELS 2.0
#endif
/* Four of those pieces as one where both its ends are this many of its travels (|v| dt / 2)
 * above the contact line, tried before the pair (0: never). Issue 29, eleventh round: callgrind,
 * bench-states tapping, default.conf 928.4 -> 901.8 instructions per sample, nchv.conf 1047.4 ->
 * 1020.6; the whole suite 172/0, its worst figures within a few per cent of before
 * (docs/numerics.md) */
#ifndef RT_ACC_MERGE4_TRAVELS
#define RT_ACC_MERGE4_TRAVELS 2.0
#endif
/* Two pieces in contact are taken as one where an embedded error estimate allows it
 * (rt_merge_ok_t, issue 29, seventh round): the force law at the long piece's midpoint (the
 * tip there from its ends' x, v, a: quintic Hermite) against the Hermite force's midpoint
 * value, within this many of the Newton tolerance (rt_state.ftol: the force that bends the
 * cantilever by 1 pm). 0: never. Both ends in contact, not close to the line (as
 * RT_ACC_CLOSE_TRAVELS, with the long piece's travel; no trial where the end predicted from
 * the start is), no crossing; its step record's work corrected with that midpoint
 * (rt_ev_merged). At 1: default.conf 1019.5 -> 1023.2 instructions per sample, nchv.conf
 * 1145.9 -> 1178.9, test_rt_steady 148/0 with NCHV's energy 0.031 -> 0.038 eV
 * (docs/numerics.md, seventh round): dearer, so off. */
#ifndef RT_ACC_MERGE_TOL
#define RT_ACC_MERGE_TOL 0.0
#endif
/* The tip-channel (Toeplitz) form of a graded sample (issue 29, ninth round; afm_rt_tc.h): its
 * RT_ACC_NEAR_PIECES Hermite pieces taken as nodes of the tip's response alone (x, v and the
 * acceleration at each node a dot product over the earlier nodes' forces and slopes, weights per
 * model), the modal state formed once from the node forces where a piece is redone in substeps
 * and at the sample's end. Same discretization (the same pieces, no merges: finer where the
 * default merges two out of contact), other rounding. 0: the default's graded pieces. */
#ifndef RT_ACC_TC
#define RT_ACC_TC 0
#endif
#define RT_TC_NODES RT_ACC_NEAR_PIECES
/* the tip-channel form with rt_graded_acc's merges out of contact (an origin reset before each
 * merged pair); 0: every piece a node */
#ifndef RT_ACC_TC_MERGE
#define RT_ACC_TC_MERGE 0
#endif
/* The out-of-contact forces (van der Waals 1 / d^2, capillary, electrostatic) change on the
 * scale of the gap d itself, which is a0 at the contact line, not on the scale of the distance
 * to that line (issue 29, twelfth round). > 0: a merge (RT_ACC_MERGE_TRAVELS,
 * RT_ACC_MERGE4_TRAVELS, which then bound the distance to the line) also needs both its ends
 * this many of its travels above d = 0 (rt_merge_clear); 0: not tested. */
#ifndef RT_ACC_GAP_MERGE
#define RT_ACC_GAP_MERGE 0
#endif
/* With RT_ACC_GAP_MERGE, > 0: a merge that is clear of d = 0 but not of the line (and out of
 * contact) is kept where the embedded estimate (rt_merge_ok_t: the force law at its midpoint
 * against the Hermite force's) agrees within this many Newton tolerances; 0: never. */
#ifndef RT_ACC_GAP_TOL
#define RT_ACC_GAP_TOL 0.0
#endif
#define RT_ACC_SURE 0.999 /* rt_state.sure_k: below 1, so that rounding cannot decide */
#define RT_MAX_SUBSTEPS AFM_MAX_RT_SUBSTEPS
#define RT_RESYNC 4096 /* steps between phasor resynchronisations */
#define RT_NEWTON_MAX 12
#define RT_KB_J_K 1.380649e-23 /* Boltzmann constant (exact, SI 2019) */

/* The tip at the end of a piece and what a full step from there needs of it. The free step
 * carries it in registers from sample to sample (rt_run_t), so that the chain from one force
 * to the next does not go through a store and a load; rt_snap holds the same struct. */
typedef struct {
    double x_m, v_m_s, f_n; /* tip displacement (m), velocity (m/s), tip-sample force (N) */
    /* x*, v*: the tip at the end of a full step from here without the response to that
     * step's end force (m, m/s) */
    double x_free_m, v_free_m_s;
    /* 1 / max(1 - fx gx - fv gv, 1/4) (dimensionless) at the last force evaluation, for a
     * piece of rt_snap.slope_cells cells; in a free-standing rt_tip, for a full step */
    double inv_slope;
    /* x, v and the gap d = x cos(alpha) + Z at the full step's first guess, its end force
     * held at f_n: x_free_m + gx f_n, ... (m, m/s, m) */
    double x_guess_m, v_guess_m_s, gap_guess_m;
} rt_tip;

/* The tip-channel form's tables (afm_rt_tc.h), for tab[1]'s pieces of ncell / RT_TC_NODES cells
 * (on: m a multiple of RT_TC_NODES). A node's force F and slope D = tau dF/dt move the tip at
 * the node l pieces later by w[o][l][0 for F, 1 for D][0 x (m/N), 1 v (m/s/N), 2 acceleration
 * (1/kg)], o = 1 for the origin node (the state the nodes start from: it enters only through
 * the next piece's K0, Gd0 rows), 0 for a later node (K1, Gd1 of its own piece, then K0, Gd0 of
 * the next). m[o][l][F, D][q, v][i]: the same on the modal state. fr[l]: the tip rows of
 * Phi(l tau) on the origin's (qh, qh'): x (q, v), v (q, v), acceleration (q, v). */
typedef struct {
    bool on;
    int k; /* cells per piece */
    double w[2][RT_TC_NODES + 1][2][3];
    double m[2][RT_TC_NODES + 1][2][2][AFM_MAX_MODES] __attribute__((aligned(32)));
    double fr[RT_TC_NODES + 1][6][AFM_MAX_MODES] __attribute__((aligned(32)));
} rt_tc_tab;

/* The state a step reads and writes; two of them so a trial step can be dropped. */
typedef struct {
    double q[AFM_MAX_MODES], v[AFM_MAX_MODES];       /* homogeneous part qh (m), qh' (m/s) */
    double z_re[AFM_MAX_TONES], z_im[AFM_MAX_TONES]; /* e^{i theta_j} */
    rt_tip tip;
    double dfdx_n_m, dfdv_n_s_m; /* df/dx (N/m), df/dv (N s/m) at the last force evaluation */
    int slope_cells;             /* the piece length tip.inv_slope is for, in cells (0: none) */
    double df_per_cell_n;        /* force change per cell over the piece that ended here (N) */
    double fdot_n_s;             /* dF/dt here (N/s): the accurate scheme's Hermite end slope */
    /* the tip's acceleration here (m/s^2), from the state as it ends (rt_ev_acc's sum): kept
     * only by the accurate scheme's pieces taken for the step record (rt_piece_acc_t, rec) */
    double acc_m_s2;
    /* tip.x_free_m, tip.v_free_m_s hold the accurate scheme's next full step's x*, v* (its
     * F0, D0 terms and tones in), as rt_free_acc_t left them: that step chains them from here
     * (block ends do not change the results); every other writer of tip clears it */
    bool acc_free;
} rt_snap;

/* The step tables of one scheme: contact substeps m, ncell = m RT_GRID cells, the
 * coefficients of a piece of k cells at prop[k - 1] (in block), and, once thermal noise was
 * set, its Cholesky factors and bridge gains (rt_state.lth, .bridge). */
typedef struct {
    int m, ncell;
    int drive_tones; /* tones whose drive rows prop holds (zeros past: calloc, then the
                        afm_rt_coef_drive_cells calls) */
    afm_rt_prop *prop;
    double *block, *lth, *bridge;
} rt_tables;

typedef struct {
    int n, np, m, ncell, ntones; /* np: n rounded up to a multiple of 4 */
    double tip[AFM_MAX_MODES];   /* tip_i, zero past n */
    double rot[AFM_MAX_MODES];   /* rot_i (tip rotation per unit q_i), zero past n */
    afm_rt_prop *prop;           /* prop[k - 1]: step of k cells, tau = k dt / ncell */
    double *block;
    rt_snap buf[2];
    int cur;
    double wd[AFM_MAX_TONES];
    double cq_re[AFM_MAX_TONES][AFM_MAX_MODES], cq_im[AFM_MAX_TONES][AFM_MAX_MODES];
    double th_re[AFM_MAX_TONES], th_im[AFM_MAX_TONES]; /* theta = rot . qh + Im(th z) */
    double amp_m[AFM_MAX_TONES]; /* base amplitude of each tone (m); zero past ntones */
    double xc;                   /* tip x at which the gap is a0 */
    double cos_alpha, z_m;       /* d = x cos(alpha) + Z (copies of s->f's and s's) */
    /* A full step's first guess per unit end force of the step before (rt_tip's x_guess_m,
     * v_guess_m_s, gap_guess_m): gx + hx (m/N), gv + hv (m/s/N), (gx + hx) cos(alpha) (m/N) */
    double guess_x_per_n, guess_v_per_n, guess_gap_per_n;
    bool kinked; /* the force has a kink at d = a0 (contact, capillary, electrostatic) */
    double ftol; /* Newton tolerance on F (N) */
    double inv_cells[RT_MAX_SUBSTEPS * RT_GRID + 1]; /* 1 / k */
    double clear_k; /* 4/27 dt: the Hermite path's largest dip per unit end speed */
    /* RT_ACC_SURE (clear_k + RT_ACC_NEAR_TRAVELS dt) (s): a sample that starts within this
     * times |v| of the contact line is certainly taken in pieces (rt_run_acc_t) */
    double sure_k;
    afm_rt_starr starr;
    long since_sync;
    bool noise;   /* thermal force on */
    double *lth;  /* thermal Cholesky factors: step of k cells at lth + 3 np (k - 1) */
    afm_rng *rng; /* its generator (allocated by the first afm_sim_set_thermal) */
    /* Brownian-bridge gains (afm_rt_coef_bridge), 4 np each: a substep's first kc cells
     * (kc = 1 .. RT_GRID - 1), then a substep of the rest of a sample of j substeps
     * (j = 2 .. m); see rt_bridge_gain */
    double *bridge;
    struct rt_noise *nz; /* the increments being split (mutable scratch) */
    /* The accurate scheme (cfg.rt_scheme; rt_run_acc): the force cubic Hermite in time.
     * m, ncell, prop, block, lth and bridge above are tab[acc]'s (rt_use). */
    bool acc;
    rt_tables tab[2]; /* [0] the fast scheme's, [1] the accurate one's */
    /* the tip acceleration: sum_i aq_i qh_i + av_i qh'_i + tip2 F + Im(ax_j z_j) with
     * aq = -tip w^2, av = -2 tip xi w (1/s^2, 1/s; zero past n), tip2 = sum tip^2 (1/kg),
     * ax_j = -wd_j^2 cx_j (m/s^2; zero past ntones) */
    double aq[AFM_MAX_MODES], av[AFM_MAX_MODES], tip2;
    double ax_re[AFM_MAX_TONES], ax_im[AFM_MAX_TONES];
    /* The accurate scheme's free step chained to the next (rt_free_acc_t): the next full step's
     * x*, v* and the tip acceleration its end slope takes, per unit end force F1 and end
     * slope D1 = tau dF/dt of this one, over the part of the modal update that waits for them
     * (afm_rt_coef.h's K1 and Gd1 rows, tab[1]'s full step): x* (m/N, m/N), v* (m/s/N, m/s/N),
     * the acceleration (1/kg, 1/kg) */
    double fa_xf, fa_xd, fa_vf, fa_vd, fa_af, fa_ad;
    /* the tones' steady tip responses cx_j (m), for the drive rows of the tables not in
     * force, which rt_changed leaves stale (drive_stale) until a hand-over needs them */
    double cx_re[AFM_MAX_TONES], cx_im[AFM_MAX_TONES];
    bool drive_stale[2];
    /* The step record's last kept end as the last run with the record left it (rt_run_acc_t,
     * evs): the tip acceleration its last piece formed (m/s^2) at the tip it ended on (m, m/s,
     * N). The next run's first step starts its work from it, as one longer run would have:
     * rt_ev_start's own sum differs in the last bits, and the per-period dissipated energy
     * then depended on where the caller split its runs (replay --block, the daemon's ring
     * items; issue 12: lockstep against replay). ev_a_ok is cleared by everything else that
     * moves or changes the state (rt_run without the record, rt_changed, rt_changed_z,
     * rt_set_scheme, rt_thermal). */
    bool ev_a_ok;
    double ev_a_m_s2, ev_x_m, ev_v_m_s, ev_f_n;
    rt_tc_tab tc; /* the tip-channel form's tables (RT_ACC_TC) */
} rt_state;

/* A redone piece takes the noise already drawn for its interval (issue 11): the increment
 * the next piece must take, the last piece's, and what of a sample's increment its
 * substeps have not taken yet (per mode, on (qh, qh')). */
typedef struct rt_noise {
    double gq[AFM_MAX_MODES], gv[AFM_MAX_MODES]; /* given to the next piece of given_cells */
    int given_cells;                             /* 0: the next piece draws afresh */
    double lq[AFM_MAX_MODES], lv[AFM_MAX_MODES]; /* the last piece's (last_cells) */
    int last_cells;
    double rq[AFM_MAX_MODES], rv[AFM_MAX_MODES]; /* the sample's rest, rem_cells */
    int rem_cells;
    double sq[AFM_MAX_MODES], sv[AFM_MAX_MODES]; /* a substep's rest after its crossing */
} rt_noise;

/* Four modes at a time. GCC/Clang vector extension (plain C would leave it to the
 * auto-vectoriser, which at -O2 turned these loops into memcpy calls and scalar code);
 * aligned(8) and may_alias make loads from any double array legal. */
typedef double rt_v4 __attribute__((vector_size(32), aligned(8), may_alias));
#if !defined(__AVX__) && defined(__GNUC__) && !defined(__clang__)
/* Without AVX, gcc warns that passing rt_v4 by value has another ABI; every such function
 * here is static, so no other object file sees that ABI. */
#pragma GCC diagnostic ignored "-Wpsabi"
#endif
#if !defined(__AVX__) && defined(__clang__) /* the same warning from clang (portable builds) */
#pragma clang diagnostic ignored "-Wpsabi"
#endif
#define RT_V4(p) (*(const rt_v4 *)(const void *)(p))
#define RT_V4W(p) (*(rt_v4 *)(void *)(p))

/* a b + c, rounded once per lane in every build (-std=c11 keeps gcc from contracting
 * anything else): one vfmadd in an x86-64-v3 build; elsewhere lane by lane with
 * __builtin_fma, which gcc and clang fold into one vfmadd in the x86-64-v3 clone of a
 * portable build (AFM_CLONES) and into fmla on arm64, so every copy gives the same bits (the
 * baseline x86-64 copy calls libm's fma: slow, exact). As AFM_V4_FMA of the estimators. */
static inline __attribute__((always_inline)) rt_v4 rt_fma4(rt_v4 a, rt_v4 b, rt_v4 c) {
#if defined(__FMA__) && defined(__AVX__)
    return (rt_v4)_mm256_fmadd_pd((__m256d)a, (__m256d)b, (__m256d)c);
#else
    return (rt_v4){__builtin_fma(a[0], b[0], c[0]), __builtin_fma(a[1], b[1], c[1]),
                   __builtin_fma(a[2], b[2], c[2]), __builtin_fma(a[3], b[3], c[3])};
#endif
}

static inline rt_v4 rt_splat(double x) {
    return (rt_v4){x, x, x, x};
}

static inline double rt_hsum(rt_v4 a) {
    return (a[0] + a[1]) + (a[2] + a[3]);
}

/* rt_hsum of a and b at once (one horizontal add), same rounding. */
static inline void rt_hsum2(rt_v4 a, rt_v4 b, double *sa, double *sb) {
#if defined(__AVX__)
    __m256d t = _mm256_hadd_pd((__m256d)a, (__m256d)b); /* a0+a1, b0+b1, a2+a3, b2+b3 */
    __m128d u = _mm_add_pd(_mm256_castpd256_pd128(t), _mm256_extractf128_pd(t, 1));
    *sa = u[0];
    *sb = u[1];
#else
    *sa = rt_hsum(a);
    *sb = rt_hsum(b);
#endif
}

/* d = x cos(alpha) + Z. */
static inline double rt_gap(const rt_state *r, double x) {
    return fma(x, r->cos_alpha, r->z_m);
}

/* The drive's tones. nt is a constant in every hot copy: 1 (scalar), or RT_TONES_V4 when
 * several tones run: then all AFM_MAX_TONES phasors are rotated and summed as one vector,
 * whatever their number (every per-tone array is zero past ntones: rt_changed,
 * afm_rt_coef_drive_cells, rt_sync_phasors), so four tones cost what one does (a scalar loop over
 * four tones cost +14 ns/sample, the soak's worst state, issue 12). */
#define RT_TONES_V4 AFM_MAX_TONES
_Static_assert(AFM_MAX_TONES == 4, "the tone vector is one rt_v4");

/* The nt of r's tones: 0, 1 or RT_TONES_V4. */
static inline int rt_tones_kind(const rt_state *r) {
    return r->ntones > 1 ? RT_TONES_V4 : r->ntones;
}

/* sum_j Im(c_j z_j) = c_re z_im + c_im z_re over nt tones. */
static inline double rt_tones_im(const double *c_re, const double *c_im, const double *z_re,
                                 const double *z_im, int nt) {
    if (nt == RT_TONES_V4)
        return rt_hsum(rt_fma4(RT_V4(c_re), RT_V4(z_im), RT_V4(c_im) * RT_V4(z_re)));
    if (nt < 1) return 0.0;
    /* from the first tone's term, not 0.0 + it (an add per call; the same value unless that
     * term is -0.0, and then the same once added to a sum) */
    double t = c_re[0] * z_im[0] + c_im[0] * z_re[0];
    for (int j = 1; j < nt; j++)
        t += c_re[j] * z_im[j] + c_im[j] * z_re[j];
    return t;
}

/* o = z rot per tone (complex); o may not be z. */
static inline void rt_tones_rotate(const double *z_re, const double *z_im, const double *rot_re,
                                   const double *rot_im, double *o_re, double *o_im, int nt) {
    if (nt == RT_TONES_V4) {
        rt_v4 zr = RT_V4(z_re), zi = RT_V4(z_im), rr = RT_V4(rot_re), ri = RT_V4(rot_im);
        RT_V4W(o_re) = zr * rr - zi * ri;
        RT_V4W(o_im) = zr * ri + zi * rr;
        return;
    }
    for (int j = 0; j < nt; j++) {
        o_re[j] = z_re[j] * rot_re[j] - z_im[j] * rot_im[j];
        o_im[j] = z_re[j] * rot_im[j] + z_im[j] * rot_re[j];
    }
}

/* A step's phasors stored (o->z_re, o->z_im: after the modal loop, so that in == o is allowed):
 * one vector move each at RT_TONES_V4 tones. */
static inline void rt_tones_store(double *o_re, double *o_im, const double *zr, const double *zi,
                                  int nt) {
    if (nt == RT_TONES_V4) {
        RT_V4W(o_re) = RT_V4(zr);
        RT_V4W(o_im) = RT_V4(zi);
        return;
    }
    for (int j = 0; j < nt; j++) {
        o_re[j] = zr[j];
        o_im[j] = zi[j];
    }
}

/* Phasors exactly from afm_drive at s->t_s. */
static void rt_sync_phasors(const afm_sim *s, rt_state *r, rt_snap *st) {
    for (int j = 0; j < AFM_MAX_TONES; j++)
        st->z_re[j] = st->z_im[j] = 0.0; /* zero past ntones (RT_TONES_V4) */
    for (int j = 0; j < r->ntones; j++) {
        double th = afm_drive_phase_mod(&s->drive, j, s->t_s);
        st->z_re[j] = cos(th);
        st->z_im[j] = sin(th);
    }
    r->since_sync = 0;
}

/* The full state into struct afm_sim: q = qh + sum_j Im(c_j z_j), q' = qh' + sum_j
 * Im(i wd_j c_j z_j), and the tip outputs (be_fills_tip). Once per afm_sim_run. */
static void rt_publish(afm_sim *s, const rt_state *r, const rt_snap *b) {
    for (int i = 0; i < r->n; i++) {
        double q = b->q[i], v = b->v[i];
        for (int j = 0; j < r->ntones; j++) {
            double cr = r->cq_re[j][i], ci = r->cq_im[j][i];
            q += cr * b->z_im[j] + ci * b->z_re[j];
            v += r->wd[j] * (cr * b->z_re[j] - ci * b->z_im[j]);
        }
        s->q[i] = q;
        s->qd[i] = v;
    }
    double u = 0.0;
    for (int j = 0; j < r->ntones; j++)
        u += r->amp_m[j] * b->z_im[j];
    s->f_last_n = b->tip.f_n;
    s->x_last_m = b->tip.x_m;
    s->v_last_m = b->tip.v_m_s;
    s->base_last_m = u;
}

#endif
