/*
 * The frame pipeline through the C ABI, two ways:
 *
 * 1. Over stereotrace's own renderer on the built-in Cornell box: a few spatiotemporal
 *    frames at 160x90 on 2 threads, both eyes read back into the program's own (padded)
 *    planes and checked to be finite, non-negative and lit.
 * 2. Over the program's own "renderer" (callbacks): the wall of wall.h, whose G-buffers the
 *    program fills and whose "path-traced" samples are the wall's exact colour. In stereo
 *    mode the library reprojects the right eye into the left and asks the program to trace
 *    only the left pixels whose reprojection was discarded; the program counts them and
 *    checks the left image against the closed form.
 * 3. The same wall sliding sideways under still cameras whose G-buffers are jittered (as
 *    TAA does): the program states the jitter (stereotrace_pipeline_set_jitter), renders
 *    its G-buffers at the jittered positions and gives the wall's motion per pixel
 *    (StGBufferMut.motion). The temporal history then follows the wall onto the unjittered
 *    grid, exactly; without the motion vectors it lags behind.
 * 4. Beyond the paper, on the built-in atrium with a moving light: temporal gradients
 *    (ST_HISTORY_GRADIENT), the variance-guided blend and the à-trous filter, read back
 *    through StFrameStats (gradient samples traced, filter time) and checked finite.
 *
 * Then bad input: an unknown scene, a zero size, a NaN budget, unknown enum values, a
 * missing callback, cameras of the wrong size, the output before any frame, a failing
 * callback (which must leave the output as it was). Each call must return its error code
 * with a message. Built by examples/c/run.sh under AddressSanitizer; exits 0
 * only if every check holds.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stereotrace.h"
#include "check.h"
#include "wall.h"


static void expect(StStatus got, StStatus want, const char *what) {
    const char *message = stereotrace_last_error();
    CHECK(got == want, "%s: status %d, expected %d (%s)", what, got, want, message);
    if (got == want && want != ST_STATUS_OK) printf("refused as expected: %-32s -> %s\n", what, message);
}

/* An RGB image of the program's own, rows padded to `stride`. */
typedef struct {
    uint32_t width, height, stride;
    float *planes[3];
} Image;

static Image image_new(uint32_t width, uint32_t height) {
    Image im = {width, height, width + 5, {NULL, NULL, NULL}};
    for (int c = 0; c < 3; c++) im.planes[c] = calloc((size_t)im.stride * height, sizeof(float));
    return im;
}

static StRgbMut image_view(Image *im) {
    StRgbMut v;
    StPlaneMutF32 *p[3] = {&v.r, &v.g, &v.b};
    for (int c = 0; c < 3; c++) *p[c] = (StPlaneMutF32){im->planes[c], im->width, im->height, im->stride};
    return v;
}

static void image_free(Image *im) {
    for (int c = 0; c < 3; c++) free(im->planes[c]);
}

