/* cmdline.h: getopt_long for the `baker` subcommands, with the project's
 * messages instead of getopt's.
 *
 * In: argv (argv[0] is the subcommand), the short and long option tables.
 * Out: one option or positional argument per call, in command-line order
 * (no permutation), `--opt=value` and `--opt value` alike. Long options must
 * be spelled in full (no abbreviations), so adding an option never changes
 * what an existing command line means. The flags shared by every command
 * (--progress[=json], -q/--quiet, -v/--verbose, --threads N, --log FILE)
 * are taken here (bk_common_option, bk_set_threads, bk_log_open); the caller sees -h/--help and --version as codes.
 * On a bad option the message (as "--photons needs a value (see baker bake
 * --help)") lands in err and the caller exits with BK_ERR_INPUT. */
#ifndef BAKER_CMDLINE_H
#define BAKER_CMDLINE_H

#include <getopt.h>

#include "base/common.h"

/* codes cmd_next returns besides an option's own value */
enum {
  CMD_END = -1,          /* no arguments left */
  CMD_ERROR = -2,        /* err holds the message */
  CMD_POSITIONAL = 1,    /* p->arg is a non-option argument */
  CMD_HELP = 'h',
  CMD_VERSION = 0x100,   /* values of long-only options start here */
  CMD_PROGRESS,
  CMD_THREADS,
  CMD_LOG,
  CMD_FIRST_OWN          /* first value free for a command's long-only options */
};

/* Every command's long options end with these (then a zero entry). */
#define CMD_COMMON_LONGOPTS                                   \
  {"help", no_argument, NULL, CMD_HELP},                      \
  {"version", no_argument, NULL, CMD_VERSION},                \
  {"progress", optional_argument, NULL, CMD_PROGRESS},        \
  {"threads", required_argument, NULL, CMD_THREADS},          \
  {"log", required_argument, NULL, CMD_LOG},                  \
  {"quiet", no_argument, NULL, 'q'},                          \
  {"verbose", no_argument, NULL, 'v'}
/* ...and their short options end with these */
#define CMD_COMMON_SHORTOPTS "hqv"

typedef struct cmd_parser {
  int argc;
  char **argv;
  const char *command;           /* "bake": messages point to `baker bake --help` */
  const char *shortopts;         /* getopt form, without the leading "-:" */
  const struct option *longopts; /* zero-terminated */
  const char *opt;               /* the option as typed, less any "=value" (messages) */
  const char *arg;               /* its value, or the positional argument */
  int rest;                      /* after "--": index of the next argument */
  char opt_buf[128];
} cmd_parser_t;

void cmd_begin(cmd_parser_t *p, int argc, char **argv, const char *command,
               const char *shortopts, const struct option *longopts);
/* The next option's value (its short letter or long value), CMD_POSITIONAL,
 * CMD_HELP, CMD_VERSION, CMD_END, or CMD_ERROR with err set (BK_ERR_INPUT). */
int cmd_next(cmd_parser_t *p, bk_error_t *err);
/* "baker VERSION" on stdout, as `baker --version`. */
void cmd_print_version(void);

/* Whole-string numbers for option values: 0 on junk, overflow or (floats)
 * a value that is not finite. */
int cmd_parse_ll(const char *s, long long *out);
int cmd_parse_float(const char *s, float *out);

#endif
