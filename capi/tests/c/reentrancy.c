/*
 * One call at a time per pipeline and per context, tested from C as an engine would meet it.
 *
 * 1. From inside each callback (fill_gbuffers, and every trace call) of a frame, every
 *    exported function on the same pipeline (render_frame, render_frame_at,
 *    render_frame_lent, output, output_view, pixels, reset, resize, set_jitter, destroy)
 *    returns ST_STATUS_BUSY with a message naming the call in progress, while a call on
 *    another pipeline and a kernel call on an idle context succeed.
 * 2. From a second thread, while a frame waits inside its callback, the same: every call on
 *    the busy pipeline is refused, calls on another pipeline and an idle context succeed.
 * 3. A context in a kernel call on one thread refuses every kernel call from another thread
 *    (EMA, blend, reprojection, SSIM); the results of the calls that ran are exact.
 *
 * In 1 and 2 every frame's output and statistics equal, bit for bit, those of a twin
 * pipeline that nobody intruded on, in every mode. Built by capi/tests/c/run.sh under
 * AddressSanitizer + UndefinedBehaviorSanitizer and again under ThreadSanitizer; exits 0
 * only if every check holds. Everything the callbacks share with other threads is guarded
 * by a pthread mutex (what a real engine must do too: callbacks run on the pipeline's
 * worker threads).
 */
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "stereotrace.h"
#include "check.h"
#include "wall.h"

enum { W = 48, H = 24, FRAMES = 4 };
static const double HALF_BASELINE = 0.1;

static double centre(uint32_t eye, uint32_t frame) {
    return (eye == 0 ? -HALF_BASELINE : HALF_BASELINE) + 0.02 * frame;
}

static StCamera eye_camera(uint32_t eye, uint32_t frame) {
    return wall_camera(centre(eye, frame), W, H);
}

/* What a callback does besides rendering. */
typedef enum { QUIET, INTRUDE, WAIT_FOR_THREAD } Behaviour;

typedef struct Engine {
    pthread_mutex_t lock;
    pthread_cond_t changed;
    /* Guarded by `lock`. */
    Behaviour behaviour;
    StPipeline *self;     /* the pipeline these callbacks serve */
    StPipeline *other;    /* another pipeline, idle */
    StContext *idle;      /* a context nobody else uses */
    int waits_left;       /* WAIT_FOR_THREAD: callbacks still to wait for the intruder */
    int waiting;          /* a callback waits until the intruder clears this */
    int intrusions;       /* intrusion checks run */
} Engine;

static void engine_init(Engine *e) {
    memset(e, 0, sizeof *e);
    pthread_mutex_init(&e->lock, NULL);
    pthread_cond_init(&e->changed, NULL);
}

static void engine_destroy(Engine *e) {
    pthread_mutex_destroy(&e->lock);
    pthread_cond_destroy(&e->changed);
}

static void expect(StStatus got, StStatus want, const char *what) {
    CHECK(got == want, "%s: status %d, expected %d (%s)", what, got, want, stereotrace_last_error());
}

/* An output image of the pipeline's size. */
typedef struct {
    float planes[3][W * H];
} Image;

static StRgbMut image_view(Image *im) {
    StRgbMut v;
    StPlaneMutF32 *p[3] = {&v.r, &v.g, &v.b};
    for (int c = 0; c < 3; c++) *p[c] = (StPlaneMutF32){im->planes[c], W, H, W};
    return v;
}

/* A small call of each kernel on `context` (kind 0 EMA, 1 blend, 2 reprojection, 3 SSIM),
 * on buffers of the calling thread's own. */
enum { KERNELS = 4 };
static const char *kernel_names[KERNELS] = {"stereotrace_ema", "stereotrace_blend", "stereotrace_reproject",
                                            "stereotrace_ssim"};
