"""Measurements on baked grids, and the small numerical tools of the bench.

In: `.vdb` files written by `baker bake` (cell-centred fog volumes, DESIGN.md
section 5), read with OpenVDB's Python module. Out: numbers for the JSON.

* Radiance error (the trade sweep): relative L2 over voxels,
      e = sqrt( sum_v |L(v) - L_ref(v)|^2 / sum_v |L_ref(v)|^2 ),
  summed over the three channels, evaluated on the REFERENCE grid's voxels.
  A run at another resolution is first resampled there by trilinear
  interpolation between its voxel centres (clamped at the border), which is
  what a renderer sampling the coarse grid sees; so a coarse grid pays both
  for its blur and for its noise.
* Deposited energy (the stability report): E = 4 pi V sum_v Lbar(v), the
  track-length estimator run backwards (each photon adds Phi l / (4 pi V)).
  For a spot light in a medium of constant n and constant sigma_t it must
  equal integral over the cone of I (1 - exp(-sigma_t l(w))) / sigma_t dw,
  l(w) the chord of the grid box along w (DESIGN.md section 2);
  `spot_energy_analytic` evaluates that integral by the midpoint rule.
* Pareto front and power-law fits for the plots.
"""
import math

import numpy as np

try:  # the harness reports a missing module per run instead of dying at import
    import pyopenvdb as vdb
except ImportError:  # pragma: no cover - depends on the machine
    vdb = None


class GridRead:
    """A dense copy of one grid: `data` is [nx, ny, nz(, 3)] float32 indexed
    (i, j, k) = x, y, z; voxel (i, j, k) is centred at origin + (i, j, k) * voxel."""

    def __init__(self, data, origin, voxel, meta):
        self.data = data
        self.origin = np.asarray(origin, dtype=np.float64)
        self.voxel = float(voxel)
        self.meta = meta


def file_metadata(path):
    if vdb is None:
        raise RuntimeError("pyopenvdb is missing: install python3-openvdb (for /usr/bin/python3)")
    return dict(vdb.readMetadata(path))


def grid_names(path):
    if vdb is None:
        raise RuntimeError("pyopenvdb is missing: install python3-openvdb (for /usr/bin/python3)")
    return sorted(g["name"] for g in vdb.readAllGridMetadata(path))


def dims_from_meta(meta):
    """Grid dimensions as base/grid.h derives them: `grid_resolution` voxels
    along the longest side of `grid_bounds`, round(extent / voxel) elsewhere."""
    bounds = meta["grid_bounds"].replace("[", " ").replace("]", " ").replace(",", " ").split()
    lo = np.array([float(x) for x in bounds[:3]])
    hi = np.array([float(x) for x in bounds[3:6]])
    res = int(meta["grid_resolution"])
    ext = hi - lo
    voxel = float(ext.max()) / res
    dims = [max(1, int(round(e / voxel))) for e in ext]
    return dims, lo, hi, voxel


def read_grid(path, name="radiance"):
    """Reads grid `name` of a baker file into a dense array over the whole
    index box of the bake (0 .. dims-1), inactive voxels as 0."""
    meta = file_metadata(path)
    grid = vdb.read(path, name)
    dims, _, _, _ = dims_from_meta(meta)
    vec = grid.valueTypeName.startswith("vec3")
    shape = tuple(dims) + ((3,) if vec else ())
    data = np.zeros(shape, dtype=np.float32)
    grid.copyToArray(data, ijk=(0, 0, 0))
    origin = grid.transform.indexToWorld((0, 0, 0))
    voxel = grid.transform.voxelSize()[0]
    return GridRead(data, origin, voxel, meta)


def _resample_axis(a, axis, src_origin, src_voxel, dst_origin, dst_voxel, n_dst):
    n_src = a.shape[axis]
    x = dst_origin + np.arange(n_dst) * dst_voxel            # target voxel centres
    u = np.clip((x - src_origin) / src_voxel, 0.0, n_src - 1)  # source index space
    i0 = np.floor(u).astype(np.int64)
    i0 = np.minimum(i0, n_src - 1)
    i1 = np.minimum(i0 + 1, n_src - 1)
    w = (u - i0).astype(np.float32)
    shape = [1] * a.ndim
    shape[axis] = n_dst
    w = w.reshape(shape)
    return np.take(a, i0, axis=axis) * (1.0 - w) + np.take(a, i1, axis=axis) * w


def resample_trilinear(src, dst_origin, dst_voxel, dst_dims):
    """`src` (a GridRead) sampled at the voxel centres of another cell-centred
    grid, by trilinear interpolation (separable: one axis at a time)."""
    a = src.data
    for axis in range(3):
        a = _resample_axis(a, axis, src.origin[axis], src.voxel, dst_origin[axis], dst_voxel,
                           dst_dims[axis])
    return a


