/*
 * Times whole stereo frames through the C ABI: `frame_time SCENE FRAMES [THREADS]` renders
 * one warm-up frame and FRAMES measured frames of SCENE at 1280x720 in the default
 * configuration (spatiotemporal, paper order, 1 spp, rasterised compact G-buffers, no
 * budget), the head walking the scene's camera path, and prints the median and minimum
 * frame time measured around stereotrace_pipeline_render_frame. The same frames through
 * Rust are `stereotrace throughput --scene SCENE --frames FRAMES --no-baseline`.
 */
#define _POSIX_C_SOURCE 199309L /* clock_gettime under -std=c11 */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "stereotrace.h"

static int compare(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s SCENE FRAMES [THREADS]\n", argv[0]);
        return 2;
    }
    int frames = atoi(argv[2]);
    if (frames < 1 || frames > 100000) {
        fprintf(stderr, "FRAMES must be in 1..=100000\n");
        return 2;
    }
    StPipelineConfig config = stereotrace_pipeline_config_default();
    config.threads = argc > 3 ? (uint32_t)atoi(argv[3]) : 2;
    StPipeline *p = NULL;
    if (stereotrace_pipeline_create_scene(argv[1], &config, &p) != ST_STATUS_OK) {
        fprintf(stderr, "error: %s\n", stereotrace_last_error());
        return 1;
    }
    double *ms = malloc(sizeof(double) * (size_t)frames);
    for (int i = 0; i <= frames; i++) {
        struct timespec t0, t1;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        if (stereotrace_pipeline_render_frame(p, (uint32_t)i, NULL) != ST_STATUS_OK) {
            fprintf(stderr, "error: %s\n", stereotrace_last_error());
            return 1;
        }
        clock_gettime(CLOCK_MONOTONIC, &t1);
        if (i > 0) ms[i - 1] = (t1.tv_sec - t0.tv_sec) * 1e3 + (t1.tv_nsec - t0.tv_nsec) / 1e6;
    }
    qsort(ms, (size_t)frames, sizeof(double), compare);
    printf("%s: %d frames through the C ABI, median %.2f ms, min %.2f ms\n", argv[1], frames, ms[frames / 2], ms[0]);
    free(ms);
    stereotrace_pipeline_destroy(p);
    return 0;
}
