/* vox_code.c: coding a volume's σs and σt (see vox_code.h). */
#include "vox_code.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"

/* Chunks coded side by side, each with a table of its own until they are
 * joined in chunk order (the same buffer on every run). */
#define CODE_CHUNKS 64

typedef struct code_chunk {
  float *table; /* 2C floats per entry */
  size_t entries, cap, base;
  int failed;
} code_chunk_t;

typedef struct code_job {
  const volume_t *v;
  const float *sigma_s, *sigma_t; /* the plain arrays (sigma_s may become code) */
  float *code;                    /* NULL in the first pass */
  int C;
  code_chunk_t chunk[CODE_CHUNKS];
} code_job_t;

static int same_bits(float a, float b) { return bk_as_uint(a) == bk_as_uint(b); }

/* Zero or a normal float: what every device computes with alike (a device
 * may flush denormals to zero). */
static int plain_float(float x) { return x == 0.0f || isnormal(x); }

/* The medium's σs and σt at one density, as the voxelizer computes them;
 * ok: rho can be a word of the code and the values are plain floats. */
typedef struct code_medium {
  float rho, s[3], t[3];
  int ok;
} code_medium_t;

static code_medium_t code_medium_at(const code_job_t *J, float rho) {
  const volume_t *v = J->v;
  code_medium_t m = {rho, {0}, {0}, !(bk_as_uint(rho) & MC_ENTRY_BIT) && plain_float(rho)};
  for (int c = 0; c < J->C; c++) {
    m.s[c] = mc_medium(v->medium_s[c], v->medium_a[c], rho, 0);
    m.t[c] = mc_medium(v->medium_s[c], v->medium_a[c], rho, 1);
    m.ok &= plain_float(m.s[c]) && plain_float(m.t[c]);
  }
  return m;
}

/* 1 when voxel i's σs and σt are m's, bit for bit, and m can code them. */
static int code_is_medium(const code_job_t *J, const code_medium_t *m, size_t i) {
  const int C = J->C;
  if (!m->ok) return 0;
  for (int c = 0; c < C; c++)
    if (!same_bits(m->s[c], J->sigma_s[(size_t)C * i + c]) ||
        !same_bits(m->t[c], J->sigma_t[(size_t)C * i + c]))
      return 0;
  return 1;
}

/* 1 when voxel i's values equal table entry e. */
static int code_is_entry(const code_job_t *J, const float *table, size_t e, size_t i) {
  const int C = J->C;
  const float *x = table + e * 2 * (size_t)C;
  const float *s = J->sigma_s + (size_t)C * i, *t = J->sigma_t + (size_t)C * i;
  for (int c = 0; c < C; c++)
    if (!same_bits(x[c], s[c]) || !same_bits(x[C + c], t[c])) return 0;
  return 1;
}

/* Voxel i appended to the chunk's table as a new entry; 0 when memory ran
 * out. */
static int code_append(const code_job_t *J, code_chunk_t *ch, size_t i) {
  const int C = J->C;
  if (ch->entries == ch->cap) {
    size_t cap = ch->cap ? 2 * ch->cap : 256;
    float *grown = realloc(ch->table, cap * 2 * (size_t)C * sizeof(float));
    if (!grown) return 0;
    ch->table = grown, ch->cap = cap;
  }
  float *e = ch->table + ch->entries++ * 2 * (size_t)C;
  memcpy(e, J->sigma_s + (size_t)C * i, (size_t)C * sizeof(float));
  memcpy(e + C, J->sigma_t + (size_t)C * i, (size_t)C * sizeof(float));
  return 1;
}

/* One chunk's voxels in order. A voxel that is not the medium's is an
 * entry, shared with the one before when equal to it. The first pass
 * (no code yet) builds the chunk's table; the second finds the same
 * entries again and writes each voxel's word, the entries numbered from the
 * chunk's place in the joined table. Voxel i's word is written after its
 * σs is read, so the code may take σs's place. */
static void code_pass(void *ctx, size_t k, size_t lo, size_t hi) {
  code_job_t *J = ctx;
  code_chunk_t *ch = &J->chunk[k];
  size_t next = 0; /* the second pass: entries met so far */
  const code_medium_t none = code_medium_at(J, 0.0f), uniform = code_medium_at(J, 1.0f);
  for (size_t i = lo; i < hi; i++) {
    const code_medium_t here = J->v->density ? code_medium_at(J, J->v->density[i]) : uniform;
    float word = 0.0f;
    if (code_is_medium(J, &here, i)) {
      word = here.rho;
    } else if (code_is_medium(J, &none, i)) {
      word = 0.0f;
    } else if (!J->code) {
      if ((!ch->entries || !code_is_entry(J, ch->table, ch->entries - 1, i)) &&
          !code_append(J, ch, i)) {
        ch->failed = 1;
        return;
      }
      continue;
    } else {
      if (!next || !code_is_entry(J, ch->table, next - 1, i)) next++;
      const uint32_t bits = MC_ENTRY_BIT | (uint32_t)(ch->base + next - 1);
      memcpy(&word, &bits, sizeof bits);
    }
    if (J->code) J->code[i] = word;
  }
}

