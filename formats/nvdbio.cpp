/* nvdbio.cpp: NanoVDB files for vdbio (see vdbio.h).
 *
 * Writing converts the OpenVDB grids vdbio_write built (so the grids, their
 * classes, transforms and backgrounds are the same as in a .vdb) with
 * openToNanoVDB, one grid per segment, uncompressed: pbrt-v4 and Blender read
 * that without a codec. NanoVDB grids carry no file metadata, so the
 * creator, scene hash and the rest stay in .vdb files only.
 *
 * Reading goes the other way (nanoToOpenVDB), so every vdbio reader (the
 * view, ior_vdb, density_vdb) takes .nvdb files with its OpenVDB code. */
#include "vdbio_internal.h"

#include <nanovdb/util/IO.h>
#include <nanovdb/util/NanoToOpenVDB.h>
#include <nanovdb/util/OpenToNanoVDB.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <strings.h>
#include <string>
#include <vector>

namespace vdb = openvdb;

int vdbio_is_nano_path(const char *path) {
  const size_t n = path ? strlen(path) : 0;
  return n >= 5 && strcasecmp(path + n - 5, ".nvdb") == 0;
}

/* By content, not name: NanoVDB files start with the magic "NanoVDB0". */
bool vdbio_is_nano_file(const char *path) {
  FILE *f = path ? fopen(path, "rb") : NULL;
  if (!f)
    return false;
  uint64_t magic = 0;
  const bool ok = fread(&magic, sizeof magic, 1, f) == 1 && magic == NANOVDB_MAGIC_NUMBER;
  fclose(f);
  return ok;
}

/* The bytes of nanovdb::io::writeGrids (one segment: its header, then each
 * grid), but a grid at a time: the header's size follows from the names
 * alone, so the grids go after room left for it and the header, which
 * needs every grid's statistics, goes in last. */
void nvdbio_write(const std::string &file, const std::vector<std::string> &names,
                  const std::function<vdb::GridBase::Ptr(int)> &make,
                  const std::function<void(int)> &done) {
  const nanovdb::io::Codec codec = nanovdb::io::Codec::NONE;
  uint64_t header = sizeof(nanovdb::io::Header);
  for (const std::string &n : names) header += sizeof(nanovdb::io::MetaData) + n.size() + 1;
  std::ofstream os(file, std::ios::out | std::ios::binary | std::ios::trunc);
  if (!os.is_open())
    throw std::runtime_error("cannot open " + file + " for writing");
  nanovdb::io::Segment seg(codec);
  os.seekp((std::streamoff)header);
  for (int i = 0; i < (int)names.size(); i++) {
    nanovdb::GridHandle<nanovdb::HostBuffer> h = nanovdb::openToNanoVDB(make(i));
    seg.add(h);
    seg.meta.back().fileSize = nanovdb::io::Internal::write(os, h, codec);
    done(i);
  }
  if (seg.memUsage() != header) /* a name NanoVDB stored otherwise */
    throw std::runtime_error("NanoVDB segment header size differs from its grid names'");
  os.seekp(0);
  seg.write(os);
  os.close();
  if (os.fail())
    throw std::runtime_error("writing " + file + " failed");
}

/* OpenVDB's names for the value types vdbio reads; others by number. */
static std::string nvdbio_type_name(nanovdb::GridType t) {
  switch (t) {
  case nanovdb::GridType::Float: return "float";
  case nanovdb::GridType::Double: return "double";
  case nanovdb::GridType::Vec3f: return "vec3s";
  case nanovdb::GridType::Vec3d: return "vec3d";
  default: return "nanovdb type " + std::to_string((int)t);
  }
}

int nvdbio_list(const char *path, std::vector<std::string> &names,
                std::vector<std::string> &types, bk_error_t *err) {
  try {
    for (const nanovdb::io::GridMetaData &m : nanovdb::io::readGridMetaData(path)) {
      names.push_back(m.gridName);
      types.push_back(nvdbio_type_name(m.gridType));
    }
  } catch (const std::exception &e) {
    return bk_fail(err, BK_ERR_INPUT, "%s: not a readable NanoVDB file (%s)", path, e.what());
  }
  return BK_OK;
}

int nvdbio_load_grid(const char *path, const char *where, const char *grid_name,
                     vdb::GridBase::Ptr &grid, int *found, bk_error_t *err) {
  const std::string pre = where && where[0] ? std::string(where) + ": " + path : path;
  std::vector<std::string> names, types;
  int rc = nvdbio_list(pre.c_str(), names, types, err);
  if (rc)
    return rc;
  bool has = false;
  std::string list;
  for (size_t i = 0; i < names.size(); i++) {
    has = has || names[i] == grid_name;
    list += (i ? ", \"" : "\"") + names[i] + "\" (" + types[i] + ")";
  }
  if (!has) {
    if (found) {
      *found = 0;
      return BK_OK;
    }
    return bk_fail(err, BK_ERR_INPUT, "%s: no grid named \"%s\"; the file has %s", pre.c_str(),
                   grid_name, list.empty() ? "none" : list.c_str());
  }
  try {
    vdbio_trees_next();
    nanovdb::GridHandle<nanovdb::HostBuffer> h = nanovdb::io::readGrid(path, grid_name);
    grid = nanovdb::nanoToOpenVDB(h);
  } catch (const std::exception &e) {
    return bk_fail(err, BK_ERR_INPUT, "%s: grid \"%s\" cannot be read from the NanoVDB file (%s)",
                   pre.c_str(), grid_name, e.what());
  }
  if (!grid)
    return bk_fail(err, BK_ERR_INPUT, "%s: grid \"%s\" has a type NanoVDB cannot convert",
                   pre.c_str(), grid_name);
  if (found)
    *found = 1;
  return BK_OK;
}
