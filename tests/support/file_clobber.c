#include "file_clobber.h"

#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

long sl_test_file_size(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return -1;
    long n = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
    fclose(f);
    return n;
}

bool sl_test_clobber_in_place(const char *path, long size)
{
    int fd = open(path, O_WRONLY | O_TRUNC);
    if (fd < 0)
        return false;
    uint8_t junk[4096];
    memset(junk, 0xA5, sizeof junk);
    bool ok = true;
    for (long at = 0; at < size / 4 && ok; at += (long)sizeof junk)
        ok = write(fd, junk, sizeof junk) == (ssize_t)sizeof junk;
    close(fd);
    return ok;
}
