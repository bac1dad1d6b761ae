/* verify.h: the `baker verify` command (verify_cmd.c). */
#ifndef BAKER_VERIFY_H
#define BAKER_VERIFY_H

#include <stdio.h>

int verify_main(int argc, char **argv);
void verify_usage(FILE *out);

#endif
