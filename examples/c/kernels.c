/*
 * An engine-side C program that runs stereotrace's kernels on its own buffers.
 *
 * The "engine" renders a wall (the plane z = -D, facing the cameras) with a colour that is
 * linear in world position, for both eyes of a parallel stereo rig (60 cm apart, so the
 * right eye misses a few columns the left one sees), into G-buffers of its
 * own (rows padded to a stride wider than the image). It then asks the library to:
 *   1. reproject the right eye's image into the left eye, with the full and the compact
 *      G-buffer layouts;
 *   2. accumulate (EMA) new samples onto the reprojected history;
 *   3. compare two images with SSIM;
 * and checks every answer against what it knows in closed form: bilinear reprojection of a
 * linear colour on a plane gives back that colour exactly (to float rounding), the pixels
 * the right eye cannot see are reported out of frame, SSIM of an image with itself is 1.
 * Last, it feeds the library bad input (null pointers, a stride below the width, a zero
 * size, a NaN camera, a misaligned pointer, an output overlapping an input, an unknown
 * enum value) and checks that each call returns its error code with a message, never
 * crashing. Built by examples/c/run.sh under AddressSanitizer; exits 0 only if every check
 * holds.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stereotrace.h"
#include "check.h"
#include "wall.h"

enum { W = 101, H = 37, STRIDE = W + 3, N = STRIDE * H };
static const double HALF_BASELINE = 0.3;


/* One eye of the engine: camera, G-buffer planes and a colour image. */
typedef struct {
    double centre_x;
    StCamera camera;
    float *depth, *pos[3], *nrm[3], *rgb[3];
    uint32_t *oct;
} Eye;

static float *plane_f32(void) { return calloc(N, sizeof(float)); }

/* The engine's G-buffer pass: the pixel-centre ray of every pixel hits the wall. */
static void render_eye(Eye *e, double centre_x) {
    e->centre_x = centre_x;
    e->camera = wall_camera(centre_x, W, H);
    e->depth = plane_f32();
    e->oct = calloc(N, sizeof(uint32_t));
    for (int c = 0; c < 3; c++) e->pos[c] = plane_f32(), e->nrm[c] = plane_f32(), e->rgb[c] = plane_f32();
    for (int y = 0; y < H; y++) {
        for (int x = 0; x < W; x++) {
            int i = y * STRIDE + x;
            float p[3], rgb[3];
            wall_surface(centre_x, W, H, x, y, p);
            wall_colour(p, rgb);
            e->depth[i] = (float)WALL_DEPTH;
            for (int c = 0; c < 3; c++) e->pos[c][i] = p[c], e->rgb[c][i] = rgb[c];
            e->nrm[0][i] = 0, e->nrm[1][i] = 0, e->nrm[2][i] = 1;
            e->oct[i] = stereotrace_encode_normal(0, 0, 1);
        }
    }
}

static StPlaneF32 view(const float *p) { return (StPlaneF32){p, W, H, STRIDE}; }
static StPlaneMutF32 view_mut(float *p) { return (StPlaneMutF32){p, W, H, STRIDE}; }

static StGBuffer gbuffer(const Eye *e, StLayout layout) {
    StGBuffer g = {.layout = layout, .depth = view(e->depth), .camera = e->camera};
    for (int c = 0; c < 3; c++) g.position[c] = view(e->pos[c]), g.normal[c] = view(e->nrm[c]);
    g.normal_octahedral = (StPlaneU32){e->oct, W, H, STRIDE};
    return g;
}

static StRgb rgb_of(float *const planes[3]) { return (StRgb){view(planes[0]), view(planes[1]), view(planes[2])}; }
static StRgbMut rgb_mut_of(float *planes[3]) {
    return (StRgbMut){view_mut(planes[0]), view_mut(planes[1]), view_mut(planes[2])};
}

static void free_eye(Eye *e) {
    free(e->depth), free(e->oct);
    for (int c = 0; c < 3; c++) free(e->pos[c]), free(e->nrm[c]), free(e->rgb[c]);
}