/* 1. Our renderer on a built-in scene. */
static void scene_pipeline(void) {
    StPipelineConfig config = stereotrace_pipeline_config_default();
    config.width = 160, config.height = 90, config.threads = 2, config.spp = 2;
    StPipeline *p = NULL;
    expect(stereotrace_pipeline_create_scene("cornell", &config, &p), ST_STATUS_OK, "cornell pipeline");
    if (p == NULL) return;
    StFrameStats stats;
    for (uint32_t frame = 0; frame < 3; frame++) {
        expect(stereotrace_pipeline_render_frame(p, frame, &stats), ST_STATUS_OK, "render frame");
        printf("cornell frame %u: %.1f ms (G-buffers %.1f, reprojection %.1f, tracing %.1f), traced %llu + %llu px\n",
               frame, stats.total_ms, stats.gbuffer_ms, stats.reprojection_ms, stats.tracing_ms,
               (unsigned long long)stats.traced_pixels[0], (unsigned long long)stats.traced_pixels[1]);
    }
    CHECK(stats.traced_pixels[1] == 160 * 90, "the right eye traced %llu pixels",
          (unsigned long long)stats.traced_pixels[1]);
    CHECK(stats.traced_pixels[0] < 160 * 90 / 4, "the left eye traced %llu pixels: stereo reprojection did little",
          (unsigned long long)stats.traced_pixels[0]);
    for (uint32_t eye = 0; eye < 2; eye++) {
        Image im = image_new(160, 90);
        StRgbMut view = image_view(&im);
        expect(stereotrace_pipeline_output(p, eye, &view), ST_STATUS_OK, "output");
        double sum = 0;
        int bad = 0;
        for (uint32_t y = 0; y < im.height; y++)
            for (uint32_t x = 0; x < im.width; x++)
                for (int c = 0; c < 3; c++) {
                    float v = im.planes[c][y * im.stride + x];
                    bad += !(v >= 0 && isfinite(v));
                    sum += v;
                }
        CHECK(bad == 0, "eye %u: %d non-finite or negative samples", eye, bad);
        /* The same image lent without a copy (valid until the next render call). */
        StRgb lent;
        expect(stereotrace_pipeline_output_view(p, eye, &lent), ST_STATUS_OK, "output view");
        const StPlaneF32 *lent_planes[3] = {&lent.r, &lent.g, &lent.b};
        int differ = 0;
        for (int c = 0; c < 3; c++)
            for (uint32_t y = 0; y < im.height; y++)
                differ += memcmp(&lent_planes[c]->data[y * lent_planes[c]->stride], &im.planes[c][y * im.stride],
                                 sizeof(float) * im.width) != 0;
        CHECK(differ == 0, "eye %u: %d rows of the lent output differ from the copy", eye, differ);
        CHECK(sum / (160 * 90 * 3) > 0.01, "eye %u is dark: mean %g", eye, sum / (160 * 90 * 3));
        printf("cornell eye %u: mean %.4f\n", eye, sum / (160 * 90 * 3));
        image_free(&im);
    }
    Image wrong = image_new(161, 90);
    StRgbMut view = image_view(&wrong);
    expect(stereotrace_pipeline_output(p, 0, &view), ST_STATUS_INVALID_ARGUMENT, "output of the wrong size");
    expect(stereotrace_pipeline_output(p, 2, &view), ST_STATUS_INVALID_ARGUMENT, "eye 2");
    image_free(&wrong);
    stereotrace_pipeline_destroy(p);
}

/* 2. The program's own renderer behind callbacks. */
enum { CW = 96, CH = 40 };
static const double HALF_BASELINE = 0.3;

typedef struct {
    double centre_x[2];
    uint64_t traced[2];
    int fail_trace;
} Engine;

static int fill_gbuffers(void *user, uint32_t frame, const StGBufferMut *left, const StGBufferMut *right) {
    Engine *e = user;
    (void)frame;
    const StGBufferMut *g[2] = {left, right};
    for (int eye = 0; eye < 2; eye++) {
        const StGBufferMut *b = g[eye];
        if (b->depth.width != CW || b->depth.height != CH) return 1;
        for (int y = 0; y < CH; y++) {
            for (int x = 0; x < CW; x++) {
                size_t i = (size_t)y * b->depth.stride + x;
                float p[3];
                wall_surface(e->centre_x[eye], CW, CH, x, y, p);
                b->depth.data[i] = (float)WALL_DEPTH;
                for (int c = 0; c < 3; c++) b->position[c].data[i] = p[c];
                b->normal[0].data[i] = 0, b->normal[1].data[i] = 0, b->normal[2].data[i] = 1;
                b->normal_octahedral.data[i] = stereotrace_encode_normal(0, 0, 1);
            }
        }
    }
    return 0;
}

