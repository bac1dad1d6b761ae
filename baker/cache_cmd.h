/* cache_cmd.h: the `baker cache` command (cache_cmd.c). */
#ifndef BAKER_CACHE_CMD_H
#define BAKER_CACHE_CMD_H

int cache_main(int argc, char **argv);

#endif
