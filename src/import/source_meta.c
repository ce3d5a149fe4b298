/* The "source" metadata of imports: base name and content hash, never the path as typed
 * (issue 12: `dm1.bsp`, `./dm1.bsp` and `/abs/dm1.bsp` gave three different .slscene files). */
#include "source_meta.h"

#include <errno.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

const char *sl_path_base_name(const char *path)
{
    const char *base = path;
    for (const char *s = path; *s; s++)
        if (*s == '/' || *s == '\\')
            base = s + 1;
    return *base ? base : path;
}

static sl_status set_hash(sl_scene scene, uint64_t h, sl_error *err)
{
    char hex[17];
    snprintf(hex, sizeof hex, "%016llx", (unsigned long long)h);
    return sl_scene_set_meta(scene, "source.xxh3", hex, err);
}

sl_status sl_scene_set_source(sl_scene scene, const char *name, const void *data, size_t size, sl_error *err)
{
    sl_status st = sl_scene_set_meta(scene, "source", sl_path_base_name(name ? name : "<memory>"), err);
    if (st == SL_OK)
        st = set_hash(scene, sl_hash64(size ? data : "", size, 0), err);
    return st;
}

sl_status sl_scene_set_source_file(sl_scene scene, const char *path, sl_error *err)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0)
        return sl_fail(err, SL_ERROR_IO, "%s: cannot open to hash it: %s", path, strerror(errno));
    XXH3_state_t *state = XXH3_createState();
    if (!state) {
        close(fd);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    }
    XXH3_64bits_reset_withSeed(state, 0);
    const size_t cap = (size_t)1 << 16;
    uint8_t *buf = sl_alloc(&scene->alloc, cap);
    if (!buf) {
        XXH3_freeState(state);
        close(fd);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    }
    sl_status st = SL_OK;
    for (;;) {
        ssize_t n = read(fd, buf, cap);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0) {
            st = sl_fail(err, SL_ERROR_IO, "%s: read failed while hashing it: %s", path, strerror(errno));
            break;
        }
        if (n == 0)
            break;
        XXH3_64bits_update(state, buf, (size_t)n);
    }
    uint64_t h = XXH3_64bits_digest(state);
    XXH3_freeState(state);
    sl_free(&scene->alloc, buf, cap);
    close(fd);
    if (st == SL_OK)
        st = sl_scene_set_meta(scene, "source", sl_path_base_name(path), err);
    if (st == SL_OK)
        st = set_hash(scene, h, err);
    return st;
}

sl_status sl_scene_set_source_entry(sl_scene scene, const char *archive, const char *entry, sl_error *err)
{
    const char *base = sl_path_base_name(archive);
    size_t n = strlen(base) + strlen(entry) + 2;
    char small[512];
    char *s = n <= sizeof small ? small : sl_alloc(&scene->alloc, n);
    if (!s)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory");
    size_t nb = strlen(base);
    memcpy(s, base, nb);
    s[nb] = ':';
    memcpy(s + nb + 1, entry, n - nb - 1); /* with the NUL */
    sl_status st = sl_scene_set_meta(scene, "source", s, err);
    if (s != small)
        sl_free(&scene->alloc, s, n);
    return st;
}
