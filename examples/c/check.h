/* The C examples' check macro: report a failed condition with its place and keep going; the
 * program's exit status is non-zero if any check failed (see `failures`). */
#ifndef STEREOTRACE_EXAMPLE_CHECK_H
#define STEREOTRACE_EXAMPLE_CHECK_H

#include <stdio.h>

static int failures = 0;
#define CHECK(cond, ...)                                                                       \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "FAILED %s:%d: ", __FILE__, __LINE__);                             \
            fprintf(stderr, __VA_ARGS__);                                                      \
            fprintf(stderr, "\n");                                                             \
            failures++;                                                                        \
        }                                                                                      \
    } while (0)

#endif
