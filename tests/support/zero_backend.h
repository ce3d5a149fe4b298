/* A draw backend that forwards every call to another one but answers every query with 0 samples:
 * broken on purpose, so that a query culler's oracle test shows it can fail (test_backend,
 * test_query_cullers). */
#ifndef SL_TEST_ZERO_BACKEND_H
#define SL_TEST_ZERO_BACKEND_H
#include "sightline/backend.h"

typedef struct sl_test_zero_backend {
    sl_draw_backend inner;
} sl_test_zero_backend;

/* The table (user = z, which must outlive it) forwarding to inner. */
sl_draw_backend sl_test_zero_table(sl_test_zero_backend *z, sl_draw_backend inner);
#endif