static int trace(void *user, uint32_t eye, uint32_t frame, uint32_t spp, const StCamera *camera, const StPlaneU8 *mask,
                 uint32_t row_start, uint32_t row_end, const StRgbMut *out) {
    Engine *e = user;
    (void)frame, (void)spp, (void)camera;
    if (e->fail_trace) return 42;
    for (uint32_t y = row_start; y < row_end; y++) {
        for (uint32_t x = 0; x < CW; x++) {
            if (mask && mask->data[y * mask->stride + x] == 0) continue;
            float p[3], rgb[3];
            wall_surface(e->centre_x[eye], CW, CH, (int)x, (int)y, p);
            wall_colour(p, rgb);
            size_t i = (size_t)y * out->r.stride + x;
            out->r.data[i] = rgb[0], out->g.data[i] = rgb[1], out->b.data[i] = rgb[2];
            e->traced[eye]++;
        }
    }
    return 0;
}

static void callback_pipeline(void) {
    Engine engine = {{-HALF_BASELINE, HALF_BASELINE}, {0, 0}, 0};
    StFrameSourceCallbacks callbacks = {.user = &engine, .fill_gbuffers = fill_gbuffers, .trace = trace};
    StPipelineConfig config = stereotrace_pipeline_config_default();
    config.mode = ST_MODE_STEREO, config.width = CW, config.height = CH, config.threads = 2;
    /* Tolerances for this coarse view: a tap is a source pixel centre up to a pixel (~16 cm
     * of wall) from the surface point, so the room-scale 5 cm default would discard all. */
    StReprojectParams tolerances = stereotrace_reproject_params_default();
    tolerances.position_tolerance = 0.5f;
    config.reprojection = &tolerances;
    StCamera cameras[2] = {wall_camera(-HALF_BASELINE, CW, CH), wall_camera(HALF_BASELINE, CW, CH)};
    StPipeline *p = NULL;
    expect(stereotrace_pipeline_create_callbacks(&callbacks, &config, cameras, &p), ST_STATUS_OK, "callback pipeline");
    if (p == NULL) return;
    Image none = image_new(CW, CH);
    StRgbMut none_view = image_view(&none);
    expect(stereotrace_pipeline_output(p, 0, &none_view), ST_STATUS_INVALID_ARGUMENT, "output before any frame");
    image_free(&none);
    StFrameStats stats;
    expect(stereotrace_pipeline_render_frame_at(p, 0, cameras, &stats), ST_STATUS_OK, "callback frame");
    /* The right eye is traced everywhere; the left only where reprojection was discarded:
     * the columns the right eye cannot see (the wall shifts by `shift` pixels). */
    double shift = wall_shift_pixels(2 * HALF_BASELINE, CW, CH);
    CHECK(engine.traced[1] == (uint64_t)CW * CH, "right eye: %llu pixels traced", (unsigned long long)engine.traced[1]);
    CHECK(engine.traced[0] > 0 && engine.traced[0] <= (uint64_t)ceil(shift + 0.5) * CH,
          "left eye: %llu pixels traced for a %.2f px shift", (unsigned long long)engine.traced[0], shift);
    CHECK(engine.traced[0] == stats.traced_pixels[0], "left eye: the engine traced %llu pixels, the library says %llu",
          (unsigned long long)engine.traced[0], (unsigned long long)stats.traced_pixels[0]);
    Image left = image_new(CW, CH);
    StRgbMut view = image_view(&left);
    expect(stereotrace_pipeline_output(p, 0, &view), ST_STATUS_OK, "left output");
    double worst = 0;
    int border = (int)ceil(shift + 0.5);
    for (int y = 0; y < CH; y++) {
        /* The border column next to the traced ones keeps part of its footprint: its
         * colour is the in-frame taps' average, not the surface's. */
        for (int x = border; x < CW; x++) {
            float q[3], truth[3];
            wall_surface(-HALF_BASELINE, CW, CH, x, y, q);
            wall_colour(q, truth);
            for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(left.planes[c][y * left.stride + x] - truth[c]));
        }
    }
    /* Reprojected pixels interpolate a linear colour: exact to float rounding. */
    CHECK(worst < 2e-4, "left image off the closed form by %g", worst);
    printf("callback stereo frame: right traced %llu px, left traced %llu px (shift %.2f px), worst error %.2e\n",
           (unsigned long long)engine.traced[1], (unsigned long long)engine.traced[0], shift, worst);
    image_free(&left);

    StCamera small[2] = {wall_camera(-HALF_BASELINE, CW - 1, CH), wall_camera(HALF_BASELINE, CW - 1, CH)};
    expect(stereotrace_pipeline_render_frame_at(p, 1, small, NULL), ST_STATUS_INVALID_ARGUMENT,
           "cameras of another size");
    expect(stereotrace_pipeline_render_frame(p, 1, NULL), ST_STATUS_INVALID_ARGUMENT, "frame without a scene");
    /* A failing callback refuses the frame with its own status; the output is the last
     * frame's, untouched (transactional frames). */
    Image before = image_new(CW, CH), after = image_new(CW, CH);
    StRgbMut before_view = image_view(&before), after_view = image_view(&after);
    expect(stereotrace_pipeline_output(p, 0, &before_view), ST_STATUS_OK, "left output before a refused frame");
    engine.fail_trace = 1;
    expect(stereotrace_pipeline_render_frame_at(p, 1, cameras, NULL), ST_STATUS_CALLBACK_FAILED,
           "a failing trace callback");
    expect(stereotrace_pipeline_output(p, 0, &after_view), ST_STATUS_OK, "left output after a refused frame");
    int changed = 0;
    for (int c = 0; c < 3; c++)
        changed += memcmp(before.planes[c], after.planes[c], sizeof(float) * before.stride * CH) != 0;
    CHECK(changed == 0, "a refused frame changed %d planes of the output", changed);
    image_free(&before);
    image_free(&after);
    expect(stereotrace_pipeline_destroy(p), ST_STATUS_OK, "destroy");

    StFrameSourceCallbacks missing = {.user = &engine, .fill_gbuffers = fill_gbuffers};
    p = NULL;
    expect(stereotrace_pipeline_create_callbacks(&missing, &config, cameras, &p), ST_STATUS_NULL_POINTER,
           "missing trace callback");
    CHECK(p == NULL, "a refused create wrote a pipeline");
}