/* Stereo reprojection right -> left in `layout`; checks it against the closed form. */
static StReasonCounts reproject_and_check(StContext *ctx, Eye *left, Eye *right, StLayout layout, float *out[3],
                                          uint8_t *reason, float *weight) {
    StGBuffer target = gbuffer(left, layout), source = gbuffer(right, layout);
    StReprojectInput in = {.colour = rgb_of(right->rgb), .extra = NULL, .pixel_mask = NULL};
    StPlaneMutF32 weight_view = view_mut(weight);
    StReprojectOutput o = {.colour = rgb_mut_of(out), .extra = NULL,
                           .reason = (StPlaneMutU8){reason, W, H, STRIDE}, .weight = &weight_view};
    StReprojectParams params = stereotrace_reproject_params_default();
    /* A tap is a source pixel centre up to a pixel away from the target's surface point:
     * 15 cm on this coarse 101-pixel view of a wall 5 m away, so the room-scale 5 cm default
     * would discard everything. Tolerances belong to the scene's scale. */
    params.position_tolerance = 0.5f;
    StReasonCounts counts;
    StStatus s = stereotrace_reproject(ctx, &target, &source, &in, &o, &params, &counts);
    CHECK(s == ST_STATUS_OK, "reproject (layout %d): status %d: %s", layout, s, stereotrace_last_error());

    uint64_t total = 0;
    for (int r = 0; r < ST_REASON_COUNT; r++) total += counts.pixels[r];
    CHECK(total == (uint64_t)W * H, "reason counts add up to %llu, not %d", (unsigned long long)total, W * H);
    CHECK(counts.pixels[ST_REASON_OUT_OF_FRAME] > 0, "no pixel of the left border was reported out of frame");
    CHECK(counts.pixels[ST_REASON_REPROJECTED] + counts.pixels[ST_REASON_OUT_OF_FRAME] == (uint64_t)W * H,
          "a pixel of the wall was discarded for another reason");
    /* The right eye sees the wall shifted left by `shift` pixels: the left eye's first
     * columns have no footprint in it (out of frame), the next one only part of one (its
     * accepted weight is below 1 and its colour the in-frame taps' average). Everywhere else
     * the four taps bracket the point and give back the linear colour. */
    double shift = wall_shift_pixels(2 * HALF_BASELINE, W, H);
    int border = (int)ceil(shift + 0.5);
    double worst = 0;
    for (int y = 0; y < H; y++) {
        for (int x = 0; x < W; x++) {
            int i = y * STRIDE + x;
            if (reason[i] != ST_REASON_REPROJECTED) {
                CHECK(x < border, "pixel (%d, %d) not reprojected (reason %d) outside the border", x, y, reason[i]);
                continue;
            }
            if (weight[i] < 1.0f) {
                CHECK(x < border && weight[i] > 0, "partial weight %g at (%d, %d)", weight[i], x, y);
                continue;
            }
            float truth[3], p[3] = {left->pos[0][i], left->pos[1][i], left->pos[2][i]};
            wall_colour(p, truth);
            for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(out[c][i] - truth[c]));
        }
    }
    CHECK(worst < 2e-4, "reprojected colour off the closed form by %g", worst);
    printf("reproject %-7s: %llu reprojected, %llu out of frame (shift %.2f px), worst colour error %.2e\n",
           layout == ST_LAYOUT_FULL ? "full" : "compact", (unsigned long long)counts.pixels[ST_REASON_REPROJECTED],
           (unsigned long long)counts.pixels[ST_REASON_OUT_OF_FRAME], shift, worst);
    return counts;
}

static void expect(StStatus got, StStatus want, const char *what) {
    const char *message = stereotrace_last_error();
    CHECK(got == want, "%s: status %d, expected %d (%s)", what, got, want, message);
    CHECK(message != NULL && (want == ST_STATUS_OK) == (message[0] == '\0'), "%s: message '%s'", what,
          message ? message : "(null)");
    if (got == want && want != ST_STATUS_OK) printf("refused as expected: %-34s -> %s\n", what, message);
}

