/* A counting allocator for tests: checks that every handle returns every byte it took. */
#ifndef SL_TEST_COUNTING_ALLOC_H
#define SL_TEST_COUNTING_ALLOC_H
#include "sightline/core.h"
typedef struct sl_test_counter { size_t live, peak, calls; } sl_test_counter;
/* An allocator whose user pointer is c. */
sl_allocator sl_test_counting_allocator(sl_test_counter *c);
#endif
