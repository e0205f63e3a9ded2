/*
 * The examples' "engine scene": a wall (the plane z = -WALL_DEPTH, facing the cameras) with a
 * colour linear in world position, seen by pinhole cameras looking down -z from (x, 0, 0).
 * Everything about it is known in closed form, which is what the examples check the library
 * against.
 */
#ifndef STEREOTRACE_EXAMPLE_WALL_H
#define STEREOTRACE_EXAMPLE_WALL_H

#include <math.h>
#include <stdint.h>

#include "stereotrace.h"

static const double WALL_DEPTH = 5.0, WALL_VFOV = 1.0;

/* OpenGL-style right-handed perspective times a view that only translates along x. */
static inline StCamera wall_camera(double centre_x, uint32_t width, uint32_t height) {
    double f = 1.0 / tan(WALL_VFOV / 2.0), aspect = (double)width / height, n = 0.01, fa = 1000.0;
    double m[4][4] = {{f / aspect, 0, 0, -centre_x * f / aspect},
                      {0, f, 0, 0},
                      {0, 0, (fa + n) / (n - fa), 2 * fa * n / (n - fa)},
                      {0, 0, -1, 0}};
    StCamera c = {.width = width, .height = height};
    for (int row = 0; row < 4; row++)
        for (int col = 0; col < 4; col++) c.view_proj[4 * col + row] = m[row][col];
    return c;
}

/* Where the pixel-centre ray of pixel (x, y) of the camera at centre_x hits the wall. */
static inline void wall_surface(double centre_x, uint32_t width, uint32_t height, int x, int y, float p[3]) {
    double f = 1.0 / tan(WALL_VFOV / 2.0), aspect = (double)width / height;
    double ndc_x = (x + 0.5) / width * 2 - 1, ndc_y = 1 - (y + 0.5) / height * 2;
    p[0] = (float)(centre_x + WALL_DEPTH * ndc_x * aspect / f);
    p[1] = (float)(WALL_DEPTH * ndc_y / f);
    p[2] = (float)-WALL_DEPTH;
}

/* The wall's colour at a world position: linear, so bilinear reprojection reproduces it. */
static inline void wall_colour(const float p[3], float rgb[3]) {
    rgb[0] = 0.5f + 0.1f * p[0];
    rgb[1] = 0.5f + 0.1f * p[1];
    rgb[2] = 0.25f;
}

/* How many pixels the wall shifts between two cameras `baseline` apart. */
static inline double wall_shift_pixels(double baseline, uint32_t width, uint32_t height) {
    double f = 1.0 / tan(WALL_VFOV / 2.0), aspect = (double)width / height;
    return baseline / (2 * WALL_DEPTH * aspect / f / width);
}

#endif
