/* vdbio_isolate.cpp: every VDB read runs in a child process (fork) with
 * memory and time limits (isolate.h), and hands its result back through a
 * pipe (a dense grid's values through shared memory).
 *
 * Why a child rather than checking declared sizes before OpenVDB allocates:
 * the sizes are not the only danger. Corrupt blosc data makes OpenVDB's
 * bloscFromStream write past a heap buffer (issue 17): a memory-corrupting
 * bug inside the library, which no check of ours in front of it can rule
 * out for every byte it will decode (zip and blosc streams, metadata strings,
 * node masks, NanoVDB's conversion), and the next such bug would be found
 * the same way. A child confines whatever happens: a crash is a signal, an
 * absurd allocation fails at the child's RLIMIT_AS, a loop ends at its
 * alarm, and this process only ever sees a status, a message and arrays it
 * checks before allocating. The cost is one fork per read and the hand-over
 * of the result: a dense grid's values in shared memory (a memfd the parent
 * maps, below), anything else through a pipe. Several grids of one file may
 * be read side by side (iso_run_all, one child per core, each answer taken
 * as it comes); a child that dies then is read again alone before the file
 * is called corrupt, since the children together may have held more than
 * the machine.
 *
 * The child, its limits and the pipe: isolate.cpp.
 *
 * Caveat: the child of a process that already ran TBB work inherits TBB's
 * state without its worker threads (a multi-frame bake with a VDB medium
 * forks after frame 1's write). Not yet tested; the alarm bounds a hang. */
#include "vdbio_iso.h"

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include <fcntl.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

/* OpenVDB has parsed the metadata and turns to the trees (vdbio_internal.h). */
void vdbio_trees_next(void) {
  iso_lift_parse_limit();
}

/* --- dense results in shared memory ---------------------------------------------- */

/* A dense grid's values travel in a memfd made before the fork: the child's
 * reader writes them straight into it (vdbio_dense_room) and the parent maps
 * the same pages. Through the pipe a grid was copied twice and faulted into
 * fresh pages of the parent, which took the parent 35 ms for a 24 MB grid.
 * Where memfd_create is refused, the pipe carries them as before. */
static int iso_room_fd = -1; /* in the child: its job's memfd */
static float *iso_room_at = nullptr;

static float *iso_room(size_t bytes) {
  if (iso_room_at || ftruncate(iso_room_fd, (off_t)bytes) != 0)
    return nullptr; /* one array per job */
  void *p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, iso_room_fd, 0);
  return iso_room_at = p == MAP_FAILED ? nullptr : static_cast<float *>(p);
}

static void iso_room_trim(size_t bytes) {
  if (ftruncate(iso_room_fd, (off_t)bytes) != 0)
    iso_room_at = nullptr; /* not sent as in the room: the parent would find another size */
}

float *(*vdbio_dense_room)(size_t bytes) = nullptr;
void (*vdbio_dense_room_trim)(size_t bytes) = nullptr;

/* The parent's mappings, for vdbio_array_free. */
static std::mutex iso_maps_lock;
static std::unordered_map<void *, size_t> iso_maps;

/* The child's `bytes` of values in `fd`, mapped; NULL when the file is not
 * exactly that long. Sealed first, so that no process can shrink it under
 * the mapping (a read past its end would be SIGBUS). */
static float *iso_room_map(int fd, size_t bytes) {
  struct stat s;
  if (fcntl(fd, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW) != 0 || fstat(fd, &s) != 0 ||
      (uint64_t)s.st_size != (uint64_t)bytes)
    return nullptr;
  void *p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_POPULATE, fd, 0);
  if (p == MAP_FAILED)
    return nullptr;
  std::lock_guard<std::mutex> g(iso_maps_lock);
  iso_maps[p] = bytes;
  return static_cast<float *>(p);
}

void vdbio_array_free(float *p) {
  if (!p)
    return;
  size_t bytes = 0;
  {
    std::lock_guard<std::mutex> g(iso_maps_lock);
    auto it = iso_maps.find(p);
    if (it != iso_maps.end())
      bytes = it->second, iso_maps.erase(it);
  }
  if (bytes)
    munmap(p, bytes);
  else
    free(p);
}

/* --- the readers of vdbio.h ----------------------------------------------------- */

/* A dense grid: its description, then its values. */
struct iso_dense_job : iso_job {
  const char *path, *name;
  int pad;
  const vdbio_dense_t *like; /* NULL: read over its own box */
  vdbio_dense_t *out;
  int want_check, checked = 0, found = 0;
  int grey = 0; /* a Vec3f grid may come back as one channel (vdbio.h) */
  int room = -1; /* the memfd the values travel in, or -1: the pipe */

