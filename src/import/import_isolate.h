/* The assimp import in this process, and the isolation around it (import_isolate.c). */
#ifndef SL_IMPORT_ISOLATE_H
#define SL_IMPORT_ISOLATE_H

#include "sightline/import.h"

/* sl_import_assimp without the child process: assimp runs here (import_assimp.c). */
sl_status sl_import_assimp_in_process(const char *path, const sl_import_options *opt, const sl_allocator *alloc,
                                      sl_scene *out, sl_error *err);

/* The same after sl_import_assimp_check passed (opt not NULL): the child's entry. */
sl_status sl_import_assimp_checked(const char *path, const sl_import_options *opt, const sl_allocator *alloc,
                                   sl_scene *out, sl_error *err);

/* What sl_import_assimp checks before assimp runs (options, the file's kind and size, a PLY
 * header's sanity): cheap, our own code, done in this process before any child is started. */
sl_status sl_import_assimp_check(const char *path, const sl_import_options *opt, const sl_allocator *alloc, sl_error *err);

#endif