/* 3. A sliding wall: motion vectors and jitter. The wall's colour moves with it (its texture
 * is slid by `offset`), the cameras stay still, and each frame's G-buffers are jittered. */
static const double SLIDE_PER_FRAME = 0.2;

typedef struct {
    double offset;
} SlidingWall;

/* The wall point seen at continuous pixel coordinate (px, py) of the camera at centre_x. */
static void wall_at(double centre_x, double px, double py, float p[3]) {
    double f = 1.0 / tan(WALL_VFOV / 2.0), aspect = (double)CW / CH;
    double ndc_x = px / CW * 2 - 1, ndc_y = 1 - py / CH * 2;
    p[0] = (float)(centre_x + WALL_DEPTH * ndc_x * aspect / f);
    p[1] = (float)(WALL_DEPTH * ndc_y / f);
    p[2] = (float)-WALL_DEPTH;
}

static void sliding_colour(const SlidingWall *w, const float p[3], float rgb[3]) {
    float q[3] = {(float)(p[0] - w->offset), p[1], p[2]};
    wall_colour(q, rgb);
}

static int sliding_gbuffers(void *user, uint32_t frame, const StGBufferMut *left, const StGBufferMut *right) {
    (void)user, (void)frame;
    const StGBufferMut *g[2] = {left, right};
    const double centre[2] = {-HALF_BASELINE, HALF_BASELINE};
    for (int eye = 0; eye < 2; eye++) {
        const StGBufferMut *b = g[eye];
        for (int y = 0; y < CH; y++) {
            for (int x = 0; x < CW; x++) {
                size_t i = (size_t)y * b->depth.stride + x;
                float p[3];
                /* Rendered where the pipeline's jitter puts the pixel's sample. */
                wall_at(centre[eye], x + 0.5 + b->jitter[0], y + 0.5 + b->jitter[1], p);
                b->depth.data[i] = (float)WALL_DEPTH;
                for (int c = 0; c < 3; c++) b->position[c].data[i] = p[c];
                b->normal[0].data[i] = 0, b->normal[1].data[i] = 0, b->normal[2].data[i] = 1;
                /* The wall's motion since the last frame (null planes: not asked for). */
                if (b->motion[0].data) {
                    b->motion[0].data[i] = (float)SLIDE_PER_FRAME;
                    b->motion[1].data[i] = 0, b->motion[2].data[i] = 0;
                }
            }
        }
    }
    return 0;
}