  ~iso_dense_job() override {
    if (room >= 0)
      close(room);
  }
  void prepare() override { /* a new one per child: one that died may have left values */
    if (room >= 0)
      close(room);
    room = memfd_create("baker-vdb-grid", MFD_CLOEXEC | MFD_ALLOW_SEALING);
  }
  int work(bk_error_t *err) override {
    if (room >= 0)
      iso_room_fd = room, vdbio_dense_room = iso_room, vdbio_dense_room_trim = iso_room_trim;
    if (like)
      return vdbio_read_dense_like_direct(path, name, like, out, &found, err);
    found = 1;
    return vdbio_read_dense_direct(path, name, pad, out, want_check ? &checked : NULL, grey, err);
  }
  bool send(int fd) override {
    const int32_t in_room = found && out->data && out->data == iso_room_at;
    int32_t flags[3] = {found, checked, in_room};
    if (!iso_write(fd, flags, sizeof flags) || !iso_write(fd, out, sizeof *out))
      return false;
    const size_t n = (size_t)out->nx * out->ny * out->nz * out->channels;
    return !found || in_room || iso_write(fd, out->data, n * sizeof(float));
  }
  int recv(int fd, bk_error_t *err) override {
    int32_t flags[3];
    if (!iso_read(fd, flags, sizeof flags) || !iso_read(fd, out, sizeof *out))
      return -1;
    out->data = NULL;
    found = flags[0] != 0;
    checked = flags[1] != 0;
    if (!found)
      return BK_OK;
    const int d[3] = {out->nx, out->ny, out->nz};
    for (int a = 0; a < 3; a++)
      if (d[a] < 1 || d[a] > GRID_MAX_AXIS)
        return -1; /* the child's own checks allow no such box */
    if (out->channels != 1 && out->channels != 3)
      return -1;
    grid_dims_t gd;
    memset(&gd, 0, sizeof gd);
    gd.nx = d[0];
    gd.ny = d[1];
    gd.nz = d[2];
    const std::string where = std::string(path) + ": grid \"" + name + "\"";
    int rc = grid_check_memory(&gd, sizeof(float) * (size_t)out->channels, where.c_str(), err);
    if (rc)
      return rc;
    const size_t n = grid_count(&gd) * (size_t)out->channels;
    if (flags[2]) { /* in the memfd: mapped, or the child broke the protocol */
      if (room < 0 || !(out->data = iso_room_map(room, n * sizeof(float))))
        return -1;
      return BK_OK;
    }
    out->data = (float *)bk_calloc(n, sizeof(float), where.c_str(), err);
    if (!out->data)
      return BK_ERR_RUNTIME;
    if (iso_read(fd, out->data, n * sizeof(float)))
      return BK_OK;
    vdbio_dense_free(out);
    return -1;
  }
};

static int iso_dense(iso_dense_job &job, vdbio_dense_t *out, bk_error_t *err) {
  memset(out, 0, sizeof *out);
  job.out = out;
  int rc = iso_run(job, job.path, err);
  if (rc)
    vdbio_dense_free(out);
  return rc;
}

int vdbio_read_dense_verified(const char *path, const char *grid_name, int pad,
                              vdbio_dense_t *out, int *checked, bk_error_t *err) {
  if (!path || !grid_name || !out)
    return bk_fail(err, BK_ERR_RUNTIME, "vdbio_read_dense: invalid arguments");
  iso_dense_job job;
  job.path = path;
  job.name = grid_name;
  job.pad = pad;
  job.like = NULL;
  job.want_check = checked != NULL;
  int rc = iso_dense(job, out, err);
  if (checked)
    *checked = job.checked;
  return rc;
}

/* The job whose child has its answer ready (its pipe readable: a child
 * writes only once its work is done, or dies), among those running below
 * `limit`; the lowest such index when several are. */
static int iso_ready(const std::vector<iso_started> &st, int limit) {
  std::vector<pollfd> fds;
  std::vector<int> job;
  for (int j = 0; j < limit; j++)
    if (st[(size_t)j].pid > 0)
      fds.push_back(pollfd{st[(size_t)j].fd, POLLIN, 0}), job.push_back(j);
  while (poll(fds.data(), fds.size(), -1) < 0 && errno == EINTR) {
  }
  for (size_t k = 0; k < fds.size(); k++)
    if (fds[k].revents)
      return job[k];
  return job[0]; /* poll failed otherwise: wait on the first, as a blocking read does */
}

/* Jobs [0, count) with at most `width` children at work, each answer taken
 * as soon as it is ready and the next job started in its place, so small
 * grids are read beside a large one. The answer is the first failure in list
 * order: once job i has failed, jobs after it are ended and only those
 * before it still waited for. A child that died (a signal, e.g. the
 * kernel's out-of-memory killer when children beside it held memory too)
 * is read again alone before the file is called corrupt, and the rest then
 * one at a time. */
