/* fuzz_util.h: what every fuzz target shares. The readers take a path, so
 * each input is written to a file in a private, empty directory made once
 * per process (the working directory is moved there, so a relative path in a
 * fuzzed scene names nothing of ours). */
#ifndef BAKER_FUZZ_UTIL_H
#define BAKER_FUZZ_UTIL_H

#include <stddef.h>
#include <stdint.h>

/* Makes the directory and moves into it; aborts when it cannot. */
void fuzz_enter_workdir(void);
/* Writes the input as NAME in the working directory; aborts on failure
 * (a full disk is not a finding). */
void fuzz_write_input(const char *name, const uint8_t *data, size_t size);
/* For targets whose readers fork (fuzz_vdb): a child that fails is not a
 * finding, so it leaves no artifact; the parent's own faults still do. */
void fuzz_children_die_plainly(void);

#endif
