/* outfile.h: the durability half of atomic output (common.h has the naming
 * and the rename).
 *
 * Every output is written to ".NAME.tmpPID" beside NAME and renamed into
 * place. Before the rename the temporary file is fsync'ed, so a full disk or
 * an I/O error that the kernel reports only at write-back (ENOSPC, EDQUOT,
 * EIO) is seen while the previous NAME is still intact; after it the
 * directory is fsync'ed so the rename itself survives a power cut.
 *
 * A process killed by SIGKILL leaves its ".NAME.tmpPID" behind; the next run
 * that writes into the directory removes those whose PID no longer exists
 * (and that nobody has written for a minute: see BK_STALE_TEMP_AGE_S). */
#ifndef BAKER_OUTFILE_H
#define BAKER_OUTFILE_H

#include "base/common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* fsync(2) of `temp_path`; BK_ERR_RUNTIME naming `final_path` and the
 * reason ("No space left on device") when the data cannot be made durable. */
int bk_fsync_path(const char *temp_path, const char *final_path, bk_error_t *err);
/* fsync of the directory holding `path` (best effort: some file systems
 * refuse it, which loses nothing that the rename did not already risk). */
void bk_fsync_dir_of(const char *path);
/* Removes ".NAME.tmpPID" regular files in `dir` owned by this user whose
 * process is gone (kill(PID, 0) says ESRCH). Live processes' files and
 * anything else are never touched. Returns how many were removed. */
int bk_clean_stale_temps(const char *dir);
/* The PID a temporary name carries, or 0 when `name` is not ".X.tmpPID". */
long bk_temp_name_pid(const char *name);

#ifdef __cplusplus
}
#endif
#endif