static int iso_run_all(iso_job *const *jobs, int count, int width, const char *path,
                       void (*meanwhile)(void *), void *ctx, bk_error_t *err) {
  std::vector<iso_started> st((size_t)count);
  std::vector<char> done((size_t)count, 0);
  int limit = count, running = 0, rc = BK_OK;
  for (;;) {
    for (int j = 0; j < limit && running < width && !rc; j++)
      if (!done[(size_t)j] && st[(size_t)j].pid <= 0) {
        /* each child's own: the address space it starts with holds the
         * grids mapped since the last one started */
        st[(size_t)j].limits = iso_limits_for(*jobs[j], path);
        rc = iso_start(*jobs[j], path, st[(size_t)j].limits, &st[(size_t)j], err);
        running += !rc;
      }
    if (rc || !running)
      break;
    if (meanwhile) /* once, while the first readers work; no fork during it */
      meanwhile(ctx), meanwhile = NULL;
    const int i = iso_ready(st, limit);
    bk_error_t e;
    e.code = BK_OK;
    e.msg[0] = 0;
    bool died = false;
    const int r = iso_parent(*jobs[i], st[(size_t)i].fd, st[(size_t)i].pid, path,
                             st[(size_t)i].limits, &e, &died);
    close(st[(size_t)i].fd);
    st[(size_t)i] = iso_started();
    running--;
    if (r && died && width > 1) { /* again alone, and the rest one at a time */
      for (int j = 0; j < count; j++)
        if (st[(size_t)j].pid > 0)
          iso_abandon(&st[(size_t)j]), running--;
      width = 1;
      continue;
    }
    done[(size_t)i] = 1;
    if (r) { /* the first failure so far in list order: the later jobs no longer matter */
      *err = e;
      limit = i;
      for (int j = i + 1; j < count; j++)
        if (st[(size_t)j].pid > 0)
          iso_abandon(&st[(size_t)j]), running--;
    }
  }
  for (int j = 0; j < count; j++)
    iso_abandon(&st[(size_t)j]);
  return rc ? rc : limit < count ? err->code : BK_OK;
}

int vdbio_read_dense_verified_all(const char *path, int count, const char *const *names,
                                  const int *grey, vdbio_dense_t *outs, int *checked,
                                  void (*meanwhile)(void *ctx), void *ctx, bk_error_t *err) {
  if (!path || count < 0 || (count && (!names || !outs || !checked)))
    return bk_fail(err, BK_ERR_RUNTIME, "vdbio_read_dense_verified_all: invalid arguments");
  std::vector<iso_dense_job> jobs((size_t)count);
  std::vector<iso_job *> ptr((size_t)count);
  for (int i = 0; i < count; i++) {
    memset(&outs[i], 0, sizeof outs[i]);
    iso_dense_job &j = jobs[(size_t)i];
    j.path = path;
    j.name = names[i];
    j.pad = 0;
    j.like = NULL;
    j.want_check = 1;
    j.grey = grey && grey[i];
    j.out = &outs[i];
    ptr[(size_t)i] = &j;
  }
  /* one child per core: each grid's decode, copy and checksum beside the others */
  const long cpus = sysconf(_SC_NPROCESSORS_ONLN);
  const int width = cpus < 1 ? 1 : cpus > count ? count : (int)cpus;
  const int rc = iso_run_all(ptr.data(), count, width < 1 ? 1 : width, path, meanwhile, ctx, err);
  for (int i = 0; i < count; i++) {
    checked[i] = jobs[(size_t)i].checked;
    if (rc)
      vdbio_dense_free(&outs[i]);
  }
  return rc;
}

int vdbio_read_dense(const char *path, const char *grid_name, int pad, vdbio_dense_t *out,
                     bk_error_t *err) {
  return vdbio_read_dense_verified(path, grid_name, pad, out, NULL, err);
}

int vdbio_read_dense_like(const char *path, const char *grid_name, const vdbio_dense_t *like,
                          vdbio_dense_t *out, int *found, bk_error_t *err) {
  if (!path || !grid_name || !like || !out || !found)
    return bk_fail(err, BK_ERR_RUNTIME, "vdbio_read_dense_like: invalid arguments");
  iso_dense_job job;
  job.path = path;
  job.name = grid_name;
  job.pad = 0;
  job.like = like;
  job.want_check = 0;
  int rc = iso_dense(job, out, err);
  *found = rc ? 0 : job.found;
  return rc;
}

/* A float grid resampled into the caller's array. */
struct iso_array_job : iso_fill_job {
  const char *path, *name, *where;
  const grid_dims_t *dims;
  size_t bytes() const override { return grid_count(dims) * sizeof(float); }
  int work(bk_error_t *err) override {
    return vdbio_resample_float_direct(path, name, dims, out, where, err);
  }
};

int vdbio_resample_float(const char *path, const char *grid_name, const grid_dims_t *dims,
                         float *out, const char *where, bk_error_t *err) {
  if (!path || !dims || !out || dims->nx < 1 || dims->ny < 1 || dims->nz < 1)
    return vdbio_resample_float_direct(path, grid_name, dims, out, where, err); /* its message */
  iso_array_job job;
  job.path = path;
  job.name = grid_name;
  job.where = where;
  job.dims = dims;
  job.out = out;
  return iso_run(job, path, err);
}
