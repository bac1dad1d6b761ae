/* common.c: errors, logging, progress, timings, safe sizes, atomic output. */
#define _POSIX_C_SOURCE 200809L
#include "base/common.h"
#include "base/outfile.h"

#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <sys/stat.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

int bk_verbosity = 1;
int bk_progress_forced = 0;
int bk_progress_json = 0;
int bk_progress_frame = BK_NO_FRAME;
static FILE *bk_log_file;

int bk_fail(bk_error_t *err, int code, const char *fmt, ...) {
  if (err) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err->msg, sizeof err->msg, fmt, ap);
    va_end(ap);
    err->code = code;
  }
  return code;
}

/* One message line on stderr and, with --log, in the log file. */
static void emit(const char *prefix, const char *fmt, va_list ap) {
  va_list copy;
  va_copy(copy, ap);
  fprintf(stderr, "%s", prefix);
  vfprintf(stderr, fmt, ap);
  fputc('\n', stderr);
  if (bk_log_file) {
    fprintf(bk_log_file, "%s", prefix);
    vfprintf(bk_log_file, fmt, copy);
    fputc('\n', bk_log_file);
    fflush(bk_log_file);
  }
  va_end(copy);
}

void bk_log(int level, const char *fmt, ...) {
  /* the log file keeps what -q hides, and what -v adds */
  int log_level = bk_verbosity > 1 ? bk_verbosity : 1;
  if (level > bk_verbosity && (!bk_log_file || level > log_level)) return;
  va_list ap;
  va_start(ap, fmt);
  if (level > bk_verbosity) {
    vfprintf(bk_log_file, fmt, ap);
    fputc('\n', bk_log_file);
  } else {
    emit("", fmt, ap);
  }
  va_end(ap);
}

void bk_warn(const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  emit("warning: ", fmt, ap);
  va_end(ap);
}

static void report(const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  emit("", fmt, ap);
  va_end(ap);
}

void bk_report(const char *command, const char *msg) { report("baker %s: %s", command, msg); }

int bk_log_open(const char *path, bk_error_t *err) {
  FILE *f = fopen(path, "a");
  if (!f)
    return bk_fail(err, BK_ERR_INPUT, "--log %s: cannot open for appending: %s", path,
                   strerror(errno));
  if (bk_log_file) fclose(bk_log_file);
  bk_log_file = f;
  return BK_OK;
}

int bk_common_option(const char *arg) {
  if (!strcmp(arg, "--progress")) bk_progress_forced = 1;
  else if (!strcmp(arg, "--progress=json")) bk_progress_json = 1;
  else if (!strcmp(arg, "-q") || !strcmp(arg, "--quiet")) bk_verbosity = 0;
  else if (!strcmp(arg, "-v") || !strcmp(arg, "--verbose")) bk_verbosity = 2;
  else return 0;
  return 1;
}

double bk_now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

int bk_mul_size(size_t a, size_t b, size_t *out) {
  if (a != 0 && b > SIZE_MAX / a) return 0;
  *out = a * b;
  return 1;
}

int bk_mul3_size(size_t a, size_t b, size_t c, size_t *out) {
  size_t ab;
  return bk_mul_size(a, b, &ab) && bk_mul_size(ab, c, out);
}

const char *bk_format_bytes(double bytes, char *buf, size_t len) {
  static const char *units[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  int u = 0;
  while (bytes >= 1024.0 && u < 6) {
    bytes /= 1024.0;
    u++;
  }
  snprintf(buf, len, u == 0 ? "%.0f %s" : "%.1f %s", bytes, units[u]);
  return buf;
}

void bk_touch_pages(void *p, size_t bytes) {
  /* each page's first byte written back as it is: the contents stay */
  for (size_t at = 0; p && at < bytes; at += 4096) {
    volatile char *b = (volatile char *)p + at;
    *b = *b;
  }
}

void *bk_calloc_touched(size_t count, size_t size, const char *what, bk_error_t *err) {
  char *p = bk_calloc(count, size, what, err);
  /* a zero per page, volatile (the compiler drops a memset after calloc);
   * not bk_touch_pages, whose read first maps the zero page: two faults */
  for (size_t at = 0, total = count * size; p && at < total; at += 4096)
    ((volatile char *)p)[at] = 0; /* size checked by bk_calloc */
  return p;
}

void *bk_calloc(size_t count, size_t size, const char *what, bk_error_t *err) {
  size_t total;
  if (!bk_mul_size(count, size, &total)) {
    bk_fail(err, BK_ERR_RUNTIME, "%s: size overflows (%zu x %zu bytes)", what, count, size);
    return NULL;
  }
  void *p = calloc(count ? count : 1, size ? size : 1);
  if (!p) {
    char b[32];
    bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory allocating %s", what,
            bk_format_bytes((double)total, b, sizeof b));
  }
  return p;
}

