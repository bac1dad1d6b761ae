/* vdbio.h: OpenVDB files, behind a C interface.
 *
 * Writing: dense x-fastest arrays on a grid_dims_t become sparse grids (voxels
 * at zero left inactive, then the background set to the grid's value outside
 * the box) with a linear, cell-centred transform: index (i,j,k) maps to the
 * centre of our voxel (i,j,k). Float grids are fog volumes; Vec3f grids have
 * no class (NanoVDB allows fog volumes of scalars only) and vector_type
 * invariant. A path ending in ".nvdb" is written as NanoVDB (nvdbio.cpp),
 * which keeps the grids but not the file metadata. The file is written under
 * a temporary name and renamed.
 *
 * Reading: a grid from any file (ours or another tool's) is resampled
 * trilinearly through its own transform, either at the voxel centres of one of
 * our grids (ior_vdb, density_vdb) or densely over its own active bounding box
 * (the viewing pass). ".nvdb" files are read through NanoVDB's conversion
 * back to OpenVDB grids, so every reader takes both. Corrupt or truncated files, missing grids and grids of
 * the wrong type are BK_ERR_INPUT with a message naming the file and grid.
 *
 * Every reader parses the file in a child process with memory and time
 * limits (vdbio_isolate.cpp): a file that crashes OpenVDB, exhausts the
 * memory this process may use or takes too long is BK_ERR_INPUT, and this
 * process is untouched. */
#ifndef BAKER_VDBIO_H
#define BAKER_VDBIO_H

#include "base/grid.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Whether a path asks for NanoVDB: it ends in ".nvdb", in any case. */
int vdbio_is_nano_path(const char *path);

typedef enum { VDBIO_FLOAT = 1, VDBIO_VEC3 = 3 } vdbio_type_t;

/* A grid made on the fly instead of read from a dense array: writes voxels
 * [lo, hi) (x fastest) as (hi - lo) * type floats to out (one float per
 * voxel for a `grey` Vec3 grid). The writer asks for
 * a few z slices at a time, from several threads at once, and for each voxel
 * twice (the slab its tree and checksum are built from, then the rows of the
 * leaves being written), so a derived grid (extinction = σs + σa) never
 * exists whole. */
typedef void (*vdbio_fill_fn)(const void *ctx, size_t lo, size_t hi, float *out);

typedef struct vdbio_grid {
  const char *name;
  vdbio_type_t type;
  const float *data;      /* grid_count(dims) * type floats, or NULL with fill */
  int vector_invariant;   /* Vec3 only: VEC_INVARIANT (radiance, colours) */
  float background;       /* the value outside the grid (every channel); 0 for most */
  vdbio_fill_fn fill;     /* when data is NULL */
  const void *fill_ctx;
  /* Vec3 only: the three channels are equal, and data or fill give one
   * float per voxel, written as (v, v, v): grey light's RGB grids, read and
   * scanned at a third of the bytes */
  int grey;
} vdbio_grid_t;

typedef enum { VDBIO_META_STRING, VDBIO_META_INT, VDBIO_META_FLOAT } vdbio_meta_kind_t;
typedef struct vdbio_meta {
  const char *key;
  vdbio_meta_kind_t kind;
  const char *s;
  long long i;
  double f;
} vdbio_meta_t;

typedef enum { VDBIO_COMPRESS_NONE = 0, VDBIO_COMPRESS_ZIP = 1, VDBIO_COMPRESS_BLOSC = 2 } vdbio_compression_t;
typedef struct vdbio_write_opts {
  vdbio_compression_t compression; /* `baker bake` defaults to blosc */
  int half_float;                  /* save floats as 16-bit */
  /* Optional: called with g, in file order, once grid g's values are read
   * no more (its tree written and its checksum taken), so that the caller
   * may free what no later grid reads. */
  void (*grid_done)(void *ctx, int g);
  void *grid_done_ctx;
} vdbio_write_opts_t;

/* The grids' OpenVDB trees are built and written one at a time, each freed
 * before the next is built, so the write holds one tree beside the arrays.
 * Besides the caller's metadata the file gets "creator", "voxel_centering"
 * and "grid_bounds_min"/"grid_bounds_max" (Vec3d: the world box the voxels
 * cover), unless the caller gave its own. */
int vdbio_write(const char *path, const grid_dims_t *dims, const vdbio_grid_t *grids,
                int grid_count, const vdbio_meta_t *meta, int meta_count,
                const vdbio_write_opts_t *opts, bk_error_t *err);

/* Samples float grid `grid_name` of `path` at every voxel centre of `dims`
 * (world space, trilinear, background outside its active voxels).
 * `where` names the scene key for messages. */
int vdbio_resample_float(const char *path, const char *grid_name, const grid_dims_t *dims,
                         float *out, const char *where, bk_error_t *err);

/* A grid read densely over an index box, with the affine map from that box's
 * indices (cell centres) to world space. */
typedef struct vdbio_dense {
  int nx, ny, nz;
  int channels;                 /* 1 or 3 */
  float *data;                  /* x-fastest, channels interleaved */
  double index_to_world[3][4];  /* world = M * (i, j, k, 1) */
  double world_to_index[3][4];
  int uniform_scale;            /* the map is translation + uniform scale */
  double voxel_size;            /* world length of one index step (uniform) */
} vdbio_dense_t;

/* Lists the grids in a file: fills names (caller frees with vdbio_free_names). */
int vdbio_list_grids(const char *path, char ***names, char ***types, int *count, bk_error_t *err);
void vdbio_free_names(char **names, char **types, int count);