int main(void) {
    printf("stereotrace %s (header %d.%d.%d)\n", stereotrace_version_string(), STEREOTRACE_VERSION_MAJOR,
           STEREOTRACE_VERSION_MINOR, STEREOTRACE_VERSION_PATCH);
    CHECK(stereotrace_version() == STEREOTRACE_VERSION_MAJOR * 10000 + STEREOTRACE_VERSION_MINOR * 100 +
                                       STEREOTRACE_VERSION_PATCH,
          "library version %u does not match the header", stereotrace_version());

    StContext *ctx = NULL;
    expect(stereotrace_context_create(2, &ctx), ST_STATUS_OK, "context");
    if (ctx == NULL) return 1;

    Eye left, right;
    render_eye(&left, -HALF_BASELINE);
    render_eye(&right, HALF_BASELINE);
    float *out[3] = {plane_f32(), plane_f32(), plane_f32()}, *out2[3] = {plane_f32(), plane_f32(), plane_f32()};
    float *weight = plane_f32();
    uint8_t *reason = calloc(N, 1), *reason2 = calloc(N, 1);

    StReasonCounts full = reproject_and_check(ctx, &left, &right, ST_LAYOUT_FULL, out, reason, weight);
    StReasonCounts compact = reproject_and_check(ctx, &left, &right, ST_LAYOUT_COMPACT, out2, reason2, weight);
    CHECK(memcmp(&full, &compact, sizeof full) == 0, "the two layouts disagree on the reasons");

    /* EMA: the left eye's new samples onto the reprojected history. Expected, per pixel:
     * history + 0.2 * (new - history) where the history was reprojected, the new sample
     * where it was not (a reset). */
    float *history[3] = {plane_f32(), plane_f32(), plane_f32()};
    for (int c = 0; c < 3; c++) memcpy(history[c], out[c], N * sizeof(float));
    StRgb fresh = rgb_of(left.rgb);
    StPlaneU8 reason_view = {reason, W, H, STRIDE};
    StRgbMut accum = rgb_mut_of(out);
    StAccumulateStats ema_stats;
    expect(stereotrace_ema(ctx, &fresh, &reason_view, NULL, NULL, &accum, NULL, NULL, &ema_stats), ST_STATUS_OK, "ema");
    CHECK(ema_stats.resets == full.pixels[ST_REASON_OUT_OF_FRAME], "EMA reset %llu pixels, expected %llu",
          (unsigned long long)ema_stats.resets, (unsigned long long)full.pixels[ST_REASON_OUT_OF_FRAME]);
    double worst = 0;
    for (int y = 0; y < H; y++) {
        for (int x = 0; x < W; x++) {
            int i = y * STRIDE + x;
            for (int c = 0; c < 3; c++) {
                float h = history[c][i], n = left.rgb[c][i];
                float want = reason[i] == ST_REASON_REPROJECTED ? h + 0.2f * (n - h) : n;
                worst = fmax(worst, fabs(out[c][i] - want));
            }
        }
    }
    CHECK(worst < 1e-6, "EMA off its definition by %g", worst);
    printf("ema: %llu resets (the out-of-frame pixels), worst error against the definition %.2e\n",
           (unsigned long long)ema_stats.resets, worst);
    for (int c = 0; c < 3; c++) free(history[c]);

    /* SSIM of an image with itself. */
    StSsimResult ssim;
    expect(stereotrace_ssim(ctx, &fresh, &fresh, ST_SSIM_VARIANT_VOLUME, &ssim), ST_STATUS_OK, "ssim");
    CHECK(ssim.ssim == 1.0 && ssim.rmse == 0.0 && ssim.voxels == 3ull * W * H, "SSIM %g, RMSE %g, %llu voxels",
          ssim.ssim, ssim.rmse, (unsigned long long)ssim.voxels);
    printf("ssim of an image with itself: %.6f over %llu voxels\n", ssim.ssim, (unsigned long long)ssim.voxels);

    /* Bad input: every call refused with its code and a message, nothing written. */
    StGBuffer t = gbuffer(&left, ST_LAYOUT_FULL), s = gbuffer(&right, ST_LAYOUT_FULL);
    StReprojectInput in = {.colour = rgb_of(right.rgb)};
    StReprojectOutput o = {.colour = rgb_mut_of(out), .reason = {reason, W, H, STRIDE}};
    expect(stereotrace_reproject(NULL, &t, &s, &in, &o, NULL, NULL), ST_STATUS_NULL_POINTER, "null context");
    expect(stereotrace_reproject(ctx, &t, NULL, &in, &o, NULL, NULL), ST_STATUS_NULL_POINTER, "null source");
    StGBuffer bad = t;
    bad.depth.data = NULL;
    expect(stereotrace_reproject(ctx, &bad, &s, &in, &o, NULL, NULL), ST_STATUS_NULL_POINTER, "null depth plane");
    bad = t;
    bad.depth.stride = W - 1;
    expect(stereotrace_reproject(ctx, &bad, &s, &in, &o, NULL, NULL), ST_STATUS_INVALID_ARGUMENT,
           "stride below the width");
    bad = t;
    bad.position[1].width = 0;
    expect(stereotrace_reproject(ctx, &bad, &s, &in, &o, NULL, NULL), ST_STATUS_INVALID_ARGUMENT, "zero width");
    bad = t;
    bad.normal[2].height = H - 1;
    expect(stereotrace_reproject(ctx, &bad, &s, &in, &o, NULL, NULL), ST_STATUS_INVALID_ARGUMENT,
           "planes of different sizes");
    bad = s;
    bad.camera.view_proj[5] = NAN;
    expect(stereotrace_reproject(ctx, &t, &bad, &in, &o, NULL, NULL), ST_STATUS_INVALID_ARGUMENT, "NaN camera");
    bad = s;
    memset(bad.camera.view_proj, 0, sizeof bad.camera.view_proj);
    expect(stereotrace_reproject(ctx, &t, &bad, &in, &o, NULL, NULL), ST_STATUS_INVALID_ARGUMENT,
           "singular camera");
    bad = t;
    bad.layout = 7;
    expect(stereotrace_reproject(ctx, &bad, &s, &in, &o, NULL, NULL), ST_STATUS_INVALID_ARGUMENT,
           "unknown layout value");
    bad = t;
    bad.depth.data = (const float *)((const char *)left.depth + 1);
    expect(stereotrace_reproject(ctx, &bad, &s, &in, &o, NULL, NULL), ST_STATUS_MISALIGNED, "misaligned plane");
    StReprojectOutput overlapping = o;
    overlapping.colour.g = view_mut(right.rgb[1]); /* writes over the input it reads */
    expect(stereotrace_reproject(ctx, &t, &s, &in, &overlapping, NULL, NULL), ST_STATUS_ALIASING,
           "output overlapping an input");
    StReprojectParams p = stereotrace_reproject_params_default();
    p.normal_cos = NAN;
    expect(stereotrace_reproject(ctx, &t, &s, &in, &o, &p, NULL), ST_STATUS_INVALID_ARGUMENT, "NaN tolerance");
    StEmaParams ep = stereotrace_ema_params_default();
    ep.alpha = 0;
    expect(stereotrace_ema(ctx, &fresh, &reason_view, NULL, NULL, &accum, NULL, &ep, NULL), ST_STATUS_INVALID_ARGUMENT,
           "EMA alpha 0");
    ep = stereotrace_ema_params_default();
    ep.ramp = 1;
    expect(stereotrace_ema(ctx, &fresh, &reason_view, NULL, NULL, &accum, NULL, &ep, NULL), ST_STATUS_INVALID_ARGUMENT,
           "EMA ramp without a history length");
    expect(stereotrace_ssim(ctx, &fresh, &fresh, 9, &ssim), ST_STATUS_INVALID_ARGUMENT, "unknown SSIM variant");
    expect(stereotrace_ssim(ctx, &fresh, &fresh, ST_SSIM_VARIANT_VOLUME, NULL), ST_STATUS_NULL_POINTER,
           "null SSIM result");
    expect(stereotrace_context_create(2, NULL), ST_STATUS_NULL_POINTER, "context into a null pointer");
    expect(stereotrace_blend(ctx, &fresh, &accum, &reason_view, 0.5f, 0, NULL), ST_STATUS_OK, "blend");

    free_eye(&left), free_eye(&right);
    for (int c = 0; c < 3; c++) free(out[c]), free(out2[c]);
    free(weight), free(reason), free(reason2);
    stereotrace_context_destroy(ctx);
    stereotrace_context_destroy(NULL);
    if (failures) {
        fprintf(stderr, "%d check(s) failed\n", failures);
        return 1;
    }
    printf("all checks passed\n");
    return 0;
}