static int sliding_trace(void *user, uint32_t eye, uint32_t frame, uint32_t spp, const StCamera *camera,
                         const StPlaneU8 *mask, uint32_t row_start, uint32_t row_end, const StRgbMut *out) {
    SlidingWall *w = user;
    (void)frame, (void)spp, (void)camera;
    const double centre[2] = {-HALF_BASELINE, HALF_BASELINE};
    for (uint32_t y = row_start; y < row_end; y++) {
        for (uint32_t x = 0; x < CW; x++) {
            if (mask && mask->data[y * mask->stride + x] == 0) continue;
            float p[3], rgb[3];
            wall_at(centre[eye], x + 0.5, y + 0.5, p); /* samples on the unjittered grid */
            sliding_colour(w, p, rgb);
            size_t i = (size_t)y * out->r.stride + x;
            out->r.data[i] = rgb[0], out->g.data[i] = rgb[1], out->b.data[i] = rgb[2];
        }
    }
    return 0;
}

/* An engine's own G-buffer of one eye (full layout, with motion), at a padded stride: what
 * it lends to stereotrace_pipeline_render_frame_lent instead of copying. Planes: depth,
 * position x y z, normal x y z, motion x y z. */
enum { ENGINE_STRIDE = CW + 3, ENGINE_PLANES = 10 };
typedef struct {
    float *plane[ENGINE_PLANES];
} EngineGBuffer;

static EngineGBuffer engine_gbuffer_new(void) {
    EngineGBuffer g;
    for (int k = 0; k < ENGINE_PLANES; k++) g.plane[k] = calloc((size_t)ENGINE_STRIDE * CH, sizeof(float));
    return g;
}

static void engine_gbuffer_free(EngineGBuffer *g) {
    for (int k = 0; k < ENGINE_PLANES; k++) free(g->plane[k]);
}

/* The engine renders its own G-buffers (here by the same code as the callback, through
 * writable views of its own planes) for the pipeline's jitter. */
static void engine_render(EngineGBuffer g[2], const float jitter[2]) {
    StGBufferMut views[2];
    for (int eye = 0; eye < 2; eye++) {
        StPlaneMutF32 planes[ENGINE_PLANES];
        for (int k = 0; k < ENGINE_PLANES; k++)
            planes[k] = (StPlaneMutF32){.data = g[eye].plane[k], .width = CW, .height = CH, .stride = ENGINE_STRIDE};
        views[eye] = (StGBufferMut){.depth = planes[0],
                                    .position = {planes[1], planes[2], planes[3]},
                                    .normal = {planes[4], planes[5], planes[6]},
                                    .motion = {planes[7], planes[8], planes[9]},
                                    .jitter = {jitter[0], jitter[1]}};
    }
    sliding_gbuffers(NULL, 0, &views[0], &views[1]);
}