/* Reads `grid_name` densely over its active bounding box (plus `pad` voxels).
 * It must be float or Vec3f (else BK_ERR_INPUT naming the type found). */
int vdbio_read_dense(const char *path, const char *grid_name, int pad, vdbio_dense_t *out,
                     bk_error_t *err);
/* vdbio_read_dense, and the grid's checksum checked when the file records
 * one: *checked = 1 when it was checked (and matched), 0 when the file has
 * none; a mismatch is BK_ERR_INPUT naming the grid. */
int vdbio_read_dense_verified(const char *path, const char *grid_name, int pad,
                              vdbio_dense_t *out, int *checked, bk_error_t *err);
/* vdbio_read_dense_verified of `count` grids over their own boxes (pad 0),
 * read side by side (one reader per core) into outs[i], checked[i]; the
 * first failure in list order is the answer, and then no outs are kept.
 * grey (NULL: none): where grey[i] is set, a Vec3f grid whose three
 * channels hold the same bits in every voxel (grey light) comes back as one
 * channel, outs[i].channels 1 (a third of the memory); any other, as usual.
 * meanwhile (NULL: none) runs once in this process while the first readers
 * work, e.g. the view's OpenCL start-up; no reader is started while it runs,
 * so it may load libraries (a fork during a dlopen is not safe). */
int vdbio_read_dense_verified_all(const char *path, int count, const char *const *names,
                                  const int *grey, vdbio_dense_t *outs, int *checked,
                                  void (*meanwhile)(void *ctx), void *ctx, bk_error_t *err);
/* Reads `grid_name` resampled into the index space of `like` (same box and
 * transform), through its own transform. *found = 0 when the file has no such
 * grid (not an error: callers decide). Float grids give 1 channel, Vec3f 3. */
int vdbio_read_dense_like(const char *path, const char *grid_name, const vdbio_dense_t *like,
                          vdbio_dense_t *out, int *found, bk_error_t *err);
void vdbio_dense_free(vdbio_dense_t *d);
/* Frees an array a reader returned in vdbio_dense_t.data, also once the
 * caller has taken it over: it may be shared memory mapped from the reader's
 * child (vdbio_isolate.cpp), not malloc's. Anything else is free()d. */
void vdbio_array_free(float *p);

/* Checksums (written by vdbio_write, checked by vdbio_verify). The file
 * metadata holds checksum_box = "NX NY NZ" and, per grid, checksum_v2_<name>
 * = 16 hex digits. The grid's values over the index box [0,NX) x [0,NY) x
 * [0,NZ), x fastest then y then z, channels interleaved, are taken as 32-bit
 * words: a value's IEEE-754 bits, or 0 for +-0 and NaN (what an inactive
 * voxel reads back as), with half-float output after rounding to half. Word
 * i goes to lane i mod 8; each lane is a 32-bit FNV-1a (h ^= word; h *=
 * 16777619, from 2166136261). The checksum is the 64-bit FNV-1a (h ^= word;
 * h *= 2^40 + 2^8 + 0xb3, from 14695981039346656037) over the eight lanes,
 * then over the grid's background value (one word per channel, -0 as +0).
 * Files written before this rule hold checksum_<name> instead: the 64-bit
 * FNV-1a over all the words in one chain, a voxel whose channels are all 0
 * or NaN as zeros, -0 as +0, then the background; they are still checked.
 * Outside the box, the grid must hold only its background. */
typedef enum { VDBIO_VERIFY_OK = 0, VDBIO_VERIFY_CORRUPT = 1, VDBIO_VERIFY_UNCHECKED = 2 }
    vdbio_verify_status_t;
typedef struct vdbio_verify_grid {
  char name[256];
  vdbio_verify_status_t status;
  char detail[512]; /* why CORRUPT or UNCHECKED */
} vdbio_verify_grid_t;
/* Recomputes every grid's checksum; *grids (caller frees) gets one entry per
 * grid in file order. BK_ERR_INPUT when the file cannot be opened or read. */
int vdbio_verify(const char *path, vdbio_verify_grid_t **grids, int *count, bk_error_t *err);

/* Reads a string or number metadata entry from the file as text ("" if absent). */
int vdbio_read_meta(const char *path, const char *key, char *out, size_t len, bk_error_t *err);

/* Exact reading of what vdbio_write wrote (photon shards, baker/shard.h):
 * float (channels 1) or Vec3f (channels 3) grid `grid_name` copied value
 * for value over the index box [0,nx) x [0,ny) x [0,nz) of dims into out
 * (grid_count(dims) * channels floats), no resampling: the array written
 * comes back bit for bit (but -0 as +0, which the writer leaves inactive).
 * A missing grid or one of another type is BK_ERR_INPUT naming both. */
int vdbio_read_box(const char *path, const char *grid_name, const grid_dims_t *dims, int channels,
                   float *out, bk_error_t *err);

/* Every file metadata entry of a string, integer or floating-point kind,
 * its value as text that reads back exactly (integers in decimal, doubles
 * with 17 digits); other kinds (vectors) are left out. *entries (caller
 * frees) in the file's order. */
typedef struct vdbio_meta_entry {
  char key[128];
  vdbio_meta_kind_t kind;
  char value[4096];
} vdbio_meta_entry_t;
int vdbio_read_meta_all(const char *path, vdbio_meta_entry_t **entries, int *count,
                        bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
