/* cmdline.c: getopt_long with the project's messages; see cmdline.h. */
#include "cmdline.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"

#define CMD_SHORTOPTS_MAX 64

void cmd_begin(cmd_parser_t *p, int argc, char **argv, const char *command,
               const char *shortopts, const struct option *longopts) {
  memset(p, 0, sizeof *p);
  p->argc = argc;
  p->argv = argv;
  p->command = command;
  p->shortopts = shortopts;
  p->longopts = longopts;
  /* the commands run more than once in one process (the tests call
   * view_main repeatedly): 0 makes glibc's getopt start afresh */
  optind = 0;
  opterr = 0;
}

/* 1 when tok ("--name" or "--name=value") spells the long option in full. */
static int spelled_in_full(const char *tok, const char *name) {
  if (strncmp(tok, "--", 2) != 0) return 1; /* a short option */
  size_t n = strcspn(tok + 2, "=");
  return strlen(name) == n && strncmp(tok + 2, name, n) == 0;
}

static int unknown(cmd_parser_t *p, const char *typed, bk_error_t *err) {
  return bk_fail(err, BK_ERR_INPUT, "unknown option '%s' (see baker %s --help)", typed,
                 p->command), CMD_ERROR;
}

/* The shared options that take a value: --progress[=json], --threads N,
 * --log FILE. */
static int common_value(cmd_parser_t *p, int c, bk_error_t *err) {
  const char *v = p->arg;
  if (c == CMD_PROGRESS) {
    if (v && strcmp(v, "json") != 0)
      return bk_fail(err, BK_ERR_INPUT, "--progress=%s: expected --progress or --progress=json", v);
    bk_common_option(v ? "--progress=json" : "--progress");
    return BK_OK;
  }
  if (c == CMD_LOG) return bk_log_open(v, err);
  char *end;
  errno = 0;
  long n = strtol(v, &end, 10);
  if (errno || end == v || *end || n < 1 || n > 4096)
    return bk_fail(err, BK_ERR_INPUT, "--threads: expected a thread count in 1..4096, got '%s'",
                   v);
  bk_set_threads((int)n);
  return BK_OK;
}

int cmd_next(cmd_parser_t *p, bk_error_t *err) {
  /* "-": arguments in order, as code 1; ":": a missing value is ':' */
  char shortopts[CMD_SHORTOPTS_MAX];
  snprintf(shortopts, sizeof shortopts, "-:%s", p->shortopts);
  if (p->rest > 0) { /* after "--": the rest are arguments */
    if (p->rest >= p->argc) return CMD_END;
    p->arg = p->argv[p->rest++];
    return CMD_POSITIONAL;
  }
  for (;;) {
    int tok = optind > 0 ? optind : 1, index = -1;
    int c = getopt_long(p->argc, p->argv, shortopts, p->longopts, &index);
    const char *typed = tok < p->argc ? p->argv[tok] : "";
    size_t n = strncmp(typed, "--", 2) == 0 ? strcspn(typed, "=") : strlen(typed);
    snprintf(p->opt_buf, sizeof p->opt_buf, "%.*s", (int)n, typed);
    p->opt = p->opt_buf;
    p->arg = optarg;
    if (c == -1) {
      p->rest = optind > 0 ? optind : p->argc; /* getopt stops at "--" or the end */
      return cmd_next(p, err);
    }
    if (c == 1) return CMD_POSITIONAL;
    if (c == '?') return unknown(p, typed, err);
    if (index >= 0 && !spelled_in_full(typed, p->longopts[index].name))
      return unknown(p, typed, err);
    if (c == ':') {
      int known = strncmp(typed, "--", 2) != 0; /* glibc leaves index unset here */
      for (const struct option *o = p->longopts; o->name && !known; o++)
        known = spelled_in_full(typed, o->name);
      if (!known) return unknown(p, typed, err);
      return bk_fail(err, BK_ERR_INPUT, "%s needs a value (see baker %s --help)", p->opt,
                     p->command), CMD_ERROR;
    }
    if (c == CMD_PROGRESS || c == CMD_THREADS || c == CMD_LOG) {
      if (common_value(p, c, err)) return CMD_ERROR;
    } else if (c == 'q') bk_common_option("-q");
    else if (c == 'v') bk_common_option("-v");
    else return c;
  }
}

void cmd_print_version(void) { printf("baker %s\n", BAKER_VERSION); }

int cmd_parse_ll(const char *s, long long *out) {
  char *end;
  errno = 0;
  long long v = strtoll(s, &end, 10);
  if (errno || end == s || *end) return 0;
  *out = v;
  return 1;
}

int cmd_parse_float(const char *s, float *out) {
  char *end;
  errno = 0;
  float v = strtof(s, &end);
  if (end == s || *end != 0 || errno == ERANGE || !isfinite(v)) return 0;
  *out = v;
  return 1;
}
