/* test_frames.c: frame lists in fileseq/Deadline/OpenJD syntax (base/frames):
 * every form, the order and de-duplication rule, and the refusals. */
#include <stdio.h>
#include <string.h>

#include "base/frames.h"

static int failures;

/* spec must parse to exactly the frames `want` (n of them) */
static void expect_list(const char *spec, const int *want, int n) {
  frames_list_t l;
  bk_error_t err = {0, ""};
  if (frames_parse_list(spec, "--frames", &l, &err)) {
    printf("FAIL %s: refused: %s\n", spec, err.msg);
    failures++;
    return;
  }
  int ok = l.count == n;
  for (int i = 0; ok && i < n; i++) ok = l.frames[i] == want[i];
  if (!ok) {
    printf("FAIL %s: got %d frames:", spec, l.count);
    for (int i = 0; i < l.count && i < 20; i++) printf(" %d", l.frames[i]);
    printf("\n");
    failures++;
  }
  frames_list_free(&l);
}

/* spec must be refused with BK_ERR_INPUT and a message holding `needle` */
static void expect_refused(const char *spec, const char *needle) {
  frames_list_t l;
  bk_error_t err = {0, ""};
  int rc = frames_parse_list(spec, "--frames", &l, &err);
  if (rc != BK_ERR_INPUT || !strstr(err.msg, needle) || !strstr(err.msg, "--frames")) {
    printf("FAIL %s: rc %d, message \"%s\" (expected exit 2 naming \"%s\")\n", spec, rc, err.msg,
           needle);
    failures++;
  }
}

int main(void) {
  expect_list("7", (int[]){7}, 1);
  expect_list("1-4", (int[]){1, 2, 3, 4}, 4);
  expect_list("1-9x3", (int[]){1, 4, 7}, 3);
  expect_list("1-9X3", (int[]){1, 4, 7}, 3);
  expect_list("1-9:4", (int[]){1, 5, 9}, 3);
  expect_list("-3--1", (int[]){-3, -2, -1}, 3);
  expect_list("1-3,7,10-20x5", (int[]){1, 2, 3, 7, 10, 15, 20}, 7);
  expect_list("1-20:8, 3", (int[]){1, 9, 17, 3}, 4);
  /* the given order, each frame once at its first place */
  expect_list("10,1-3,2,10,1", (int[]){10, 1, 2, 3}, 4);
  expect_list("5-6,1-6", (int[]){5, 6, 1, 2, 3, 4}, 6);
  expect_refused("", "element \"\"");
  expect_refused("1,,3", "element \"\"");
  expect_refused("1-3,", "element \"\"");
  expect_refused("1-3,a", "element \"a\"");
  expect_refused("1-5y2", "element \"1-5y2\"");
  expect_refused("1-", "element \"1-\"");
  expect_refused("5-1", "ends (1) before it starts (5)");
  expect_refused("1-5x0", "step must be >= 1");
  expect_refused("1-5:-2", "step must be >= 1");
  expect_refused("1-2000000", "more than");
  expect_refused("1-600000,700000-1300000", "more than");
  expect_refused("99999999999", "element");
  if (!failures) printf("frames: ok\n");
  return failures != 0;
}
