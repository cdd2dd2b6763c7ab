/* The trainer's native tile compositor: binning, front-to-back compositing and its backward.
 *
 * The twin of dofview/train/sparse.py in C, for splats that dofview/train/raster.py's project()
 * made in torch (EWA projection, CoC enlargement, energy-normalised opacity, τ-bounded support):
 * this file only sees 2-D splats, in front-to-back order, so the lens math stays written once.
 *
 *   binning   each splat's support box -> the 16x16 tiles it touches; a counting sort by tile
 *             that visits the splats in order keeps every tile's list front to back.
 *   forward   per tile, splat after splat (front to back), over the pixels of the splat's
 *             support ellipse (each row cut to its chord): α = min(α_max, o'·exp(-q/2)),
 *             q = dᵀΣ'⁻¹d, drawn when q <= 9, α >= τ and α > 0, unless it would take the pixel's
 *             transmittance below the early-stop level: then neither it nor anything behind it
 *             is drawn there (the reference 3DGS rule). Keeps T_N and the stop position per pixel.
 *   backward  per tile, the same fragments back to front (the reference backward's walk):
 *             T_i = T_(i+1)/(1 - α_i) from T_N, B = the colour behind, summed as the walk goes,
 *             ∂L/∂α_i = T_i·(c_i·G) - (B·G - g_A·T_N)/(1 - α_i); each (tile, splat) pair's
 *             gradient is summed over its pixels, then the pairs are added up per splat in pair
 *             order, so the result does not depend on the number of threads.
 *
 * Tiles go to threads (POSIX threads taking tiles from an atomic counter: no OpenMP runtime
 * beside torch's, no spin-waiting). REAL is float or double: the file is built once for each.
 * Array shapes are in the comments of struct Splats; every array is C-contiguous.
 */
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <tgmath.h> /* exp, sqrt, ceil, floor of REAL, not of double */

#ifndef REAL
#define REAL float
#endif
typedef REAL real;

typedef struct {
    int64_t count;          /* M splats, front to back */
    const real *mean2d;     /* (M, 2) pixel position of the mean */
    const real *conic;      /* (M, 3) (a, b, c) of Σ'⁻¹ = [[a, b], [b, c]], px⁻² */
    const real *opacity;    /* (M,) normalised opacity o' */
    const real *colour;     /* (M, C) */
    const real *support;    /* (M,) bound r2 on q where α >= τ can hold (<= support_max) */
    const real *lo, *hi;    /* (M, 2) corners of the support box, px */
    int64_t channels, width, height, tile, threads;
    real tau, alpha_max, support_max, early_stop;
    const int64_t *offsets; /* (tiles + 1,) start of each tile's pairs */
    const int32_t *pairs;   /* (P,) splat of each pair, tiles in row-major order, front to back */
} Splats;

static int64_t tiles_x(const Splats *s) { return (s->width + s->tile - 1) / s->tile; }
static int64_t tiles_y(const Splats *s) { return (s->height + s->tile - 1) / s->tile; }

static real clampr(real v, real lo, real hi) { return !(v >= lo) ? lo : (v > hi ? hi : v); } /* NaN -> lo */

/* The pixels whose centre (x + ½, y + ½) lies in splat g's support box: r = (x0, y0, x1, y1),
 * inclusive, clipped to the image; 0 when there are none. */
static int box_pixels(const Splats *s, int64_t g, int64_t r[4]) {
    const real *lo = s->lo + 2 * g, *hi = s->hi + 2 * g;
    if (!(lo[0] <= hi[0] && lo[1] <= hi[1])) return 0; /* also NaN */
    real w = (real)s->width, h = (real)s->height;
    r[0] = (int64_t)ceil(clampr(lo[0] - (real)0.5, -1, w));
    r[1] = (int64_t)ceil(clampr(lo[1] - (real)0.5, -1, h));
    r[2] = (int64_t)floor(clampr(hi[0] - (real)0.5, -1, w));
    r[3] = (int64_t)floor(clampr(hi[1] - (real)0.5, -1, h));
    if (r[0] < 0) r[0] = 0;
    if (r[1] < 0) r[1] = 0;
    if (r[2] > s->width - 1) r[2] = s->width - 1;
    if (r[3] > s->height - 1) r[3] = s->height - 1;
    return r[0] <= r[2] && r[1] <= r[3];
}

