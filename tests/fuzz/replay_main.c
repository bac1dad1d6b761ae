/* replay_main.c: a main() for a fuzz target built without libFuzzer (any C
 * compiler, the normal build): runs each file named on the command line
 * through LLVMFuzzerTestOneInput once, so saved crash inputs are replayed by
 * the ordinary test suite (ctest fuzz_replay_*) even where clang's libFuzzer
 * is missing. Each input gets the bounds libFuzzer runs it under: a watchdog
 * fails the replay when one takes over 10 s, or the process's resident
 * memory passes 1 GiB (a reader that loops or allocates without end fails
 * at once instead of hanging the suite). Exit 0 when every input returned
 * within them; a crash is the test failing too. */
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <unistd.h>

#define REPLAY_MAX_SECONDS 10.0
#define REPLAY_MAX_RSS_MIB 1024.0

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const char *volatile current; /* the input being replayed, for the watchdog */
static volatile double started;      /* when it started, seconds */

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Resident memory of this process, MiB (/proc/self/statm; 0 where unread). */
static double rss_mib(void) {
  long pages = 0, resident = 0;
  FILE *f = fopen("/proc/self/statm", "r");
  if (f) {
    if (fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
    fclose(f);
  }
  return (double)resident * (double)sysconf(_SC_PAGESIZE) / (1024.0 * 1024.0);
}

static void *watchdog(void *arg) {
  (void)arg;
  for (;;) {
    usleep(50 * 1000);
    const char *path = current;
    if (!path) continue;
    const double s = now_s() - started, mib = rss_mib();
    if (s > REPLAY_MAX_SECONDS || mib > REPLAY_MAX_RSS_MIB) {
      printf("FAIL: %s: %.1f s and %.0f MiB resident so far (bounds %.0f s, %.0f MiB)\n", path,
             s, mib, REPLAY_MAX_SECONDS, REPLAY_MAX_RSS_MIB);
      fflush(stdout);
      _exit(1);
    }
  }
  return NULL;
}

static int replay(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) {
    perror(path);
    return 1;
  }
  size_t cap = 1 << 16, n = 0, got;
  uint8_t *buf = malloc(cap);
  while (buf && (got = fread(buf + n, 1, cap - n, f)) > 0) {
    n += got;
    if (n == cap) buf = realloc(buf, cap *= 2);
  }
  fclose(f);
  if (!buf) return 1;
  started = now_s();
  current = path;
  LLVMFuzzerTestOneInput(buf, n);
  current = NULL;
  free(buf);
  printf("replayed %s (%zu bytes) in %.3f s\n", path, n, now_s() - started);
  return 0;
}

int main(int argc, char **argv) {
  LLVMFuzzerInitialize(&argc, &argv);
  pthread_t dog;
  if (pthread_create(&dog, NULL, watchdog, NULL) != 0) {
    perror("replay: watchdog thread");
    return 1;
  }
  int bad = 0;
  for (int i = 1; i < argc; i++) bad |= replay(argv[i]);
  return bad;
}
