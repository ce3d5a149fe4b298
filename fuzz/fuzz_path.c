/* libFuzzer target: the plain-text path reader. */
#include "sightline/path.h"

#include <stddef.h>
#include <stdint.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sl_path path = NULL;
    sl_error err;
    if (sl_path_parse(data, size, "fuzz.txt", NULL, &path, &err) == SL_OK)
        sl_path_destroy(path);
    return 0;
}
