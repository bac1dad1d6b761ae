/* medium_code.h: the volume's σs and σt, coded in one 32-bit word per voxel,
 * read by the kernels and by the host alike (baker/vox_code.h codes them).
 *
 * The medium is its coefficients scaled voxel by voxel by a density ρ
 * (density_vdb, else 1), and objects replace it only inside them and in a
 * thin shell where they blend. So a voxel's word is either ρ itself (sign
 * bit clear: σs = cs·ρ, σt = cs·ρ + ca·ρ for the medium's σs and σa
 * coefficients cs and ca), or, sign bit set, the index of an entry of a
 * table that holds its σs and σt as they are. The buffer is the words of
 * every voxel, then the table: entry e is 2C floats, σs of the C channels
 * (1: grey, 3: RGB) then σt; entry 0 holds cs and ca. A voxel is coded as
 * ρ only where that gives its values back bit for bit (the host checks it
 * with mc_medium), so coding changes no result. For RGB this is 4 bytes
 * per voxel plus the table instead of 24. A grey volume (C = 1) is coded,
 * 4 bytes instead of 8, only when the bake fits in memory only so
 * (budget_check): the decoding costs its march about 3% (docs/memory.md). */
#ifndef BAKER_MEDIUM_CODE_H
#define BAKER_MEDIUM_CODE_H

#include "kernels/shared.h"

#define MC_ENTRY_BIT 0x80000000u

/* σs (t = 0) or σt (t = 1) of a medium voxel of density rho, channel ch,
 * from the medium's coefficients cs and ca: the voxelizer's products and
 * sum, in its order. */
BK_INLINE float mc_medium(float cs, float ca, float rho, int t) {
  const float s = cs * rho;
  return t ? s + ca * rho : s;
}

/* σs (t = 0) or σt (t = 1) per metre, channel ch of C, at voxel idx of a
 * coded buffer over `voxels` voxels. (A branch-free form, both readings
 * made and one selected, made PoCL's RGB march 7% slower.) */
BK_INLINE float mc_sigma(BK_GLOBAL const float *code, bk_long voxels, int C, bk_long idx,
                         int ch, int t) {
  const float w = code[idx];
  const bk_uint bits = BK_AS_UINT(w);
  BK_GLOBAL const float *table = code + voxels;
  if (bits & MC_ENTRY_BIT) return table[(bk_long)(bits & ~MC_ENTRY_BIT) * (2 * C) + t * C + ch];
  return mc_medium(table[ch], table[C + ch], w, t);
}

/* mc_sigma of every channel of voxel idx at once: one word read, one
 * branch. */
BK_INLINE void mc_sigma_all(BK_GLOBAL const float *code, bk_long voxels, int C, bk_long idx,
                            int t, float *out) {
  const float w = code[idx];
  const bk_uint bits = BK_AS_UINT(w);
  BK_GLOBAL const float *table = code + voxels;
  if (bits & MC_ENTRY_BIT) {
    BK_GLOBAL const float *e = table + (bk_long)(bits & ~MC_ENTRY_BIT) * (2 * C) + t * C;
    for (int ch = 0; ch < C; ch++) out[ch] = e[ch];
    return;
  }
  for (int ch = 0; ch < C; ch++) out[ch] = mc_medium(table[ch], table[C + ch], w, t);
}

#endif