def rel_l2(test, ref):
    """sqrt(sum |test - ref|^2 / sum |ref|^2) in double precision, slab by
    slab so a 256^3 RGB grid needs no 400 MB temporary."""
    num = den = 0.0
    for i in range(ref.shape[0]):
        d = test[i].astype(np.float64) - ref[i]
        num += float(np.vdot(d, d))
        r = ref[i].astype(np.float64)
        den += float(np.vdot(r, r))
    if den == 0.0:
        return None
    return math.sqrt(num / den)


def radiance_error(run_path, ref):
    """Relative L2 of a run's radiance against the reference (a GridRead),
    on the reference's voxels. Returns (error, run GridRead)."""
    run = read_grid(run_path, "radiance")
    if run.data.shape == ref.data.shape and abs(run.voxel - ref.voxel) < 1e-9 * ref.voxel \
            and np.allclose(run.origin, ref.origin):
        on_ref = run.data
    else:
        on_ref = resample_trilinear(run, ref.origin, ref.voxel, ref.data.shape[:3])
    return rel_l2(on_ref, ref.data), run


def all_finite(a):
    return bool(np.isfinite(a).all())


def deposited_energy(g):
    """E = 4 pi V sum Lbar over voxels, mean of the channels (W*m: power
    times path length, attenuated)."""
    lbar = g.data
    total = float(lbar.astype(np.float64).sum())
    if lbar.ndim == 4:
        total /= lbar.shape[3]
    return 4.0 * math.pi * g.voxel ** 3 * total


def _orthonormal(d):
    d = np.asarray(d, dtype=np.float64)
    d = d / np.linalg.norm(d)
    a = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(d, a)
    u /= np.linalg.norm(u)
    return d, u, np.cross(d, u)


def box_chords(origin, dirs, bmin, bmax):
    """Length inside the box [bmin, bmax] of the rays origin + t dirs, t >= 0."""
    o = np.asarray(origin, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dirs
        t0 = (np.asarray(bmin) - o) * inv
        t1 = (np.asarray(bmax) - o) * inv
    # a ray parallel to a slab: inside it for all t, or never
    par = dirs == 0.0
    inside = (o >= np.asarray(bmin)) & (o <= np.asarray(bmax))
    tlo = np.where(par, np.where(inside, -np.inf, np.inf), np.minimum(t0, t1))
    thi = np.where(par, np.where(inside, np.inf, -np.inf), np.maximum(t0, t1))
    enter = np.maximum(tlo.max(axis=1), 0.0)
    leave = thi.min(axis=1)
    return np.maximum(leave - enter, 0.0)


def spot_energy_analytic(position, direction, angle_deg, intensity, sigma_t, bmin, bmax, m=1000):
    """integral over the cone of I (1 - exp(-sigma_t l)) / sigma_t dw (l at
    sigma_t = 0), for straight rays from `position`: midpoint rule on the
    m x m grid of the same (cos t, phi) parametrisation the photons use
    (uniform in solid angle), so each cell has solid angle Omega / m^2."""
    cos_max = math.cos(math.radians(angle_deg))
    omega = 2.0 * math.pi * (1.0 - cos_max)
    a = (np.arange(m) + 0.5) / m
    aa, bb = np.meshgrid(a, a, indexing="ij")
    ct = 1.0 - aa.ravel() * (1.0 - cos_max)
    st = np.sqrt(np.maximum(0.0, 1.0 - ct * ct))
    phi = 2.0 * math.pi * bb.ravel()
    d, u, v = _orthonormal(direction)
    dirs = (ct[:, None] * d + (st * np.cos(phi))[:, None] * u + (st * np.sin(phi))[:, None] * v)
    ell = box_chords(position, dirs, bmin, bmax)
    if sigma_t > 0.0:
        f = -np.expm1(-sigma_t * ell) / sigma_t
    else:
        f = ell
    return float(intensity) * omega * float(f.mean())


def pareto_front(times, errors):
    """Flags of the points no other point beats: a point is dominated when
    another has time <= and error <= with one of them strictly smaller.
    None entries are never on the front."""
    n = len(times)
    flags = [False] * n
    for i in range(n):
        if times[i] is None or errors[i] is None:
            continue
        dominated = False
        for j in range(n):
            if j == i or times[j] is None or errors[j] is None:
                continue
            if times[j] <= times[i] and errors[j] <= errors[i] and \
                    (times[j] < times[i] or errors[j] < errors[i]):
                dominated = True
                break
        flags[i] = not dominated
    return flags


def fit_power_law(x, y):
    """Least squares on log-log: y = c x^k. Returns dict(exponent, prefactor,
    r2, points) or None with fewer than two usable points."""
    pts = [(a, b) for a, b in zip(x, y) if a is not None and b is not None and a > 0 and b > 0]
    if len(pts) < 2:
        return None
    lx = np.log([p[0] for p in pts])
    ly = np.log([p[1] for p in pts])
    k, c = np.polyfit(lx, ly, 1)
    pred = k * lx + c
    ss_res = float(((ly - pred) ** 2).sum())
    ss_tot = float(((ly - ly.mean()) ** 2).sum())
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else 1.0
    return {"exponent": float(k), "prefactor": float(math.exp(c)), "r2": r2, "points": len(pts)}