/* Count the (tile, splat) pairs: offsets[t] = first pair of tile t, offsets[tiles] = P. */
int64_t dv_bin_count(const Splats *s, int64_t *offsets) {
    int64_t tx = tiles_x(s), n = tx * tiles_y(s), r[4];
    memset(offsets, 0, (size_t)(n + 1) * sizeof *offsets);
    for (int64_t g = 0; g < s->count; g++) {
        if (!box_pixels(s, g, r)) continue;
        for (int64_t ty = r[1] / s->tile; ty <= r[3] / s->tile; ty++)
            for (int64_t t = r[0] / s->tile; t <= r[2] / s->tile; t++) offsets[ty * tx + t + 1]++;
    }
    for (int64_t t = 0; t < n; t++) offsets[t + 1] += offsets[t];
    return offsets[n];
}

/* Fill the pairs counted by dv_bin_count (s->offsets); cursor: (tiles,) scratch. */
void dv_bin_fill(const Splats *s, int32_t *pairs, int64_t *cursor) {
    int64_t tx = tiles_x(s), n = tx * tiles_y(s), r[4];
    memcpy(cursor, s->offsets, (size_t)n * sizeof *cursor);
    for (int64_t g = 0; g < s->count; g++) {
        if (!box_pixels(s, g, r)) continue;
        for (int64_t ty = r[1] / s->tile; ty <= r[3] / s->tile; ty++)
            for (int64_t t = r[0] / s->tile; t <= r[2] / s->tile; t++) pairs[cursor[ty * tx + t]++] = (int32_t)g;
    }
}

/* Splat g's pixels inside tile (x0, y0)..(x1, y1): its box, clipped; 0 when empty. */
static int tile_box(const Splats *s, int64_t g, const int64_t t[4], int64_t r[4]) {
    if (!box_pixels(s, g, r)) return 0;
    if (r[0] < t[0]) r[0] = t[0];
    if (r[1] < t[1]) r[1] = t[1];
    if (r[2] > t[2]) r[2] = t[2];
    if (r[3] > t[3]) r[3] = t[3];
    return r[0] <= r[2] && r[1] <= r[3];
}

/* Row y of splat g cut to the chord of its support ellipse q <= r2, within x in [r0, r2]:
 * a·dx² + 2b·dx·dy + c·dy² <= r2  <=>  |dx + b·dy/a| <= sqrt(a·r2 - (ac - b²)·dy²)/a, with a rim
 * of 10⁻³ px for rounding (the exact test is fragment()'s). */
static void chord(const Splats *s, int64_t g, int64_t y, int64_t x_lo, int64_t x_hi, int64_t *xa, int64_t *xb) {
    const real *cn = s->conic + 3 * g, *m = s->mean2d + 2 * g;
    real a = cn[0], b = cn[1], c = cn[2];
    real dy = (real)y + (real)0.5 - m[1];
    real disc = a * s->support[g] - (a * c - b * b) * dy * dy;
    real half = sqrt(disc > 0 ? disc : 0) / a + (real)1e-3;
    real mid = m[0] - b * dy / a - (real)0.5;
    real lo = clampr(mid - half, (real)x_lo - 1, (real)x_hi + 1), hi = clampr(mid + half, (real)x_lo - 1, (real)x_hi + 1);
    *xa = (int64_t)ceil(lo);
    *xb = (int64_t)floor(hi);
    if (*xa < x_lo) *xa = x_lo;
    if (*xb > x_hi) *xb = x_hi;
}

/* α of splat g at pixel (x, y), 0 where it is not drawn (outside q <= support_max, below τ);
 * also the offset d and the falloff exp(-q/2), 0 where α is clamped (no gradient there). */
static inline real fragment(const Splats *s, int64_t g, int64_t x, int64_t y, real *dx, real *dy, real *falloff) {
    const real *cn = s->conic + 3 * g, *m = s->mean2d + 2 * g;
    real px = (real)x + (real)0.5 - m[0], py = (real)y + (real)0.5 - m[1];
    real q = cn[0] * px * px + 2 * cn[1] * px * py + cn[2] * py * py;
    if (!(q <= s->support_max)) return 0;
    real f = exp((real)-0.5 * q);
    real raw = s->opacity[g] * f;
    real alpha = raw < s->alpha_max ? raw : s->alpha_max;
    if (!(alpha >= s->tau) || !(alpha > 0)) return 0;
    *dx = px;
    *dy = py;
    *falloff = raw < s->alpha_max ? f : 0;
    return alpha;
}

/* ---- threads: each worker takes the next tile until none is left --------------------------- */
typedef struct Job Job;
typedef void (*TileFn)(Job *job, int64_t tile, real *scratch);
struct Job {
    const Splats *s;
    TileFn fn;
    atomic_long next;
    int64_t tiles;
    /* forward */
    real *rgb, *final;
    int32_t *last;
    /* backward */
    const real *grad_rgb, *grad_alpha, *final_in;
    const int32_t *last_in;
    double *pair_grad;
};

