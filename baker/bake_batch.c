/* bake_batch.c: the frames one `baker bake` runs (bake.h: bake_run).
 *
 * In: the options (--frames list, or a scheduler's array task), the output
 * pattern. Out: one bake_frame per frame in the order given; a frame is
 * skipped only when its output is complete and records the scene hash and
 * settings this run would bake with (the stale-frame rule), and with
 * --keep-going the frames after a failure still run and a per-frame summary
 * ends the batch. Exit status: 0, else 1 when any frame failed at run time,
 * else 2 (only bad input). */
#define _POSIX_C_SOURCE 200809L
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "bake.h"
#include "base/common.h"
#include "base/frames.h"
#include "frame_reuse.h"

/* Array-task variables, first set wins: Slurm, SGE ("undefined" outside an
 * array job), PBS Torque, PBS Pro. */
static const char *const task_vars[] = {"SLURM_ARRAY_TASK_ID", "SGE_TASK_ID", "PBS_ARRAYID",
                                        "PBS_ARRAY_INDEX", NULL};

/* The scheduler's task id, naming its variable in *var; NULL when none. */
static const char *array_task(const char **var) {
  for (int i = 0; task_vars[i]; i++) {
    const char *v = getenv(task_vars[i]);
    if (v && *v && strcmp(v, "undefined") != 0) {
      *var = task_vars[i];
      return v;
    }
  }
  return NULL;
}

/* Which frames to bake: --frames LIST; --frames task (the array task's
 * frame, an error outside one); without --frames the array task's frame when
 * the output holds a frame pattern, else the single frame 0. */
static int choose_frames(const bake_options_t *opt, frames_list_t *list, bk_error_t *err) {
  const char *var = NULL, *task = array_task(&var);
  int patterned = frames_has_pattern(opt->out_path);
  char where[64];
  int rc = BK_OK;
  if (opt->frames && strcmp(opt->frames, "task") != 0) {
    rc = frames_parse_list(opt->frames, "--frames", list, err);
  } else if ((opt->frames || patterned) && task) {
    snprintf(where, sizeof where, "$%s", var);
    rc = frames_parse_list(task, where, list, err);
  } else if (opt->frames || patterned) {
    return bk_fail(err, BK_ERR_INPUT,
                   "%s: %s but no array task variable is set ($SLURM_ARRAY_TASK_ID, "
                   "$SGE_TASK_ID, $PBS_ARRAYID or $PBS_ARRAY_INDEX); give --frames LIST",
                   opt->out_path, opt->frames ? "--frames task was given"
                                              : "the output holds a frame pattern");
  } else {
    rc = frames_parse_list("0", "frame", list, err);
  }
  if (rc) return rc;
  if (list->count > 1 && !patterned) {
    bk_fail(err, BK_ERR_INPUT,
            "%s: %d frames would all write this one file; put #### or $F4 in the "
            "output path", opt->out_path, list->count);
    frames_list_free(list); /* the caller frees the list only on success */
    return BK_ERR_INPUT;
  }
  return BK_OK;
}

/* -o is checked before any work: not stdout, not a directory, in a writable
 * directory. */
static int check_output(const bake_options_t *opt, const char *first_out, bk_error_t *err) {
  struct stat st;
  if (!strcmp(opt->out_path, "-"))
    return bk_fail(err, BK_ERR_INPUT,
                   "-o -: a VDB cannot be written to standard output (it is written under a "
                   "temporary name and renamed); give a file name");
  if (stat(first_out, &st) == 0 && S_ISDIR(st.st_mode))
    return bk_fail(err, BK_ERR_INPUT, "-o %s: is a directory; expected a file name such as "
                   "%s/light.vdb", first_out, first_out);
  return bk_check_output_dir(first_out, err);
}

/* The first setting that differs between two "key=value ..." strings, as
 * "photons 1000, now 2000". */
static void settings_diff(const char *was, const char *now, char *out, size_t len) {
  const char *p = now;
  while (*p) {
    size_t n = strcspn(p, " ");
    const char *eq = memchr(p, '=', n);
    if (eq) {
      size_t klen = (size_t)(eq - p) + 1; /* "key=" */
      const char *q = was;
      while (*q && !(strncmp(q, p, klen) == 0 && (q == was || q[-1] == ' '))) q++;
      size_t vn = *q ? strcspn(q + klen, " ") : 0;
      if (!*q || vn != n - klen || strncmp(q + klen, eq + 1, vn) != 0) {
        snprintf(out, len, "%.*s %.*s, now %.*s", (int)(klen - 1), p, (int)vn,
                 *q ? q + klen : "(none)", (int)(n - klen), eq + 1);
        if (!*q) snprintf(out, len, "no %.*s recorded", (int)(klen - 1), p);
        return;
      }
    }
    p += n;
    while (*p == ' ') p++;
  }
  snprintf(out, len, "other settings");
}

/* 1 when the existing out_path holds what this run would bake of scene s
 * (skip it), else 0 with the reason in why. */
static int up_to_date(const bake_options_t *opt, const scene_t *s, const char *out_path,
                      char *why, size_t len) {
  char now[512], was[512];
  bake_settings(opt, s, now, sizeof now);
  bk_error_t ignored;
  if (vdbio_read_meta(out_path, "creator", was, sizeof was, &ignored) != BK_OK ||
      strncmp(was, "baker", 5) != 0)
    snprintf(why, len, "%s is not a complete baker file", out_path);
  else if (vdbio_read_meta(out_path, "bake_settings", was, sizeof was, &ignored) != BK_OK)
    snprintf(why, len, "%s records no bake settings (an older baker)", out_path);
  else if (strcmp(was, now) != 0) {
    char diff[256];
    settings_diff(was, now, diff, sizeof diff);
    snprintf(why, len, "%s was baked with %s", out_path, diff);
  } else {
    return 1;
  }
  return 0;
}

