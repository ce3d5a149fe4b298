/* TEMPORARY placeholder while the subcommand is written: fails loudly. */
#include "cli.h"
int sl_cmd_pvs(int argc, char **argv)
{
    (void)argc;
    cli_error(argv[0], "not implemented yet");
    return 1;
}
