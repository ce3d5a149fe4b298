/* The file system assimp sees while it imports a model (an aiFileIO, <assimp/cfileio.h>).
 *
 * A model is untrusted input, and assimp follows the references inside it (glTF buffers and
 * images, OBJ material libraries, COLLADA/FBX side files ...). Through this IO system assimp may
 * open the model itself and files that resolve (after symlinks and '..', by realpath) inside the
 * model's own folder or inside a folder (or exactly a file) the caller allowed; anything else is
 * refused and recorded, and the import then fails naming the reference and the folder. Files are
 * opened read-only, non-blocking, without following a final symlink, and must be regular files no
 * larger than the byte limit; writes are refused. Nothing of a file's content ever reaches a
 * message. */
#ifndef SL_SCENE_ASSIMP_IO_H
#define SL_SCENE_ASSIMP_IO_H

#include "core/sl_core.h"

#include <assimp/cfileio.h>

/* Default largest file assimp may open through the IO system (model or reference). */
#define SL_ASSIMP_MAX_FILE_BYTES ((uint64_t)4 << 30)
/* Most files one import may open (assimp opens the model several times to detect its format). */
#define SL_ASSIMP_MAX_OPENS 4096u

typedef struct sl_aio_root {
    char *path;                 /* canonical; folders end in '/' */
    size_t size;                /* strlen(path) + 1, for freeing */
    bool folder;                /* prefix match (folder) or exact match (a single file) */
} sl_aio_root;

typedef struct sl_aio {
    struct aiFileIO io;         /* handed to assimp; io.UserData points back here */
    const sl_allocator *a;
    char model[4096];           /* the model's canonical path */
    char folder[4096];          /* its folder, canonical, with a trailing '/' */
    char given_dir[4096];       /* its folder as given, with the '/' ("" for a bare name): assimp
                                   puts it before references, messages take it off again */
    sl_aio_root *roots;         /* folders and files allowed besides the model's folder */
    uint32_t root_count, root_cap;
    uint64_t max_file_bytes;
    bool text_references;       /* an OBJ model: what it references (material libraries) is text */
    uint32_t opens, open_files;
    /* the first refusal, recorded for the import's error (escaped text only) */
    bool refused;
    sl_status refused_status;
    char refused_message[400];
} sl_aio;

/* Set up for a model (its path as given to assimp). allowed: extra folders or files (borrowed for
 * this call; canonical copies are made with `a`). max_file_bytes 0 means SL_ASSIMP_MAX_FILE_BYTES.
 * Fails when the model or an allowed path cannot be resolved. */
sl_status sl_aio_init(sl_aio *x, const char *model, const char *const *allowed, uint32_t allowed_count,
                      uint64_t max_file_bytes, const sl_allocator *a, sl_error *err);
void sl_aio_free(sl_aio *x);

#endif