static void *worker(void *arg) {
    Job *job = arg;
    int64_t px = job->s->tile * job->s->tile;
    real *scratch = malloc((size_t)(2 * px) * sizeof *scratch);
    if (!scratch) return (void *)1;
    for (;;) {
        int64_t t = atomic_fetch_add(&job->next, 1);
        if (t >= job->tiles) break;
        job->fn(job, t, scratch);
    }
    free(scratch);
    return NULL;
}

/* Run job->fn on every tile with s->threads threads; 0 on success. */
static int run_tiles(Job *job) {
    int64_t n = job->s->threads > 1 ? job->s->threads : 1;
    pthread_t *ids = malloc((size_t)n * sizeof *ids);
    if (!ids) return 1;
    atomic_init(&job->next, 0);
    job->tiles = tiles_x(job->s) * tiles_y(job->s);
    int64_t started = 0;
    for (; started < n - 1; started++)
        if (pthread_create(&ids[started], NULL, worker, job)) break;
    int failed = worker(job) != NULL;
    for (int64_t i = 0; i < started; i++) {
        void *ret;
        pthread_join(ids[i], &ret);
        failed |= ret != NULL;
    }
    free(ids);
    return failed;
}

static void tile_rect(const Splats *s, int64_t tile, int64_t t[4]) {
    int64_t tx = tiles_x(s);
    t[0] = (tile % tx) * s->tile;
    t[1] = (tile / tx) * s->tile;
    t[2] = t[0] + s->tile - 1 < s->width - 1 ? t[0] + s->tile - 1 : s->width - 1;
    t[3] = t[1] + s->tile - 1 < s->height - 1 ? t[1] + s->tile - 1 : s->height - 1;
}

static void forward_tile(Job *job, int64_t tile, real *trans) {
    const Splats *s = job->s;
    int64_t t[4], r[4], C = s->channels, W = s->width;
    tile_rect(s, tile, t);
    int64_t begin = s->offsets[tile], n = s->offsets[tile + 1] - begin;
    int64_t tw = t[2] - t[0] + 1, left = tw * (t[3] - t[1] + 1);
    for (int64_t y = t[1]; y <= t[3]; y++)
        for (int64_t x = t[0]; x <= t[2]; x++) {
            trans[(y - t[1]) * tw + x - t[0]] = 1;
            job->last[y * W + x] = (int32_t)n;
        }
    for (int64_t k = 0; k < n && left > 0; k++) {
        int64_t g = s->pairs[begin + k];
        if (!tile_box(s, g, t, r)) continue;
        const real *col = s->colour + g * C;
        for (int64_t y = r[1]; y <= r[3]; y++) {
            int64_t xa, xb;
            chord(s, g, y, r[0], r[2], &xa, &xb);
            for (int64_t x = xa; x <= xb; x++) {
                int64_t p = y * W + x;
                if (job->last[p] != n) continue; /* stopped */
                real dx, dy, f;
                real alpha = fragment(s, g, x, y, &dx, &dy, &f);
                if (!(alpha > 0)) continue;
                real *T = trans + (y - t[1]) * tw + x - t[0];
                real after = *T * (1 - alpha);
                if (after < s->early_stop) {
                    job->last[p] = (int32_t)k;
                    left--;
                    continue;
                }
                real w = alpha * *T;
                for (int64_t c = 0; c < C; c++) job->rgb[p * C + c] += w * col[c];
                *T = after;
            }
        }
    }
    for (int64_t y = t[1]; y <= t[3]; y++)
        for (int64_t x = t[0]; x <= t[2]; x++) job->final[y * W + x] = trans[(y - t[1]) * tw + x - t[0]];
}

/* Forward: rgb (H·W, C) += the composite (zeroed by the caller), final (H·W,) T_N, last (H·W,)
 * the position in the pixel's tile list where early stop struck (the list length if it did not).
 * Returns 0, or 1 when memory or threads ran out. */
int dv_forward(const Splats *s, real *rgb, real *final, int32_t *last) {
    Job job = {.s = s, .fn = forward_tile, .rgb = rgb, .final = final, .last = last};
    return run_tiles(&job);
}

#define PAIR_GRAD(C) (6 + (C)) /* ∂ mean (2), conic (3), opacity (1), colour (C) */
#define MAX_CHANNELS 16       /* colour channels a splat may have (native.py checks) */

