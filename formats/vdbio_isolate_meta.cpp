/* vdbio_isolate_meta.cpp: the small isolated readers of vdbio.h, each a
 * job for a limited child (vdbio_isolate.cpp says why): grid names and
 * types, one metadata value, all file metadata, an exact box of a grid, and
 * `verify`'s per-grid checksums. */
#include "vdbio_iso.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

/* The grid names and types. */
struct iso_list_job : iso_job {
  const char *path;
  char **names = NULL, **types = NULL;
  int count = 0;
  std::vector<std::string> n, t;
  int work(bk_error_t *err) override {
    return vdbio_list_grids_direct(path, &names, &types, &count, err);
  }
  bool send(int fd) override {
    int32_t c = count;
    bool ok = iso_write(fd, &c, sizeof c);
    for (int i = 0; ok && i < count; i++)
      ok = iso_write_string(fd, names[i]) && iso_write_string(fd, types[i]);
    return ok;
  }
  int recv(int fd, bk_error_t *) override {
    int32_t c;
    if (!iso_read(fd, &c, sizeof c) || c < 0 || c > (1 << 20))
      return -1;
    n.resize((size_t)c);
    t.resize((size_t)c);
    for (int32_t i = 0; i < c; i++)
      if (!iso_read_string(fd, n[i], 1u << 16) || !iso_read_string(fd, t[i], 1u << 16))
        return -1;
    return BK_OK;
  }
};

int vdbio_list_grids(const char *path, char ***names, char ***types, int *count, bk_error_t *err) {
  if (!path || !names || !count)
    return bk_fail(err, BK_ERR_RUNTIME, "vdbio_list_grids: invalid arguments");
  *names = NULL;
  if (types)
    *types = NULL;
  *count = 0;
  iso_list_job job;
  job.path = path;
  int rc = iso_run(job, path, err);
  if (rc)
    return rc;
  const size_t c = job.n.size();
  char **n = (char **)bk_calloc(c ? c : 1, sizeof(char *), path, err);
  char **t = (char **)bk_calloc(c ? c : 1, sizeof(char *), path, err);
  bool ok = n && t;
  for (size_t i = 0; ok && i < c; i++)
    ok = (n[i] = strdup(job.n[i].c_str())) && (t[i] = strdup(job.t[i].c_str()));
  if (!ok) {
    vdbio_free_names(n, t, n && t ? (int)c : 0);
    return bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory listing grids", path);
  }
  *names = n;
  *count = (int)c;
  if (types)
    *types = t;
  else
    vdbio_free_names(NULL, t, (int)c);
  return BK_OK;
}

/* One metadata value as text, into the caller's buffer. */
struct iso_meta_job : iso_job {
  const char *path, *key;
  char *out;
  size_t len;
  int work(bk_error_t *err) override { return vdbio_read_meta_direct(path, key, out, len, err); }
  bool send(int fd) override { return iso_write_string(fd, out); }
  int recv(int fd, bk_error_t *) override {
    std::string s;
    if (!iso_read_string(fd, s, (uint32_t)len))
      return -1;
    snprintf(out, len, "%s", s.c_str());
    return BK_OK;
  }
};

int vdbio_read_meta(const char *path, const char *key, char *out, size_t len, bk_error_t *err) {
  if (!path || !key || !out || len == 0)
    return bk_fail(err, BK_ERR_RUNTIME, "vdbio_read_meta: invalid arguments");
  out[0] = 0;
  iso_meta_job job;
  job.path = path;
  job.key = key;
  job.out = out;
  job.len = len;
  return iso_run(job, path, err);
}

/* An exact box of a grid into the caller's array (vdbio_box.cpp). */
struct iso_box_job : iso_fill_job {
  const char *path, *name;
  const grid_dims_t *dims;
  int channels;
  size_t bytes() const override { return grid_count(dims) * (size_t)channels * sizeof(float); }
  int work(bk_error_t *err) override {
    return vdbio_read_box_direct(path, name, dims, channels, out, err);
  }
};

int vdbio_read_box(const char *path, const char *grid_name, const grid_dims_t *dims, int channels,
                   float *out, bk_error_t *err) {
  if (!path || !grid_name || !dims || !out || (channels != 1 && channels != 3) || dims->nx < 1 ||
      dims->ny < 1 || dims->nz < 1)
    return bk_fail(err, BK_ERR_RUNTIME, "vdbio_read_box: invalid arguments");
  iso_box_job job;
  job.path = path;
  job.name = grid_name;
  job.dims = dims;
  job.channels = channels;
  job.out = out;
  return iso_run(job, path, err);
}