/* Read-only views of an engine G-buffer, with or without its motion planes. */
static StLentGBuffer engine_lent(const EngineGBuffer *g, int motion_vectors) {
    StPlaneF32 planes[ENGINE_PLANES];
    for (int k = 0; k < ENGINE_PLANES; k++)
        planes[k] = (StPlaneF32){.data = g->plane[k], .width = CW, .height = CH, .stride = ENGINE_STRIDE};
    StLentGBuffer lent = {.depth = planes[0],
                          .position = {planes[1], planes[2], planes[3]},
                          .normal = {planes[4], planes[5], planes[6]}};
    if (motion_vectors) lent.motion[0] = planes[7], lent.motion[1] = planes[8], lent.motion[2] = planes[9];
    return lent;
}

/* The largest error of the left eye's temporal output against the sliding wall's closed
 * form after `frames` frames, away from the columns the wall slides in through. With `lend`
 * the engine lends its own double-buffered G-buffers (zero-copy) instead of filling the
 * pipeline's in the callback. */
static double sliding_error(int motion_vectors, uint32_t frames, int lend) {
    SlidingWall wall = {0};
    StFrameSourceCallbacks callbacks = {.user = &wall, .fill_gbuffers = sliding_gbuffers, .trace = sliding_trace};
    StPipelineConfig config = stereotrace_pipeline_config_default();
    config.mode = ST_MODE_TEMPORAL, config.layout = ST_LAYOUT_FULL, config.width = CW, config.height = CH;
    config.threads = 2, config.motion_vectors = (uint32_t)motion_vectors;
    StReprojectParams tolerances = stereotrace_reproject_params_default();
    tolerances.position_tolerance = 0.5f;
    /* Strict taps: a footprint that leaves the frame restarts the pixel rather than averaging
     * the taps inside, which is not the linear colour at the point (that error would be
     * carried along the slide). */
    tolerances.policy = ST_TAP_POLICY_STRICT;
    config.reprojection = &tolerances;
    StCamera cameras[2] = {wall_camera(-HALF_BASELINE, CW, CH), wall_camera(HALF_BASELINE, CW, CH)};
    StPipeline *p = NULL;
    expect(stereotrace_pipeline_create_callbacks(&callbacks, &config, cameras, &p), ST_STATUS_OK, "sliding wall");
    if (p == NULL) return INFINITY;
    EngineGBuffer engine[2][2] = {{engine_gbuffer_new(), engine_gbuffer_new()},
                                  {engine_gbuffer_new(), engine_gbuffer_new()}};
    for (uint32_t f = 0; f < frames; f++) {
        wall.offset = SLIDE_PER_FRAME * f;
        /* A Halton (2, 3) jitter in [-0.5, 0.5), a new offset every frame. */
        float jitter[2];
        uint32_t base[2] = {2, 3};
        for (int k = 0; k < 2; k++) {
            float fraction = 1, r = 0;
            for (uint32_t i = f + 1; i > 0; i /= base[k]) fraction /= (float)base[k], r += fraction * (float)(i % base[k]);
            jitter[k] = r - 0.5f;
        }
        expect(stereotrace_pipeline_set_jitter(p, jitter[0], jitter[1]), ST_STATUS_OK, "set jitter");
        if (!lend) {
            expect(stereotrace_pipeline_render_frame_at(p, f, cameras, NULL), ST_STATUS_OK, "sliding frame");
            continue;
        }
        /* This frame's G-buffers in one pair of the engine's, last frame's in the other. */
        EngineGBuffer *now = engine[f % 2], *then = engine[(f + 1) % 2];
        engine_render(now, jitter);
        StLentGBuffer current[2] = {engine_lent(&now[0], motion_vectors), engine_lent(&now[1], motion_vectors)};
        StLentGBuffer previous[2] = {engine_lent(&then[0], motion_vectors), engine_lent(&then[1], motion_vectors)};
        if (f > 0) {
            expect(stereotrace_pipeline_render_frame_lent(p, f, cameras, current, NULL, NULL),
                   ST_STATUS_INVALID_ARGUMENT, "a lent frame without last frame's G-buffers");
        }
        expect(stereotrace_pipeline_render_frame_lent(p, f, cameras, current, f > 0 ? previous : NULL, NULL),
               ST_STATUS_OK, "sliding frame, lent G-buffers");
    }
    for (int k = 0; k < 2; k++) engine_gbuffer_free(&engine[k][0]), engine_gbuffer_free(&engine[k][1]);
    Image left = image_new(CW, CH);
    StRgbMut view = image_view(&left);
    expect(stereotrace_pipeline_output(p, 0, &view), ST_STATUS_OK, "sliding output");
    double pixel = wall_shift_pixels(SLIDE_PER_FRAME, CW, CH), worst = 0;
    for (int y = 1; y < CH - 1; y++) {
        for (int x = (int)ceil(pixel) + 2; x < CW - 1; x++) {
            float q[3], truth[3];
            wall_at(-HALF_BASELINE, x + 0.5, y + 0.5, q);
            sliding_colour(&wall, q, truth);
            for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(left.planes[c][y * left.stride + x] - truth[c]));
        }
    }
    image_free(&left);
    expect(stereotrace_pipeline_set_jitter(p, 1.5f, 0), ST_STATUS_INVALID_ARGUMENT, "jitter past a pixel");
    stereotrace_pipeline_destroy(p);
    return worst;
}

