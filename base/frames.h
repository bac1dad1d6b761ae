/* frames.h: frame ranges and frame patterns in file paths.
 *
 * In: a range spec from --frames ("A", "A-B" or "A-BxS"; frames may be
 * negative, e.g. "-10--1x3"), or a frame list in the syntax of fileseq,
 * Deadline and OpenJD: comma-separated "A", "A-B", "A-BxS" and "A-B:S"
 * ("1-3,7,10-20x2", "1-20:2"), and paths holding a frame pattern. Out: the list
 * of frames and each frame's path. Patterns (DESIGN.md §6):
 *   a run of k '#'  -> the frame zero padded to k digits ("####" -> 0042,
 *                      Nuke/Blender style; "#" -> 42);
 *   $Fn (n = 1..9)  -> the frame zero padded to n digits (Houdini, $F4 -> 0042);
 *   $F              -> the frame unpadded.
 * `$F` followed by a letter or '_' is another Houdini variable ($FPS, $FF,
 * $FSTART) and is left as it is. Negative frames keep their sign in front of
 * the padding, as printf("%04d") does ("-001"). */
#ifndef BAKER_FRAMES_H
#define BAKER_FRAMES_H

#include "base/common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* More frames than this in one range is surely a typo (e.g. "1-1000000"). */
#define FRAMES_MAX_COUNT 1000000

typedef struct frames_range {
  int first, last, step; /* first <= last, step >= 1 */
} frames_range_t;

/* Parses "A", "A-B" or "A-BxS". BK_ERR_INPUT (naming `where`, e.g.
 * "--frames") for anything else, B < A, S < 1 or more than FRAMES_MAX_COUNT
 * frames. */
int frames_parse(const char *spec, const char *where, frames_range_t *out, bk_error_t *err);

/* A frame list: the frames in the order the spec names them, each once (a
 * frame named again later, as in "1-5,3", keeps its first place). */
typedef struct frames_list {
  int *frames;
  int count;
} frames_list_t;

/* Parses a comma list of "A", "A-B", "A-BxS" and "A-B:S" (blanks around
 * the commas allowed). BK_ERR_INPUT naming `where` and the bad element for
 * anything else, B < A, S < 1, an empty element, or more than
 * FRAMES_MAX_COUNT frames in all; BK_ERR_RUNTIME when out of memory. */
int frames_parse_list(const char *spec, const char *where, frames_list_t *out, bk_error_t *err);
void frames_list_free(frames_list_t *l);

/* Number of frames in the range and the i-th of them (0-based). */
int frames_count(const frames_range_t *r);
static inline int frames_at(const frames_range_t *r, int i) { return r->first + i * r->step; }

/* 1 when `path` holds a '#' run, $F or $Fn. */
int frames_has_pattern(const char *path);

/* Writes `pattern` with every frame pattern replaced by `frame` into out.
 * A path without a pattern is copied as it is. BK_ERR_INPUT when the result
 * does not fit in len bytes. */
int frames_expand(const char *pattern, int frame, char *out, size_t len, bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
