#include "support/pk3_names.h"

#include <stdio.h>

void sl_test_collect_name(void *user, const char *entry)
{
    sl_test_name_list *l = user;
    if (l->count < (int)(sizeof l->names / sizeof l->names[0]))
        snprintf(l->names[l->count++], sizeof l->names[0], "%s", entry);
}