enum { FRAME_BAKED, FRAME_SKIPPED, FRAME_FAILED };
typedef struct frame_result {
  int status, code;
  char *reason; /* failed frames only */
} frame_result_t;

/* One frame: skip, or bake (saying why when an output is replaced). */
static int run_frame(const bake_options_t *opt, int frame, int i, int count,
                     frame_result_t *res, bake_reuse_t *reuse, bk_error_t *err) {
  char scene_path[SCENE_PATH_MAX], out_path[SCENE_PATH_MAX], why[SCENE_PATH_MAX + 512];
  int rc;
  if ((rc = frames_expand(opt->scene_path, frame, scene_path, sizeof scene_path, err)) ||
      (rc = frames_expand(opt->out_path, frame, out_path, sizeof out_path, err)))
    return rc;
  /* An existing output is compared with the scene (a scene that cannot be
   * loaded is then an error, never a skip), and the bake takes that scene
   * over, so its warnings are said once. A missing output is baked unseen. */
  scene_t scene, *loaded = NULL;
  if (!opt->force && access(out_path, F_OK) == 0) {
    if ((rc = bake_load_scene(opt, scene_path, frame, &scene, err))) return rc;
    if (up_to_date(opt, &scene, out_path, why, sizeof why)) {
      scene_free(&scene);
      bk_log(1, "frame %d: %s is up to date: skipped (--force re-bakes it)", frame, out_path);
      res->status = FRAME_SKIPPED;
      return BK_OK;
    }
    loaded = &scene;
    bk_log(1, "frame %d: %s: re-baking", frame, why);
  }
  if (count > 1) bk_log(1, "frame %d (%d of %d)", frame, i + 1, count);
  bk_progress_frame = frame;
  return bake_frame(opt, scene_path, out_path, frame, loaded, reuse, err);
}

/* The table --keep-going ends with, and the exit status it implies. */
static int summarize(const frames_list_t *list, const frame_result_t *res) {
  int baked = 0, skipped = 0, failed = 0, runtime = 0;
  bk_log(0, "%-10s %-8s %s", "frame", "status", "reason");
  for (int i = 0; i < list->count; i++) {
    const frame_result_t *r = &res[i];
    static const char *const names[] = {"baked", "skipped", "FAILED"};
    bk_log(0, "%-10d %-8s %s", list->frames[i], names[r->status],
           r->status == FRAME_FAILED ? r->reason : r->status == FRAME_SKIPPED ? "up to date" : "");
    baked += r->status == FRAME_BAKED;
    skipped += r->status == FRAME_SKIPPED;
    failed += r->status == FRAME_FAILED;
    runtime += r->status == FRAME_FAILED && r->code == BK_ERR_RUNTIME;
  }
  bk_log(0, "%d frames baked, %d skipped as up to date, %d failed", baked, skipped, failed);
  return runtime ? BK_ERR_RUNTIME : failed ? BK_ERR_INPUT : BK_OK;
}

/* Without --keep-going the first failure ends the batch, its message led by
 * the frame. A frame takes what the one before left when its inputs hash the
 * same (frame_reuse.h). */
static int run_frames(const bake_options_t *opt, const frames_list_t *list, frame_result_t *res,
                      bake_reuse_t *reuse, bk_error_t *err) {
  int n = list->count;
  for (int i = 0; i < n; i++) {
    int rc = run_frame(opt, list->frames[i], i, n, &res[i], reuse, err);
    if (!rc) continue;
    res[i].status = FRAME_FAILED;
    res[i].code = rc;
    if (opt->keep_going) {
      res[i].reason = strdup(err->msg);
      bk_log(0, "baker bake: frame %d: %s", list->frames[i], err->msg);
      continue;
    }
    if (n > 1) {
      char msg[sizeof err->msg];
      /* a long message loses its tail, as bk_fail's do (the test keeps
       * gcc's -Wformat-truncation quiet about it) */
      if (snprintf(msg, sizeof msg, "frame %d: %s", list->frames[i], err->msg) < 0) msg[0] = 0;
      snprintf(err->msg, sizeof err->msg, "%s", msg);
    }
    return rc;
  }
  if (opt->keep_going) {
    int rc = summarize(list, res);
    if (rc) bk_fail(err, rc, "%s", "some frames failed (see the summary above)");
    return rc;
  }
  int skipped = 0;
  for (int i = 0; i < n; i++) skipped += res[i].status == FRAME_SKIPPED;
  if (n > 1) bk_log(1, "%d frames baked, %d skipped as up to date", n - skipped, skipped);
  return BK_OK;
}

int bake_run(const bake_options_t *opt, bk_error_t *err) {
  frames_list_t list;
  char first_out[SCENE_PATH_MAX];
  int rc = choose_frames(opt, &list, err);
  if (rc) return rc;
  frame_result_t *res = bk_calloc((size_t)list.count, sizeof *res, "frame results", err);
  if (!res) rc = BK_ERR_RUNTIME;
  if (!rc) rc = frames_expand(opt->out_path, list.frames[0], first_out, sizeof first_out, err);
  if (!rc) rc = check_output(opt, first_out, err);
  bake_reuse_t reuse;
  memset(&reuse, 0, sizeof reuse);
  reuse.several_frames = list.count > 1;
  reuse.keep_fields = reuse.several_frames; /* they cost memory: only for a next frame */
  if (!rc) rc = run_frames(opt, &list, res, &reuse, err);
  fr_free(&reuse);
  for (int i = 0; res && i < list.count; i++) free(res[i].reason);
  free(res);
  frames_list_free(&list);
  return rc;
}
