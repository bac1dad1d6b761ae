/* common.h: errors, logging, progress and stage timing shared by every stage.
 *
 * Errors travel as a bk_error_t filled by the function that noticed them, and
 * its return value is the exit status the program will end with:
 * BK_OK, BK_ERR_RUNTIME (1: OpenCL failed, out of memory, I/O error) or
 * BK_ERR_INPUT (2: the user's scene, mesh, VDB file or command line is wrong).
 * Messages name the file and what was wrong, e.g.
 * "scene.json:14:9: lights[0].angle_deg: expected a number in (0, 90], got 120". */
#ifndef BAKER_COMMON_H
#define BAKER_COMMON_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

enum { BK_OK = 0, BK_ERR_RUNTIME = 1, BK_ERR_INPUT = 2 };

typedef struct bk_error {
  int code;
  char msg[2048];
} bk_error_t;

/* Fills err (when not NULL) and returns code, so callers write
 * `return bk_fail(err, BK_ERR_INPUT, "%s: ...", path);`. */
int bk_fail(bk_error_t *err, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Verbosity: 0 quiet (errors only), 1 normal, 2 verbose. */
extern int bk_verbosity;
void bk_log(int level, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void bk_warn(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* The verbosity flags every command takes (--progress, --progress=json,
 * -q/--quiet, -v/--verbose): applies `arg` and returns 1 when it is one of
 * them. */
int bk_common_option(const char *arg);

/* --log FILE: every message (bk_log, bk_warn, bk_report) is appended to FILE
 * as well as written to stderr. BK_ERR_INPUT when FILE cannot be opened. */
int bk_log_open(const char *path, bk_error_t *err);
/* A command's closing error, "baker bake: MSG", on stderr and in the log. */
void bk_report(const char *command, const char *msg);

double bk_now_ms(void); /* monotonic clock */

/* a*b (and a*b*c) without overflow; return 0 when it would overflow. */
int bk_mul_size(size_t a, size_t b, size_t *out);
int bk_mul3_size(size_t a, size_t b, size_t c, size_t *out);
/* Allocation that fails with a message saying what and how much. */
void *bk_calloc(size_t count, size_t size, const char *what, bk_error_t *err);
/* bk_calloc with every page written once on this thread: for arrays that
 * bk_parallel fills next. Pages first touched by several threads at once
 * fault under one lock: 5 ms for two 1 MB arrays, against 0.9 ms here. */
void *bk_calloc_touched(size_t count, size_t size, const char *what, bk_error_t *err);
/* Makes every page of p[0, bytes) resident on this thread (as
 * bk_calloc_touched), keeping what it holds. */
void bk_touch_pages(void *p, size_t bytes);
/* Physical memory of this machine, in bytes (0 when unknown). */
uint64_t bk_physical_memory(void);
/* Human-readable byte count ("3.2 GiB") into buf. */
const char *bk_format_bytes(double bytes, char *buf, size_t len);

/* Progress on a terminal (stderr is a tty and verbosity >= 1), or when forced
 * with --progress; silent in a pipe. Updates at most ~10 times a second.
 * --progress=json writes one object per line instead, for a farm's monitor:
 * {"stage":"photon march","fraction":0.25,"eta_s":12.5,"frame":3}
 * (eta_s null until known, frame null outside a frame batch). */
extern int bk_progress_forced;
extern int bk_progress_json;
extern int bk_progress_frame; /* BK_NO_FRAME outside a batch */
#define BK_NO_FRAME (-2147483647 - 1)
typedef struct bk_progress {
  const char *label;
  uint64_t total;
  double start_ms, last_ms;
  int enabled;
} bk_progress_t;
void bk_progress_begin(bk_progress_t *p, const char *label, uint64_t total);
void bk_progress_update(bk_progress_t *p, uint64_t done);
void bk_progress_end(bk_progress_t *p);

/* The per-stage timing table printed after a bake (like the slides' table). */
#define BK_MAX_STAGES 32
typedef struct bk_stage_time {
  char name[48];
  double ms;
  char note[96];
  int reused, reused_frame; /* the stage's result was kept from frame reused_frame */
} bk_stage_time_t;
typedef struct bk_timings {
  bk_stage_time_t stages[BK_MAX_STAGES];
  int count;
} bk_timings_t;
void bk_timings_add(bk_timings_t *t, const char *name, double ms, const char *note_fmt, ...)
    __attribute__((format(printf, 4, 5)));
void bk_timings_print(const bk_timings_t *t, FILE *out);
/* Marks the latest row as reused from `frame` (a batch of frames kept the
 * stage's result; --stats says so). */
void bk_timings_mark_reused(bk_timings_t *t, int frame);

/* 64-bit FNV-1a, for scene hashes and the kernel cache key. */
uint64_t bk_hash64(const void *data, size_t len, uint64_t seed);
#define BK_HASH_SEED 1469598103934665603ull

/* What a path names. A pipe (a FIFO, `<(...)`) can be read once, in order,
 * and blocks until its writer writes; a directory or a device (/dev/zero
 * never ends) is no input file. Missing: stat failed, and the open that
 * follows says why. */
typedef enum { BK_FILE_MISSING, BK_FILE_REGULAR, BK_FILE_PIPE, BK_FILE_OTHER } bk_file_kind_t;
bk_file_kind_t bk_file_kind(const char *path);

/* Reads a whole file into a NUL-terminated buffer (caller frees): a regular
 * file or a pipe; anything else (BK_FILE_OTHER) is refused, BK_ERR_INPUT. */
int bk_read_file(const char *path, char **out, size_t *len, bk_error_t *err);

/* Output files are written to a temporary name in the same directory and
 * renamed, so a crash never leaves a truncated file. bk_temp_path gives that
 * name; bk_check_output_dir refuses early when the directory is missing or not
 * writable, before any work is done. */
void bk_temp_path(const char *final_path, char *out, size_t len);
int bk_check_output_dir(const char *path, bk_error_t *err);
int bk_commit_temp(const char *temp_path, const char *final_path, bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
