/* Files changed under a reader's feet, for the tests that a file rewritten in place (what
 * `cp other FILE` does: same inode) cannot crash a reader (test_pvs_open, test_scene_read). */
#ifndef SL_TEST_FILE_CLOBBER_H
#define SL_TEST_FILE_CLOBBER_H
#include <stdbool.h>

/* The file's size in bytes, or -1 when it cannot be read. */
long sl_test_file_size(const char *path);
/* Truncate the file in place, then write a quarter of `size` bytes of other content into it (the
 * later pages of a mapping are gone). No cmocka assertion: it also runs in forked children. */
bool sl_test_clobber_in_place(const char *path, long size);
#endif