static StStatus kernel_call(StContext *context, int kind) {
    static _Thread_local Image accum, fresh, out;
    static _Thread_local uint8_t reasons[W * H];
    static _Thread_local float depth[W * H], position[3][W * H], normal[3][W * H];
    StRgbMut a = image_view(&accum), n = image_view(&fresh);
    StRgb in = {{n.r.data, W, H, W}, {n.g.data, W, H, W}, {n.b.data, W, H, W}};
    StPlaneU8 reason = {reasons, W, H, W};
    switch (kind) {
    case 0:
        return stereotrace_ema(context, &in, &reason, NULL, NULL, &a, NULL, NULL, NULL);
    case 1:
        return stereotrace_blend(context, &in, &a, &reason, 0.5f, 8, NULL);
    case 2: {
        StGBuffer g = {.layout = ST_LAYOUT_FULL, .depth = {depth, W, H, W}, .camera = eye_camera(0, 0)};
        for (int i = 0; i < W * H; i++) {
            float p[3];
            wall_surface(centre(0, 0), W, H, i % W, i / W, p);
            depth[i] = (float)WALL_DEPTH;
            for (int c = 0; c < 3; c++) position[c][i] = p[c], normal[c][i] = c == 2;
        }
        for (int c = 0; c < 3; c++) {
            g.position[c] = (StPlaneF32){position[c], W, H, W};
            g.normal[c] = (StPlaneF32){normal[c], W, H, W};
        }
        StRgbMut o = image_view(&out);
        StReprojectInput input = {.colour = in};
        StReprojectOutput output = {o, NULL, {reasons, W, H, W}, NULL};
        return stereotrace_reproject(context, &g, &g, &input, &output, NULL, NULL);
    }
    default: {
        StSsimResult r;
        return stereotrace_ssim(context, &in, &in, ST_SSIM_VARIANT_PER_CHANNEL, &r);
    }
    }
}

static StStatus small_kernel_call(StContext *context) {
    return kernel_call(context, 0);
}

/*
 * Every exported call on the busy pipeline `self` must be refused with ST_STATUS_BUSY and a
 * message naming `in_progress`; calls on `other` and on the idle context must succeed.
 */
static void intrude(Engine *e, const char *in_progress, const char *from) {
    pthread_mutex_lock(&e->lock);
    StPipeline *self = e->self, *other = e->other;
    StContext *idle = e->idle;
    pthread_mutex_unlock(&e->lock);

    StCamera cameras[2] = {eye_camera(0, 0), eye_camera(1, 0)};
    Image out;
    StRgbMut view = image_view(&out);
    StFrameStats stats;
    struct {
        StStatus status;
        const char *what;
    } calls[10];
    static _Thread_local uint8_t mask[W * H];
    StPlaneMutU8 mask_view = {mask, W, H, W};
    calls[0].status = stereotrace_pipeline_render_frame(self, 0, &stats), calls[0].what = "render_frame";
    calls[1].status = stereotrace_pipeline_render_frame_at(self, 9, cameras, &stats), calls[1].what = "render_frame_at";
    calls[2].status = stereotrace_pipeline_output(self, 0, &view), calls[2].what = "output";
    calls[3].status = stereotrace_pipeline_pixels(self, 0, 2, &mask_view), calls[3].what = "pixels";
    calls[4].status = stereotrace_pipeline_reset(self), calls[4].what = "reset";
    calls[5].status = stereotrace_pipeline_resize(self, W + 1, H), calls[5].what = "resize";
    calls[6].status = stereotrace_pipeline_destroy(self), calls[6].what = "destroy";
    calls[7].status = stereotrace_pipeline_set_jitter(self, 0.25f, 0), calls[7].what = "set_jitter";
    StRgb lent;
    calls[8].status = stereotrace_pipeline_output_view(self, 0, &lent), calls[8].what = "output_view";
    /* Refused as busy before its (here null) G-buffers are looked at. */
    calls[9].status = stereotrace_pipeline_render_frame_lent(self, 9, cameras, NULL, NULL, &stats),
    calls[9].what = "render_frame_lent";
    for (int i = 0; i < 10; i++) {
        CHECK(calls[i].status == ST_STATUS_BUSY, "%s: %s on the busy pipeline returned %d", from, calls[i].what,
              calls[i].status);
    }
    /* The last message names the call that holds the pipeline. */
    CHECK(strstr(stereotrace_last_error(), in_progress) != NULL, "%s: busy message '%s' does not name %s", from,
          stereotrace_last_error(), in_progress);
    if (other) expect(stereotrace_pipeline_render_frame_at(other, 0, cameras, NULL), ST_STATUS_OK, "another pipeline");
    expect(small_kernel_call(idle), ST_STATUS_OK, "an idle context");
    pthread_mutex_lock(&e->lock);
    e->intrusions++;
    pthread_mutex_unlock(&e->lock);
}

/* Runs in each callback: intrude, wait for the intruding thread, or nothing. */
static void on_callback(Engine *e) {
    pthread_mutex_lock(&e->lock);
    Behaviour b = e->behaviour;
    pthread_mutex_unlock(&e->lock);
    if (b == INTRUDE) {
        intrude(e, "stereotrace_pipeline_render_frame_at", "from a callback");
    } else if (b == WAIT_FOR_THREAD) {
        pthread_mutex_lock(&e->lock);
        if (e->waits_left > 0) {
            e->waits_left--;
            e->waiting = 1;
            pthread_cond_broadcast(&e->changed);
            while (e->waiting) pthread_cond_wait(&e->changed, &e->lock);
        }
        pthread_mutex_unlock(&e->lock);
    }
}