/* Each chunk's first entry in the joined table (entry 0 is the medium's
 * coefficients); 0 when a chunk ran out of memory or the entries overflow
 * the word. */
static size_t code_join(code_job_t *J) {
  size_t total = 1;
  for (int k = 0; k < CODE_CHUNKS; k++) {
    if (J->chunk[k].failed) return 0;
    J->chunk[k].base = total;
    total += J->chunk[k].entries;
  }
  return total <= (size_t)~MC_ENTRY_BIT ? total : 0;
}

/* The coded buffer of v's plain arrays, `floats` long, or NULL when memory
 * ran out (the arrays then as they were). in_place: the buffer is v's σs
 * array, grown by the table (a grey volume: one word per voxel where σs
 * had one float), so coding needs no second grid-sized array. */
static float *code_build(volume_t *v, int in_place, size_t *floats) {
  const size_t n = grid_count(&v->dims);
  code_job_t J;
  memset(&J, 0, sizeof J);
  J.v = v;
  J.C = v->sigma_channels == 1 ? 1 : 3;
  J.sigma_s = v->sigma_s, J.sigma_t = v->sigma_t;
  bk_parallel_chunks(n, CODE_CHUNKS, code_pass, &J);
  const size_t entries = code_join(&J), width = 2 * (size_t)J.C;
  const size_t bytes = (n + entries * width) * sizeof(float);
  if (entries) J.code = in_place ? realloc(v->sigma_s, bytes) : malloc(bytes);
  if (J.code) {
    if (in_place) v->sigma_s = NULL; /* it is the code's now, wherever realloc put it */
    J.sigma_s = in_place ? J.code : v->sigma_s;
    for (int c = 0; c < J.C; c++) {
      J.code[n + c] = v->medium_s[c];
      J.code[n + J.C + c] = v->medium_a[c];
    }
    for (int k = 0; k < CODE_CHUNKS; k++)
      if (J.chunk[k].entries)
        memcpy(J.code + n + J.chunk[k].base * width, J.chunk[k].table,
               J.chunk[k].entries * width * sizeof(float));
    bk_parallel_chunks(n, CODE_CHUNKS, code_pass, &J);
    *floats = n + entries * width;
  }
  for (int k = 0; k < CODE_CHUNKS; k++) free(J.chunk[k].table);
  return J.code;
}

void vox_code(volume_t *v) {
  size_t floats = 0;
  const double t0 = bk_now_ms();
  const int in_place = v->sigma_channels == 1;
  float *code = code_build(v, in_place, &floats);
  const size_t n = grid_count(&v->dims), width = v->sigma_channels == 1 ? 2 : 6;
  if (code)
    bk_log(2, "voxelize: sigma coded, %zu table entries, %.2f bytes per voxel, %.0f ms",
           (floats - n) / width, 4.0 * (double)floats / (double)n, bk_now_ms() - t0);
  free(v->density);
  v->density = NULL;
  if (!code) return;
  free(v->sigma_s); /* NULL when the code took its place */
  free(v->sigma_t);
  v->sigma_s = v->sigma_t = NULL;
  v->sigma_code = code;
  v->sigma_code_floats = floats;
}

void vox_code_run(const volume_t *v, int t, size_t lo, size_t hi, float *out) {
  const int C = v->sigma_channels == 1 ? 1 : 3;
  const bk_long n = (bk_long)grid_count(&v->dims);
  for (size_t i = lo; i < hi; i++, out += C) mc_sigma_all(v->sigma_code, n, C, (bk_long)i, t, out);
}

/* vox_code_decode's runs, side by side. */
typedef struct code_decode {
  const volume_t *v;
  int t;
  float *out;
} code_decode_t;

static void code_decode_range(void *ctx, size_t lo, size_t hi) {
  const code_decode_t *d = ctx;
  vox_code_run(d->v, d->t, lo, hi, d->out + (size_t)(d->v->sigma_channels == 1 ? 1 : 3) * lo);
}

float *vox_code_decode(const volume_t *v, int t) {
  const size_t n = grid_count(&v->dims), C = v->sigma_channels == 1 ? 1 : 3;
  code_decode_t d = {v, t, malloc(n * C * sizeof(float))};
  if (d.out) bk_parallel(n, BK_GRAIN, code_decode_range, &d);
  return d.out;
}