/* The file metadata, entry by entry. */
struct iso_meta_all_job : iso_job {
  const char *path;
  vdbio_meta_entry_t *entries = NULL;
  int count = 0;
  int work(bk_error_t *err) override {
    return vdbio_read_meta_all_direct(path, &entries, &count, err);
  }
  bool send(int fd) override {
    int32_t c = count;
    return iso_write(fd, &c, sizeof c) &&
           iso_write(fd, entries, (size_t)count * sizeof(vdbio_meta_entry_t));
  }
  int recv(int fd, bk_error_t *err) override {
    int32_t c;
    if (!iso_read(fd, &c, sizeof c) || c < 0 || c > (1 << 16))
      return -1;
    entries = (vdbio_meta_entry_t *)bk_calloc(c ? (size_t)c : 1, sizeof *entries, path, err);
    if (!entries)
      return BK_ERR_RUNTIME;
    count = c;
    if (!iso_read(fd, entries, (size_t)c * sizeof *entries))
      return -1;
    for (int i = 0; i < c; i++) { /* the child is trusted with nothing */
      if (entries[i].kind != VDBIO_META_STRING && entries[i].kind != VDBIO_META_INT &&
          entries[i].kind != VDBIO_META_FLOAT)
        return -1;
      entries[i].key[sizeof entries[i].key - 1] = 0;
      entries[i].value[sizeof entries[i].value - 1] = 0;
    }
    return BK_OK;
  }
};

int vdbio_read_meta_all(const char *path, vdbio_meta_entry_t **entries, int *count,
                        bk_error_t *err) {
  if (!path || !entries || !count)
    return bk_fail(err, BK_ERR_RUNTIME, "vdbio_read_meta_all: invalid arguments");
  iso_meta_all_job job;
  job.path = path;
  int rc = iso_run(job, path, err);
  if (rc) {
    free(job.entries);
    job.entries = NULL;
    job.count = 0;
  }
  *entries = job.entries;
  *count = job.count;
  return rc;
}

/* One grid's verdict (vdbio_checksum.cpp), each grid in a child of its own:
 * a grid whose reading crashes, loops or asks for absurd memory is that
 * grid's corruption, and the others are still checked. */
struct iso_verify_job : iso_job {
  const char *path, *name;
  vdbio_verify_grid_t out;
  int work(bk_error_t *err) override { return vdbio_verify_grid_direct(path, name, &out, err); }
  bool send(int fd) override { return iso_write(fd, &out, sizeof out); }
  int recv(int fd, bk_error_t *) override {
    if (!iso_read(fd, &out, sizeof out))
      return -1;
    if (out.status != VDBIO_VERIFY_OK && out.status != VDBIO_VERIFY_CORRUPT &&
        out.status != VDBIO_VERIFY_UNCHECKED)
      return -1;
    out.name[sizeof out.name - 1] = 0;
    out.detail[sizeof out.detail - 1] = 0;
    return BK_OK;
  }
};

int vdbio_verify(const char *path, vdbio_verify_grid_t **grids, int *count, bk_error_t *err) {
  char **names = NULL;
  int n = 0;
  *grids = NULL;
  *count = 0;
  int rc = vdbio_list_grids(path, &names, NULL, &n, err);
  if (rc)
    return rc;
  vdbio_verify_grid_t *g =
      (vdbio_verify_grid_t *)bk_calloc(n ? (size_t)n : 1, sizeof *g, path, err);
  for (int i = 0; g && i < n; i++) {
    iso_verify_job job;
    memset(&job.out, 0, sizeof job.out);
    job.path = path;
    job.name = names[i];
    bk_error_t e;
    memset(&e, 0, sizeof e);
    if (iso_run(job, path, &e) == BK_OK) {
      g[i] = job.out;
      continue;
    }
    snprintf(g[i].name, sizeof g[i].name, "%s", names[i]);
    g[i].status = VDBIO_VERIFY_CORRUPT;
    snprintf(g[i].detail, sizeof g[i].detail, "%.500s", e.msg);
  }
  vdbio_free_names(names, NULL, n);
  if (!g)
    return BK_ERR_RUNTIME;
  *grids = g;
  *count = n;
  return BK_OK;
}