static int fill_gbuffers(void *user, uint32_t frame, const StGBufferMut *left, const StGBufferMut *right) {
    Engine *e = user;
    const StGBufferMut *g[2] = {left, right};
    for (uint32_t eye = 0; eye < 2; eye++) {
        const StGBufferMut *b = g[eye];
        for (int y = 0; y < H; y++) {
            for (int x = 0; x < W; x++) {
                size_t i = (size_t)y * b->depth.stride + x;
                float p[3];
                wall_surface(centre(eye, frame), W, H, x, y, p);
                b->depth.data[i] = (float)WALL_DEPTH;
                for (int c = 0; c < 3; c++) b->position[c].data[i] = p[c];
                b->normal[0].data[i] = 0, b->normal[1].data[i] = 0, b->normal[2].data[i] = 1;
                b->normal_octahedral.data[i] = stereotrace_encode_normal(0, 0, 1);
                b->material.data[i] = 0;
            }
        }
    }
    on_callback(e);
    return 0;
}

/* The wall's colour times a noise of (eye, frame, pixel), so accumulation has work to do. */
static int trace(void *user, uint32_t eye, uint32_t frame, uint32_t spp, const StCamera *camera, const StPlaneU8 *mask,
                 uint32_t row_start, uint32_t row_end, const StRgbMut *out) {
    Engine *e = user;
    (void)spp, (void)camera;
    for (uint32_t y = row_start; y < row_end; y++) {
        for (uint32_t x = 0; x < W; x++) {
            if (mask && mask->data[y * mask->stride + x] == 0) continue;
            float p[3], rgb[3];
            wall_surface(centre(eye, frame), W, H, (int)x, (int)y, p);
            wall_colour(p, rgb);
            uint64_t h = ((uint64_t)eye << 56) ^ ((uint64_t)frame << 32) ^ (y * W + x);
            h = (h ^ (h >> 33)) * 0xff51afd7ed558ccdULL;
            float noise = 0.8f + 0.4f * (float)((h >> 40) & 0xffffff) / 16777216.0f;
            size_t i = (size_t)y * out->r.stride + x;
            out->r.data[i] = rgb[0] * noise, out->g.data[i] = rgb[1] * noise, out->b.data[i] = rgb[2] * noise;
        }
    }
    on_callback(e);
    return 0;
}

static StPipeline *make_pipeline(Engine *e, uint32_t mode, uint32_t order) {
    StFrameSourceCallbacks callbacks = {.user = e, .fill_gbuffers = fill_gbuffers, .trace = trace};
    StPipelineConfig config = stereotrace_pipeline_config_default();
    /* One worker: each pipeline's callbacks always run on the same thread. */
    config.mode = mode, config.order = order, config.width = W, config.height = H, config.threads = 1;
    StReprojectParams tolerances = stereotrace_reproject_params_default();
    tolerances.position_tolerance = 0.5f;
    config.reprojection = &tolerances;
    StCamera cameras[2] = {eye_camera(0, 0), eye_camera(1, 0)};
    StPipeline *p = NULL;
    expect(stereotrace_pipeline_create_callbacks(&callbacks, &config, cameras, &p), ST_STATUS_OK, "create");
    return p;
}

typedef struct {
    Image eyes[2];
    StFrameStats stats;
} Frame;

static void render(StPipeline *p, uint32_t frame, Frame *out) {
    StCamera cameras[2] = {eye_camera(0, frame), eye_camera(1, frame)};
    expect(stereotrace_pipeline_render_frame_at(p, frame, cameras, &out->stats), ST_STATUS_OK, "render");
    for (uint32_t eye = 0; eye < 2; eye++) {
        StRgbMut view = image_view(&out->eyes[eye]);
        expect(stereotrace_pipeline_output(p, eye, &view), ST_STATUS_OK, "output");
    }
}

static void same_frame(const Frame *a, const Frame *b, const char *what, uint32_t mode, uint32_t frame) {
    CHECK(memcmp(a->eyes, b->eyes, sizeof a->eyes) == 0, "%s, mode %u, frame %u: the output differs", what, mode,
          frame);
    CHECK(a->stats.traced_pixels[0] == b->stats.traced_pixels[0] &&
              a->stats.traced_pixels[1] == b->stats.traced_pixels[1] && a->stats.budget_met == b->stats.budget_met,
          "%s, mode %u, frame %u: the statistics differ", what, mode, frame);
}

