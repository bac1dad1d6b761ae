/* clcopy.h: large copies between host memory and a discrete device's
 * buffers (the photon sums of a GPU march, read after every batch).
 *
 * A read or write of pageable memory goes through the driver's own staging:
 * 7-14 GB/s on the H200 node against 55 GB/s from pinned memory
 * (docs/gpu.md). These copy through two pinned buffers of the context
 * (CL_MEM_ALLOC_HOST_PTR, mapped once): the device fills one while all
 * cores copy the other. Small copies, and every copy on a CPU device, whose
 * buffers are host memory, go straight. */
#ifndef BAKER_CLCOPY_H
#define BAKER_CLCOPY_H

#include "clhost.h"

#define CLC_STAGE ((size_t)32 << 20) /* bytes per staging buffer */

/* bytes of buffer b from offset 0 into host, or from host into b */
int clc_read(clh_context_t *cl, cl_mem b, size_t bytes, void *host, bk_error_t *err);
int clc_write(clh_context_t *cl, cl_mem b, size_t bytes, const void *host, bk_error_t *err);
/* b's first bytes set from host: a fill on the device when host holds only
 * zero bytes (found by a scan on all cores), else clc_write */
int clc_upload(clh_context_t *cl, cl_mem b, size_t bytes, const void *host, bk_error_t *err);

#endif