static void sliding_wall(void) {
    double with = sliding_error(1, 8, 0), without = sliding_error(0, 8, 0);
    /* Linear colour, exact motion, stated jitter: the history is the closed form. */
    CHECK(with < 2e-4, "with motion vectors the sliding wall is off by %g", with);
    CHECK(without > 100 * with && without > 1e-2, "without motion vectors only %g off", without);
    printf("sliding wall, jittered G-buffers: worst error %.2e with motion vectors, %.2e without\n", with, without);
    /* The engine's own planes lent in place give the same frames as planes filled in. */
    double lent_with = sliding_error(1, 8, 1), lent_without = sliding_error(0, 8, 1);
    CHECK(lent_with == with && lent_without == without, "lent G-buffers: %g and %g, filled: %g and %g", lent_with,
          lent_without, with, without);
    printf("the same with the engine's G-buffers lent (zero-copy): %.2e and %.2e\n", lent_with, lent_without);
}

/* 4. Every setting beyond the paper at once on a scene whose light moves. */
/* Every value both eyes show is finite and not negative. */
static void check_shown_finite(StPipeline *p, const char *what) {
    for (uint32_t eye = 0; eye < 2; eye++) {
        StRgb shown;
        expect(stereotrace_pipeline_output_view(p, eye, &shown), ST_STATUS_OK, "output view");
        const StPlaneF32 *planes[3] = {&shown.r, &shown.g, &shown.b};
        int bad = 0;
        for (int c = 0; c < 3; c++)
            for (uint32_t y = 0; y < shown.r.height; y++)
                for (uint32_t x = 0; x < shown.r.width; x++) {
                    float v = planes[c]->data[y * planes[c]->stride + x];
                    bad += !(v >= 0 && isfinite(v));
                }
        CHECK(bad == 0, "eye %u: %d non-finite or negative %s values", eye, bad, what);
    }
}