uint64_t bk_physical_memory(void) {
  long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  return (pages > 0 && page > 0) ? (uint64_t)pages * (uint64_t)page : 0;
}

/* --- progress --------------------------------------------------------------- */

void bk_progress_begin(bk_progress_t *p, const char *label, uint64_t total) {
  p->label = label;
  p->total = total;
  p->start_ms = p->last_ms = bk_now_ms();
  p->enabled = bk_progress_forced || bk_progress_json ||
               (bk_verbosity >= 1 && isatty(STDERR_FILENO));
}

static void progress_json(const bk_progress_t *p, double frac, double eta) {
  char eta_s[32] = "null", frame[16] = "null";
  if (frac > 0.0) snprintf(eta_s, sizeof eta_s, "%.3f", eta);
  if (bk_progress_frame != BK_NO_FRAME) snprintf(frame, sizeof frame, "%d", bk_progress_frame);
  fputs("{\"stage\":\"", stderr);
  for (const char *c = p->label; *c; c++) /* labels are ours, but stay valid JSON */
    if (*c == '"' || *c == '\\') fputc('\\', stderr), fputc(*c, stderr);
    else fputc((unsigned char)*c < 32 ? '?' : *c, stderr);
  fprintf(stderr, "\",\"fraction\":%.6f,\"eta_s\":%s,\"frame\":%s}\n", frac, eta_s, frame);
  fflush(stderr);
}

void bk_progress_update(bk_progress_t *p, uint64_t done) {
  if (!p->enabled) return;
  double now = bk_now_ms();
  if (now - p->last_ms < 100.0 && done < p->total) return;
  p->last_ms = now;
  double frac = p->total ? (double)done / (double)p->total : 1.0;
  double elapsed = (now - p->start_ms) / 1000.0;
  double eta = frac > 0.0 ? elapsed * (1.0 - frac) / frac : 0.0;
  if (bk_progress_json) {
    progress_json(p, frac, eta);
    return;
  }
  /* a pipe gets whole lines, a terminal one line redrawn in place */
  fprintf(stderr, isatty(STDERR_FILENO) ? "\r%-22s %5.1f%%  %6.1fs elapsed, ~%.1fs left   "
                                        : "%-22s %5.1f%%  %6.1fs elapsed, ~%.1fs left\n",
          p->label, 100.0 * frac, elapsed, eta);
  fflush(stderr);
}

void bk_progress_end(bk_progress_t *p) {
  if (!p->enabled) return;
  bk_progress_update(p, p->total);
  if (isatty(STDERR_FILENO) && !bk_progress_json) fputc('\n', stderr);
}

/* --- timings ---------------------------------------------------------------- */

void bk_timings_add(bk_timings_t *t, const char *name, double ms, const char *note_fmt, ...) {
  if (!t || t->count >= BK_MAX_STAGES) return;
  bk_stage_time_t *s = &t->stages[t->count++];
  snprintf(s->name, sizeof s->name, "%s", name);
  s->ms = ms;
  s->note[0] = 0;
  s->reused = s->reused_frame = 0;
  if (note_fmt) {
    va_list ap;
    va_start(ap, note_fmt);
    vsnprintf(s->note, sizeof s->note, note_fmt, ap);
    va_end(ap);
  }
}

void bk_timings_mark_reused(bk_timings_t *t, int frame) {
  if (!t || t->count == 0) return;
  t->stages[t->count - 1].reused = 1;
  t->stages[t->count - 1].reused_frame = frame;
}