/* The second thread of part 2: each time a callback waits for it, intrudes, then lets the
 * callback go on. */
enum { WAITS = 3 };
static void *intruder(void *arg) {
    Engine *e = arg;
    for (int round = 0; round < WAITS; round++) {
        pthread_mutex_lock(&e->lock);
        while (!e->waiting) pthread_cond_wait(&e->changed, &e->lock);
        pthread_mutex_unlock(&e->lock);
        intrude(e, "stereotrace_pipeline_render_frame_at", "from a second thread");
        pthread_mutex_lock(&e->lock);
        e->waiting = 0;
        pthread_cond_broadcast(&e->changed);
        pthread_mutex_unlock(&e->lock);
    }
    return NULL;
}

static void pipelines(void) {
    uint32_t schedules[8][2] = {{ST_MODE_PATH_TRACED, 0}, {ST_MODE_STEREO, 0}, {ST_MODE_TEMPORAL, 0},
                                {ST_MODE_SPATIOTEMPORAL, 0}, {ST_MODE_SPATIOTEMPORAL, 1}, {ST_MODE_STEREO_BLEND, 0},
                                {ST_MODE_SPATIOTEMPORAL_BLEND, 0}, {ST_MODE_SPATIOTEMPORAL_BLEND, 1}};
    StContext *idle = NULL;
    expect(stereotrace_context_create(1, &idle), ST_STATUS_OK, "idle context");
    Engine quiet;
    engine_init(&quiet);
    StPipeline *other = make_pipeline(&quiet, ST_MODE_STEREO, 0);
    for (int s = 0; s < 8; s++) {
        uint32_t mode = schedules[s][0], order = schedules[s][1];
        /* The twin nobody intrudes on. */
        Engine twin_engine;
        engine_init(&twin_engine);
        StPipeline *twin = make_pipeline(&twin_engine, mode, order);
        static Frame reference[FRAMES], got;
        for (uint32_t f = 0; f < FRAMES; f++) render(twin, f, &reference[f]);

        /* 1. From the callbacks. */
        Engine e;
        engine_init(&e);
        StPipeline *p = make_pipeline(&e, mode, order);
        pthread_mutex_lock(&e.lock);
        e.self = p, e.other = other, e.idle = idle, e.behaviour = INTRUDE;
        pthread_mutex_unlock(&e.lock);
        for (uint32_t f = 0; f < FRAMES; f++) {
            render(p, f, &got);
            same_frame(&got, &reference[f], "intruded from its callbacks", mode, f);
        }
        pthread_mutex_lock(&e.lock);
        CHECK(e.intrusions >= 2 * FRAMES, "mode %u: only %d callbacks intruded", mode, e.intrusions);
        e.behaviour = QUIET;
        pthread_mutex_unlock(&e.lock);
        expect(stereotrace_pipeline_destroy(p), ST_STATUS_OK, "destroy after intrusions");

        /* 2. From a second thread while a callback waits. */
        Engine e2;
        engine_init(&e2);
        StPipeline *p2 = make_pipeline(&e2, mode, order);
        pthread_mutex_lock(&e2.lock);
        e2.self = p2, e2.other = other, e2.idle = idle, e2.behaviour = WAIT_FOR_THREAD, e2.waits_left = WAITS;
        pthread_mutex_unlock(&e2.lock);
        pthread_t thread;
        pthread_create(&thread, NULL, intruder, &e2);
        for (uint32_t f = 0; f < FRAMES; f++) {
            render(p2, f, &got);
            same_frame(&got, &reference[f], "intruded from a second thread", mode, f);
        }
        pthread_join(thread, NULL);
        pthread_mutex_lock(&e2.lock);
        CHECK(e2.intrusions == WAITS, "mode %u: the second thread intruded %d times", mode, e2.intrusions);
        pthread_mutex_unlock(&e2.lock);
        expect(stereotrace_pipeline_destroy(p2), ST_STATUS_OK, "destroy");
        expect(stereotrace_pipeline_destroy(twin), ST_STATUS_OK, "destroy twin");
        engine_destroy(&e), engine_destroy(&e2), engine_destroy(&twin_engine);
        printf("mode %u order %u: callbacks and a second thread refused, frames equal to the twin's\n", mode, order);
    }
    expect(stereotrace_pipeline_destroy(other), ST_STATUS_OK, "destroy other");
    expect(stereotrace_context_destroy(idle), ST_STATUS_OK, "destroy idle context");
    engine_destroy(&quiet);
}

/* 3. A context busy on one thread. */
enum { BIG = 512 };
typedef struct {
    StContext *context;
    pthread_mutex_t lock;
    int stop;             /* guarded by lock */
    int calls, differing; /* SSIM calls after the first that ran, and how many differed; guarded by lock */
} Busy;