static void backward_tile(Job *job, int64_t tile, real *scratch) {
    const Splats *s = job->s;
    int64_t t[4], r[4], C = s->channels, W = s->width;
    tile_rect(s, tile, t);
    int64_t begin = s->offsets[tile], n = s->offsets[tile + 1] - begin;
    int64_t tw = t[2] - t[0] + 1, px = s->tile * s->tile;
    real *restrict trans = scratch, *restrict behind = scratch + px; /* T_(i+1), and B·G behind */
    const real *restrict grad_rgb = job->grad_rgb, *restrict grad_alpha = job->grad_alpha;
    const real *restrict final = job->final_in;
    const int32_t *restrict last = job->last_in;
    for (int64_t y = t[1]; y <= t[3]; y++)
        for (int64_t x = t[0]; x <= t[2]; x++) {
            trans[(y - t[1]) * tw + x - t[0]] = final[y * W + x];
            behind[(y - t[1]) * tw + x - t[0]] = 0;
        }
    for (int64_t k = n - 1; k >= 0; k--) {
        int64_t g = s->pairs[begin + k];
        if (!tile_box(s, g, t, r)) continue;
        const real *col = s->colour + g * C, *cn = s->conic + 3 * g;
        real o = s->opacity[g];
        /* this pair's sums, in locals (registers) rather than through the pair_grad pointer */
        double d_mx = 0, d_my = 0, d_a = 0, d_b = 0, d_c = 0, d_o = 0, d_col[MAX_CHANNELS] = {0};
        for (int64_t y = r[1]; y <= r[3]; y++) {
            int64_t xa, xb;
            chord(s, g, y, r[0], r[2], &xa, &xb);
            for (int64_t x = xa; x <= xb; x++) {
                int64_t p = y * W + x;
                if (k >= last[p]) continue; /* not drawn: early stop */
                real dx, dy, f;
                real alpha = fragment(s, g, x, y, &dx, &dy, &f);
                if (!(alpha > 0)) continue;
                int64_t l = (y - t[1]) * tw + x - t[0];
                real inv = 1 / (1 - alpha), T = trans[l] * inv, w = alpha * T, cg = 0;
                const real *G = grad_rgb + p * C;
                for (int64_t c = 0; c < C; c++) {
                    cg += col[c] * G[c];
                    d_col[c] += w * G[c];
                }
                real d_alpha = T * cg - (behind[l] - grad_alpha[p] * final[p]) * inv;
                behind[l] += cg * w;
                trans[l] = T;
                if (f > 0) {
                    real d_q = (real)-0.5 * d_alpha * f * o;
                    d_mx += -2 * d_q * (cn[0] * dx + cn[1] * dy);
                    d_my += -2 * d_q * (cn[1] * dx + cn[2] * dy);
                    d_a += d_q * dx * dx;
                    d_b += 2 * d_q * dx * dy;
                    d_c += d_q * dy * dy;
                    d_o += d_alpha * f;
                }
            }
        }
        double *acc = job->pair_grad + (begin + k) * PAIR_GRAD(C);
        acc[0] = d_mx, acc[1] = d_my, acc[2] = d_a, acc[3] = d_b, acc[4] = d_c, acc[5] = d_o;
        for (int64_t c = 0; c < C; c++) acc[6 + c] = d_col[c];
    }
}

/* Backward of dv_forward: gradients of the loss w.r.t. mean2d (M, 2), conic (M, 3), opacity (M,)
 * and colour (M, C) added to the zeroed arrays given, from grad_rgb (H·W, C) and grad_alpha
 * (H·W,) of alpha = 1 - T_N. Returns 0, or 1 when memory or threads ran out. */
int dv_backward(const Splats *s, const real *grad_rgb, const real *grad_alpha, const real *final,
                const int32_t *last, real *g_mean, real *g_conic, real *g_opacity, real *g_colour) {
    int64_t C = s->channels, pairs = s->offsets[tiles_x(s) * tiles_y(s)];
    double *pair_grad = calloc((size_t)(pairs > 0 ? pairs : 1) * PAIR_GRAD(C), sizeof *pair_grad);
    if (!pair_grad) return 1;
    Job job = {.s = s, .fn = backward_tile, .grad_rgb = grad_rgb, .grad_alpha = grad_alpha,
               .final_in = final, .last_in = last, .pair_grad = pair_grad};
    int failed = run_tiles(&job);
    for (int64_t i = 0; i < pairs && !failed; i++) {
        int64_t g = s->pairs[i];
        const double *acc = pair_grad + i * PAIR_GRAD(C);
        g_mean[2 * g] += (real)acc[0];
        g_mean[2 * g + 1] += (real)acc[1];
        for (int j = 0; j < 3; j++) g_conic[3 * g + j] += (real)acc[2 + j];
        g_opacity[g] += (real)acc[5];
        for (int64_t c = 0; c < C; c++) g_colour[g * C + c] += (real)acc[6 + c];
    }
    free(pair_grad);
    return failed;
}
