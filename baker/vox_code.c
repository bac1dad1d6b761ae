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
  size_t entries, cap, base, lo, hi;
  int failed;
} code_chunk_t;

typedef struct code_job {
  const volume_t *v;
  float *code;
  int C;
  code_chunk_t chunk[CODE_CHUNKS];
} code_job_t;

static int same_bits(float a, float b) { return bk_as_uint(a) == bk_as_uint(b); }

/* Zero or a normal float: what every device computes with alike (a device
 * may flush denormals to zero). */
static int plain_float(float x) { return x == 0.0f || isnormal(x); }

/* 1 when voxel i's σs and σt are the medium's at density rho, bit for bit,
 * and rho can be a word of the code. */
static int code_is_medium(const code_job_t *J, size_t i, float rho) {
  const volume_t *v = J->v;
  const int C = J->C;
  if ((bk_as_uint(rho) & MC_ENTRY_BIT) || !plain_float(rho)) return 0;
  for (int c = 0; c < C; c++) {
    const float s = mc_medium(v->medium_s[c], v->medium_a[c], rho, 0);
    const float t = mc_medium(v->medium_s[c], v->medium_a[c], rho, 1);
    if (!plain_float(s) || !plain_float(t) || !same_bits(s, v->sigma_s[(size_t)C * i + c]) ||
        !same_bits(t, v->sigma_t[(size_t)C * i + c]))
      return 0;
  }
  return 1;
}

/* Voxel i as the chunk's latest entry, appended unless equal to it; 0 when
 * memory ran out. */
static int code_entry(const code_job_t *J, code_chunk_t *ch, size_t i) {
  const int C = J->C;
  const float *s = J->v->sigma_s + (size_t)C * i, *t = J->v->sigma_t + (size_t)C * i;
  float *last = ch->entries ? ch->table + (ch->entries - 1) * 2 * (size_t)C : NULL;
  int same = last != NULL;
  for (int c = 0; c < C && same; c++) same = same_bits(last[c], s[c]) && same_bits(last[C + c], t[c]);
  if (!same) {
    if (ch->entries == ch->cap) {
      size_t cap = ch->cap ? 2 * ch->cap : 256;
      float *grown = realloc(ch->table, cap * 2 * (size_t)C * sizeof(float));
      if (!grown) return 0;
      ch->table = grown, ch->cap = cap;
    }
    float *e = ch->table + ch->entries++ * 2 * (size_t)C;
    memcpy(e, s, (size_t)C * sizeof(float));
    memcpy(e + C, t, (size_t)C * sizeof(float));
  }
  const uint32_t word = MC_ENTRY_BIT | (uint32_t)(ch->entries - 1); /* rebased later */
  memcpy(&J->code[i], &word, sizeof word);
  return 1;
}

static void code_pass(void *ctx, size_t k, size_t lo, size_t hi) {
  code_job_t *J = ctx;
  code_chunk_t *ch = &J->chunk[k];
  ch->lo = lo, ch->hi = hi;
  for (size_t i = lo; i < hi; i++) {
    const float rho = J->v->density ? J->v->density[i] : 1.0f;
    if (code_is_medium(J, i, rho)) J->code[i] = rho;
    else if (code_is_medium(J, i, 0.0f)) J->code[i] = 0.0f;
    else if (!code_entry(J, ch, i)) {
      ch->failed = 1;
      return;
    }
  }
}

/* The chunk's entry words moved to its place in the joined table, and its
 * entries copied there. */
static void code_rebase(void *ctx, size_t k, size_t lo, size_t hi) {
  code_job_t *J = ctx;
  const code_chunk_t *ch = &J->chunk[k];
  (void)lo, (void)hi;
  for (size_t i = ch->lo; i < ch->hi; i++) {
    uint32_t word;
    memcpy(&word, &J->code[i], sizeof word);
    if (!(word & MC_ENTRY_BIT)) continue;
    word += (uint32_t)ch->base;
    memcpy(&J->code[i], &word, sizeof word);
  }
  const size_t n = grid_count(&J->v->dims), width = 2 * (size_t)J->C;
  if (ch->entries)
    memcpy(J->code + n + ch->base * width, ch->table, ch->entries * width * sizeof(float));
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

float *vox_code_build(const volume_t *v, size_t *floats) {
  const size_t n = grid_count(&v->dims);
  code_job_t J;
  memset(&J, 0, sizeof J);
  J.v = v;
  J.C = v->sigma_channels == 1 ? 1 : 3;
  J.code = malloc((n ? n : 1) * sizeof(float));
  if (!J.code) return NULL;
  bk_parallel_chunks(n, CODE_CHUNKS, code_pass, &J);
  size_t entries = code_join(&J);
  const size_t width = 2 * (size_t)J.C;
  float *grown = entries ? realloc(J.code, (n + entries * width) * sizeof(float)) : NULL;
  if (grown) {
    J.code = grown;
    for (int c = 0; c < J.C; c++) {
      J.code[n + c] = v->medium_s[c];
      J.code[n + J.C + c] = v->medium_a[c];
    }
    bk_parallel_chunks(CODE_CHUNKS, CODE_CHUNKS, code_rebase, &J);
    *floats = n + entries * width;
  } else {
    free(J.code);
    J.code = NULL;
  }
  for (int k = 0; k < CODE_CHUNKS; k++) free(J.chunk[k].table);
  return J.code;
}

void vox_code(volume_t *v) {
  size_t floats = 0;
  const double t0 = bk_now_ms();
  float *code = vox_code_build(v, &floats);
  const size_t n = grid_count(&v->dims), width = v->sigma_channels == 1 ? 2 : 6;
  if (code)
    bk_log(2, "voxelize: sigma coded, %zu table entries, %.2f bytes per voxel, %.0f ms",
           (floats - n) / width, 4.0 * (double)floats / (double)n, bk_now_ms() - t0);
  free(v->density);
  v->density = NULL;
  if (!code) return;
  free(v->sigma_s);
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
