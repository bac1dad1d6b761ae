/* clenv.h: where OpenCL may keep files, chosen before the platform is touched.
 *
 * baker's own binary cache lives in BAKER_CACHE_DIR, else
 * $XDG_CACHE_HOME/baker, else $HOME/.cache/baker, else nowhere (BAKER_NO_CACHE
 * turns it off). PoCL keeps a cache of its own and, without HOME, falls back
 * to a shared /tmp/pocl that another user may own: it then finds no device
 * or aborts (cron, `env -i`, containers). So unless POCL_CACHE_DIR is set,
 * baker sets it to `pocl/` under its own cache, else to a private
 * per-user directory under $TMPDIR (or /tmp). */
#ifndef BAKER_CLENV_H
#define BAKER_CLENV_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The binary cache directory into out; 0 when caching is off. */
int clh_cache_dir(char *out, size_t len);
/* mkdir -p; 0 on success. */
int clh_mkdir_p(const char *path);
/* Sets POCL_CACHE_DIR (when unset) as above; call before clGetPlatformIDs. */
void clh_prepare_env(void);

#ifdef __cplusplus
}
#endif
#endif