void bk_timings_print(const bk_timings_t *t, FILE *out) {
  double total = 0.0;
  fprintf(out, "%-24s %12s  %s\n", "stage", "ms", "");
  for (int i = 0; i < t->count; i++) {
    fprintf(out, "%-24s %12.1f  %s\n", t->stages[i].name, t->stages[i].ms, t->stages[i].note);
    total += t->stages[i].ms;
  }
  fprintf(out, "%-24s %12.1f\n", "total", total);
}

uint64_t bk_hash64(const void *data, size_t len, uint64_t h) {
  const unsigned char *p = data;
  for (size_t i = 0; i < len; i++) {
    h ^= p[i];
    h *= 1099511628211ull;
  }
  return h;
}

bk_file_kind_t bk_file_kind(const char *path) {
  struct stat st;
  if (stat(path, &st) != 0) return BK_FILE_MISSING;
  return S_ISREG(st.st_mode) ? BK_FILE_REGULAR : S_ISFIFO(st.st_mode) ? BK_FILE_PIPE : BK_FILE_OTHER;
}

int bk_read_file(const char *path, char **out, size_t *len, bk_error_t *err) {
  if (bk_file_kind(path) == BK_FILE_OTHER)
    return bk_fail(err, BK_ERR_INPUT, "%s: not a regular file (a directory or a device)", path);
  FILE *f = fopen(path, "rb");
  if (!f)
    return bk_fail(err, BK_ERR_INPUT, "%s: cannot open: %s", path, strerror(errno));
  size_t cap = 1 << 16, n = 0;
  char *buf = malloc(cap + 1);
  if (!buf) {
    fclose(f);
    return bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory", path);
  }
  for (;;) {
    size_t got = fread(buf + n, 1, cap - n, f);
    n += got;
    if (n < cap) break;
    char *bigger = realloc(buf, cap * 2 + 1);
    if (!bigger) {
      free(buf);
      fclose(f);
      return bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory", path);
    }
    buf = bigger;
    cap *= 2;
  }
  int bad = ferror(f);
  fclose(f);
  if (bad) {
    free(buf);
    return bk_fail(err, BK_ERR_INPUT, "%s: read error", path);
  }
  buf[n] = 0;
  *out = buf;
  if (len) *len = n;
  return BK_OK;
}

/* --- atomic output ---------------------------------------------------------- */

void bk_temp_path(const char *final_path, char *out, size_t len) {
  char copy_dir[4096], copy_base[4096];
  snprintf(copy_dir, sizeof copy_dir, "%s", final_path);
  snprintf(copy_base, sizeof copy_base, "%s", final_path);
  snprintf(out, len, "%s/.%s.tmp%ld", dirname(copy_dir), basename(copy_base), (long)getpid());
}

int bk_check_output_dir(const char *path, bk_error_t *err) {
  char copy[4096];
  snprintf(copy, sizeof copy, "%s", path);
  const char *dir = dirname(copy);
  if (access(dir, F_OK) != 0)
    return bk_fail(err, BK_ERR_INPUT, "%s: output directory %s does not exist", path, dir);
  /* access() says yes to root everywhere; creating the temporary file is the
   * real test (read-only mounts, /proc, quotas) */
  char temp[4200];
  bk_temp_path(path, temp, sizeof temp);
  int fd = access(dir, W_OK) == 0 ? open(temp, O_WRONLY | O_CREAT | O_EXCL, 0644) : -1;
  if (fd < 0)
    return bk_fail(err, BK_ERR_INPUT, "%s: output directory %s is not writable", path, dir);
  close(fd);
  unlink(temp);
  bk_clean_stale_temps(dir);
  return BK_OK;
}

int bk_commit_temp(const char *temp_path, const char *final_path, bk_error_t *err) {
  /* a full disk may only show at write-back: fail while the old file stands */
  int rc = bk_fsync_path(temp_path, final_path, err);
  if (rc) {
    remove(temp_path);
    return rc;
  }
  if (rename(temp_path, final_path) != 0) {
    int e = errno;
    remove(temp_path);
    return bk_fail(err, BK_ERR_RUNTIME, "%s: cannot rename %s into place: %s", final_path,
                   temp_path, strerror(e));
  }
  bk_fsync_dir_of(final_path);
  return BK_OK;
}