static float big_a[3][BIG * BIG], big_b[3][BIG * BIG];

static StRgb big_view(float (*planes)[BIG * BIG]) {
    StRgb v = {{planes[0], BIG, BIG, BIG}, {planes[1], BIG, BIG, BIG}, {planes[2], BIG, BIG, BIG}};
    return v;
}

/* SSIM calls in a loop; a call that finds the context busy with the other thread's call is
 * refused too (and retried): either is fine, anything else is a failure. */
static void *ssim_loop(void *arg) {
    Busy *b = arg;
    StRgb a = big_view(big_a), bb = big_view(big_b);
    StSsimResult first, r;
    int have_first = 0;
    for (;;) {
        pthread_mutex_lock(&b->lock);
        int stop = b->stop;
        pthread_mutex_unlock(&b->lock);
        if (stop) break;
        StStatus s = stereotrace_ssim(b->context, &a, &bb, ST_SSIM_VARIANT_VOLUME, have_first ? &r : &first);
        CHECK(s == ST_STATUS_OK || s == ST_STATUS_BUSY, "ssim in a loop: status %d (%s)", s,
              stereotrace_last_error());
        if (s != ST_STATUS_OK) continue;
        if (have_first) {
            pthread_mutex_lock(&b->lock);
            b->calls++;
            b->differing += memcmp(&r, &first, sizeof r) != 0;
            pthread_mutex_unlock(&b->lock);
        }
        have_first = 1;
    }
    return NULL;
}

static void contexts(void) {
    for (int i = 0; i < BIG * BIG; i++)
        for (int c = 0; c < 3; c++) big_a[c][i] = (float)((i * (c + 3)) % 97) / 97.0f, big_b[c][i] = 0.5f;
    Busy b = {.stop = 0};
    pthread_mutex_init(&b.lock, NULL);
    expect(stereotrace_context_create(1, &b.context), ST_STATUS_OK, "context");
    pthread_t thread;
    pthread_create(&thread, NULL, ssim_loop, &b);
    /* Every kernel, round-robin, until each was refused while the other thread's call ran and
     * that thread's calls kept running, or 60 s. (Whether a call lands inside the other
     * thread's is up to the scheduler: both outcomes are right, anything else is wrong. The
     * destroy of a busy context is checked deterministically in capi/src/lib.rs's tests:
     * here a destroy that won the race would free the context under the other thread.) */
    int busy[KERNELS] = {0}, ok = 0, other = 0, ssim_calls = 0, all_refused = 0;
    time_t start = time(NULL);
    for (int i = 0; (!all_refused || ssim_calls < 3) && time(NULL) - start < 60; i++) {
        pthread_mutex_lock(&b.lock);
        ssim_calls = b.calls;
        pthread_mutex_unlock(&b.lock);
        int kind = i % KERNELS;
        StStatus s = kernel_call(b.context, kind);
        if (s == ST_STATUS_BUSY) {
            busy[kind]++;
            CHECK(strstr(stereotrace_last_error(), "busy in stereotrace_ssim") != NULL, "%s busy message: %s",
                  kernel_names[kind], stereotrace_last_error());
        } else if (s == ST_STATUS_OK) {
            ok++;
        } else {
            other++;
            CHECK(0, "%s on a shared context returned %d (%s)", kernel_names[kind], s, stereotrace_last_error());
        }
        all_refused = busy[0] && busy[1] && busy[2] && busy[3];
    }
    pthread_mutex_lock(&b.lock);
    b.stop = 1;
    pthread_mutex_unlock(&b.lock);
    pthread_join(thread, NULL);
    CHECK(all_refused && b.calls >= 3, "refused: EMA %d, blend %d, reprojection %d, SSIM %d times (its %d calls ran)",
          busy[0], busy[1], busy[2], busy[3], b.calls);
    CHECK(b.differing == 0, "%d of %d SSIM results changed while another thread called in", b.differing, b.calls);
    expect(stereotrace_context_destroy(b.context), ST_STATUS_OK, "destroy an idle context");
    pthread_mutex_destroy(&b.lock);
    printf("context: refused as busy EMA %d, blend %d, reprojection %d, SSIM %d times; %d ran between the other "
           "thread's %d calls\n",
           busy[0], busy[1], busy[2], busy[3], ok, b.calls);
}

int main(void) {
    pipelines();
    contexts();
    if (failures) {
        fprintf(stderr, "%d check(s) failed\n", failures);
        return 1;
    }
    printf("all checks passed\n");
    return 0;
}