static void beyond_the_paper(void) {
    StPipelineConfig config = stereotrace_pipeline_config_default();
    config.mode = ST_MODE_SPATIOTEMPORAL_BLEND, config.width = 64, config.height = 36, config.threads = 2;
    config.history = ST_HISTORY_GRADIENT, config.blend = ST_BLEND_VARIANCE, config.filter = ST_FILTER_ATROUS;
    StPipeline *p = NULL;
    expect(stereotrace_pipeline_create_scene("atrium-moving-light", &config, &p), ST_STATUS_OK, "atrium pipeline");
    if (p == NULL) return;
    StFrameStats stats;
    for (uint32_t frame = 0; frame < 3; frame++)
        expect(stereotrace_pipeline_render_frame(p, frame, &stats), ST_STATUS_OK, "render frame");
    CHECK(stats.gradient_samples[0] > 0 && stats.gradient_samples[1] > 0, "gradient samples %llu + %llu",
          (unsigned long long)stats.gradient_samples[0], (unsigned long long)stats.gradient_samples[1]);
    CHECK(stats.filter_ms > 0, "the filter took %g ms", stats.filter_ms);
    printf("atrium-moving-light frame 2: %llu + %llu gradient samples, %llu + %llu strata changed, filter %.2f ms\n",
           (unsigned long long)stats.gradient_samples[0], (unsigned long long)stats.gradient_samples[1],
           (unsigned long long)stats.gradient_changed[0], (unsigned long long)stats.gradient_changed[1],
           stats.filter_ms);
    check_shown_finite(p, "filtered");
    expect(stereotrace_pipeline_destroy(p), ST_STATUS_OK, "destroy");

    // TAA's neighbourhood clamp instead of the gradients: it moves histories from the second
    // frame on, in the fully traced right eye at least.
    config.mode = ST_MODE_SPATIOTEMPORAL, config.history = ST_HISTORY_CLAMP;
    config.blend = ST_BLEND_FIXED, config.filter = ST_FILTER_NONE;
    p = NULL;
    expect(stereotrace_pipeline_create_scene("atrium", &config, &p), ST_STATUS_OK, "clamp pipeline");
    if (p == NULL) return;
    for (uint32_t frame = 0; frame < 3; frame++)
        expect(stereotrace_pipeline_render_frame(p, frame, &stats), ST_STATUS_OK, "render frame");
    CHECK(stats.history_clamped[1] > 0, "right eye: %llu histories clamped",
          (unsigned long long)stats.history_clamped[1]);
    printf("atrium frame 2: %llu + %llu histories clamped\n", (unsigned long long)stats.history_clamped[0],
           (unsigned long long)stats.history_clamped[1]);
    check_shown_finite(p, "clamped");
    expect(stereotrace_pipeline_destroy(p), ST_STATUS_OK, "destroy");
}

static void bad_configs(void) {
    StPipeline *p = NULL;
    StPipelineConfig c = stereotrace_pipeline_config_default();
    c.width = 64, c.height = 36;
    expect(stereotrace_pipeline_create_scene("no-such-scene", &c, &p), ST_STATUS_INVALID_ARGUMENT, "unknown scene");
    expect(stereotrace_pipeline_create_scene(NULL, &c, &p), ST_STATUS_NULL_POINTER, "null scene");
    StPipelineConfig bad = c;
    bad.width = 0;
    expect(stereotrace_pipeline_create_scene("cornell", &bad, &p), ST_STATUS_INVALID_ARGUMENT, "zero width");
    bad = c, bad.budget_ms = NAN;
    expect(stereotrace_pipeline_create_scene("cornell", &bad, &p), ST_STATUS_INVALID_ARGUMENT, "NaN budget");
    bad = c, bad.mode = 17;
    expect(stereotrace_pipeline_create_scene("cornell", &bad, &p), ST_STATUS_INVALID_ARGUMENT, "unknown mode");
    bad = c, bad.spp = 0;
    expect(stereotrace_pipeline_create_scene("cornell", &bad, &p), ST_STATUS_INVALID_ARGUMENT, "zero spp");
    bad = c, bad.filter = 2;
    expect(stereotrace_pipeline_create_scene("cornell", &bad, &p), ST_STATUS_INVALID_ARGUMENT, "unknown filter");
    expect(stereotrace_pipeline_render_frame(NULL, 0, NULL), ST_STATUS_NULL_POINTER, "null pipeline");
    CHECK(p == NULL, "a refused create wrote a pipeline");
    stereotrace_pipeline_destroy(NULL);
}

int main(void) {
    scene_pipeline();
    callback_pipeline();
    sliding_wall();
    beyond_the_paper();
    bad_configs();
    if (failures) {
        fprintf(stderr, "%d check(s) failed\n", failures);
        return 1;
    }
    printf("all checks passed\n");
    return 0;
}
