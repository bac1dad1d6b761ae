/* iorgrad.c: ∇n on the host (reference) and on the OpenCL device. */
#include "iorgrad.h"

#include "ior.h"

bk_grid ig_kernel_grid(const grid_dims_t *d) {
  bk_grid g;
  g.nx = d->nx;
  g.ny = d->ny;
  g.nz = d->nz;
  g.pad0 = 0;
  g.origin_x = d->origin[0];
  g.origin_y = d->origin[1];
  g.origin_z = d->origin[2];
  g.voxel_size = d->voxel_size;
  return g;
}

/* Sizes of n and ∇n in bytes, refusing empty grids and overflow. */
static int grad_sizes(const grid_dims_t *d, size_t *ior_bytes, size_t *grad_bytes,
                      bk_error_t *err) {
  if (d->nx < 1 || d->ny < 1 || d->nz < 1 || !(d->voxel_size > 0.0f))
    return bk_fail(err, BK_ERR_INPUT,
                   "ior gradient: grid %dx%dx%d with voxel size %g: expected at least one voxel "
                   "along each axis and a positive voxel size",
                   d->nx, d->ny, d->nz, (double)d->voxel_size);
  size_t count;
  if (!bk_mul3_size((size_t)d->nx, (size_t)d->ny, (size_t)d->nz, &count) ||
      !bk_mul_size(count, sizeof(float), ior_bytes) ||
      !bk_mul_size(count, 3 * sizeof(float), grad_bytes))
    return bk_fail(err, BK_ERR_INPUT, "ior gradient: grid %dx%dx%d overflows the address space",
                   d->nx, d->ny, d->nz);
  return BK_OK;
}

int ig_compute_host(const grid_dims_t *d, const float *ior, float *grad, bk_error_t *err) {
  size_t ib, gb;
  int rc = grad_sizes(d, &ib, &gb, err);
  if (rc != BK_OK) return rc;
  bk_grid g = ig_kernel_grid(d);
  for (int k = 0; k < g.nz; k++)
    for (int j = 0; j < g.ny; j++)
      for (int i = 0; i < g.nx; i++) {
        bk_v3 v = ior_gradient_at(ior, g, i, j, k);
        float *o = grad + 3 * ior_index(g, i, j, k);
        o[0] = v.x;
        o[1] = v.y;
        o[2] = v.z;
      }
  return BK_OK;
}

int ig_compute_cl_buffers(clh_context_t *cl, cl_program program, const grid_dims_t *d,
                          cl_mem ior, cl_mem grad, bk_error_t *err) {
  cl_program own = NULL;
  cl_kernel kernel = NULL;
  cl_int cerr = CL_SUCCESS;
  size_t ib, gb;
  int rc = grad_sizes(d, &ib, &gb, err);
  if (rc != BK_OK) return rc;
  rc = BK_ERR_RUNTIME;
  if (!program) {
    if (clh_build(cl, "ior.cl", "", &own, err) != BK_OK) goto error;
    program = own;
  }
  bk_grid g = ig_kernel_grid(d);
  kernel = clCreateKernel(program, "ior_gradient", &cerr);
  CLH_CHECK(cerr, err, error);
  CLH_CHECK(clSetKernelArg(kernel, 0, sizeof(cl_mem), &ior), err, error);
  CLH_CHECK(clSetKernelArg(kernel, 1, sizeof(bk_grid), &g), err, error);
  CLH_CHECK(clSetKernelArg(kernel, 2, sizeof(cl_mem), &grad), err, error);
  size_t global[3] = {(size_t)d->nx, (size_t)d->ny, (size_t)d->nz};
  CLH_CHECK(clEnqueueNDRangeKernel(cl->queue, kernel, 3, NULL, global, NULL, 0, NULL, NULL), err,
            error);
  CLH_CHECK(clFinish(cl->queue), err, error);
  rc = BK_OK;
error:
  if (kernel) clReleaseKernel(kernel);
  if (own) clReleaseProgram(own);
  return rc;
}

int ig_compute_cl(clh_context_t *cl, const grid_dims_t *d, const float *ior, float *grad,
                  bk_error_t *err) {
  cl_mem ior_buf = NULL, grad_buf = NULL;
  cl_int cerr = CL_SUCCESS;
  size_t ib, gb;
  char b1[32], b2[32];
  int rc = grad_sizes(d, &ib, &gb, err);
  if (rc != BK_OK) return rc;
  rc = BK_ERR_RUNTIME;
  if ((cl_ulong)gb > cl->max_alloc) {
    bk_fail(err, BK_ERR_RUNTIME,
            "ior gradient: the %dx%dx%d gradient grid needs %s in one buffer; %s allows %s",
            d->nx, d->ny, d->nz, bk_format_bytes((double)gb, b1, sizeof b1), cl->device_name,
            bk_format_bytes((double)cl->max_alloc, b2, sizeof b2));
    goto error;
  }
  ior_buf = clCreateBuffer(cl->context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, ib, (void *)ior,
                           &cerr);
  CLH_CHECK(cerr, err, error);
  grad_buf = clCreateBuffer(cl->context, CL_MEM_WRITE_ONLY, gb, NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  if (ig_compute_cl_buffers(cl, NULL, d, ior_buf, grad_buf, err) != BK_OK) goto error;
  CLH_CHECK(clEnqueueReadBuffer(cl->queue, grad_buf, CL_TRUE, 0, gb, grad, 0, NULL, NULL), err,
            error);
  rc = BK_OK;
error:
  if (ior_buf) clReleaseMemObject(ior_buf);
  if (grad_buf) clReleaseMemObject(grad_buf);
  return rc;
}
