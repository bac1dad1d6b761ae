// exr.cpp: half RGBA OpenEXR output and a small reader, behind formats/exr.h.
#include "exr.h"

#include <ImfFloatAttribute.h>
#include <ImfHeader.h>
#include <ImfIntAttribute.h>
#include <ImfDoubleAttribute.h>
#include <ImfRgbaFile.h>
#include <ImfStandardAttributes.h>
#include <ImfIO.h>
#include <ImfStringAttribute.h>
#include <ImfVecAttribute.h>
#include <Imath/ImathMatrix.h>
#include <Imath/half.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fcntl.h>
#include <unistd.h>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace {

half to_half(float v) {
  if (std::isnan(v)) return half(0.0f);
  const float hmax = 65504.0f; // largest finite half
  if (v > hmax) v = hmax;
  if (v < -hmax) v = -hmax;
  return half(v);
}

Imath::V3f v3f(const float a[3]) { return Imath::V3f(a[0], a[1], a[2]); }

// OpenEXR camera space: x right, y up, z along the view (left-handed);
// Imath multiplies row vectors, p_cam = p_world * M.
Imath::M44f world_to_camera(const exr_info_t *in) {
  Imath::V3f pos = v3f(in->cam_position), at = v3f(in->cam_look_at), up = v3f(in->cam_up);
  Imath::V3f f = (at - pos).normalized();
  Imath::V3f r = f.cross(up).normalized();
  Imath::V3f u = r.cross(f);
  Imath::M44f m;
  for (int i = 0; i < 3; i++) {
    m[i][0] = r[i];
    m[i][1] = u[i];
    m[i][2] = f[i];
    m[i][3] = 0.0f;
  }
  m[3][0] = -pos.dot(r);
  m[3][1] = -pos.dot(u);
  m[3][2] = -pos.dot(f);
  m[3][3] = 1.0f;
  return m;
}

// OpenEXR's own file stream checks each write but not the flush at close,
// so the tail of a file on a full disk is lost silently. This one writes
// straight through write(2) and keeps the errno of the first failure.
class FdOStream : public Imf::OStream {
public:
  explicit FdOStream(const char *path)
      : Imf::OStream(path), fd_(open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)) {
    if (fd_ < 0) error_ = errno;
  }
  ~FdOStream() override { close_file(); }
  void write(const char c[], int n) override {
    while (n > 0 && !error_) {
      ssize_t w = ::write(fd_, c, (size_t)n);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) {
        error_ = w < 0 ? errno : EIO;
        break;
      }
      c += w;
      n -= (int)w;
      pos_ += (uint64_t)w;
    }
    if (error_) throw std::runtime_error(std::strerror(error_));
  }
  uint64_t tellp() override { return pos_; }
  void seekp(uint64_t pos) override {
    if (!error_ && lseek(fd_, (off_t)pos, SEEK_SET) < 0) error_ = errno;
    if (error_) throw std::runtime_error(std::strerror(error_));
    pos_ = pos;
  }
  int close_file() {
    if (fd_ >= 0 && close(fd_) != 0 && !error_) error_ = errno;
    fd_ = -1;
    return error_;
  }

private:
  int fd_;
  int error_ = 0;
  uint64_t pos_ = 0;
};
} // namespace

extern "C" int exr_write_rgba(const char *path, int width, int height, const float *rgba,
                              const exr_info_t *info, bk_error_t *err) {
  if (width <= 0 || height <= 0)
    return bk_fail(err, BK_ERR_INPUT, "%s: image size must be positive, got %dx%d", path, width,
                   height);
  size_t count;
  if (!bk_mul_size((size_t)width, (size_t)height, &count))
    return bk_fail(err, BK_ERR_INPUT, "%s: image size %dx%d overflows", path, width, height);
  char temp[4096];
  bk_temp_path(path, temp, sizeof temp);
  try {
    std::vector<Imf::Rgba> px(count);
    for (size_t i = 0; i < count; i++)
      px[i] = Imf::Rgba(to_half(rgba[4 * i]), to_half(rgba[4 * i + 1]), to_half(rgba[4 * i + 2]),
                        to_half(rgba[4 * i + 3]));
    Imf::Header header(width, height);
    header.compression() = Imf::ZIP_COMPRESSION;
    header.insert("software", Imf::StringAttribute("baker " BAKER_VERSION));
    if (info) {
      if (info->source) header.insert("sourceFile", Imf::StringAttribute(info->source));
      if (info->has_frame) header.insert("frame", Imf::IntAttribute(info->frame));
      if (info->has_camera) {
        header.insert("cameraPosition", Imf::V3fAttribute(v3f(info->cam_position)));
        header.insert("cameraLookAt", Imf::V3fAttribute(v3f(info->cam_look_at)));
        header.insert("cameraUp", Imf::V3fAttribute(v3f(info->cam_up)));
        header.insert("cameraFovYDeg", Imf::FloatAttribute(info->cam_fov_y_deg));
        Imf::addWorldToCamera(header, world_to_camera(info));
      }
      if (info->comments) Imf::addComments(header, info->comments);
    }
    {
      /* ZIP blocks are compressed on every core (OpenEXR's own thread pool) */
      int threads = (int)std::thread::hardware_concurrency();
      FdOStream os(temp);
      {
        Imf::RgbaOutputFile file(os, header, Imf::WRITE_RGBA, threads > 1 ? threads : 0);
        file.setFrameBuffer(px.data(), 1, (size_t)width);
        file.writePixels(height);
      } // writes the line offsets
      if (int e = os.close_file()) throw std::runtime_error(std::strerror(e));
    } // closes the file before the rename
  } catch (const std::exception &e) {
    std::remove(temp);
    return bk_fail(err, BK_ERR_RUNTIME, "%s: cannot write OpenEXR: %s", path, e.what());
  } catch (...) {
    std::remove(temp);
    return bk_fail(err, BK_ERR_RUNTIME, "%s: cannot write OpenEXR (unknown error)", path);
  }
  return bk_commit_temp(temp, path, err);
}

extern "C" int exr_read_rgba(const char *path, int *width, int *height, float **rgba,
                             bk_error_t *err) {
  *rgba = nullptr;
  try {
    Imf::RgbaInputFile file(path);
    Imath::Box2i dw = file.dataWindow();
    int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
    if (w <= 0 || h <= 0)
      return bk_fail(err, BK_ERR_INPUT, "%s: empty data window", path);
    std::vector<Imf::Rgba> px((size_t)w * (size_t)h);
    file.setFrameBuffer(px.data() - dw.min.x - (ptrdiff_t)dw.min.y * w, 1, (size_t)w);
    file.readPixels(dw.min.y, dw.max.y);
    float *out = (float *)bk_calloc(px.size(), 4 * sizeof(float), path, err);
    if (!out) return BK_ERR_RUNTIME;
    for (size_t i = 0; i < px.size(); i++) {
      out[4 * i] = px[i].r;
      out[4 * i + 1] = px[i].g;
      out[4 * i + 2] = px[i].b;
      out[4 * i + 3] = px[i].a;
    }
    *width = w;
    *height = h;
    *rgba = out;
  } catch (const std::exception &e) {
    return bk_fail(err, BK_ERR_INPUT, "%s: cannot read OpenEXR: %s", path, e.what());
  } catch (...) {
    return bk_fail(err, BK_ERR_INPUT, "%s: cannot read OpenEXR (unknown error)", path);
  }
  return BK_OK;
}

extern "C" int exr_read_attribute(const char *path, const char *name, char *out, size_t len,
                                  bk_error_t *err) {
  try {
    Imf::RgbaInputFile file(path);
    const Imf::Header &h = file.header();
    if (const auto *a = h.findTypedAttribute<Imf::V3fAttribute>(name)) {
      const Imath::V3f &v = a->value();
      snprintf(out, len, "%.9g %.9g %.9g", v.x, v.y, v.z);
    } else if (const auto *f = h.findTypedAttribute<Imf::FloatAttribute>(name)) {
      snprintf(out, len, "%.9g", f->value());
    } else if (const auto *d = h.findTypedAttribute<Imf::DoubleAttribute>(name)) {
      snprintf(out, len, "%.17g", d->value());
    } else if (const auto *i = h.findTypedAttribute<Imf::IntAttribute>(name)) {
      snprintf(out, len, "%d", i->value());
    } else if (const auto *s = h.findTypedAttribute<Imf::StringAttribute>(name)) {
      snprintf(out, len, "%s", s->value().c_str());
    } else {
      return bk_fail(err, BK_ERR_INPUT,
                     "%s: no header attribute \"%s\" of type v3f, float, double, int or string",
                     path, name);
    }
  } catch (const std::exception &e) {
    return bk_fail(err, BK_ERR_INPUT, "%s: cannot read OpenEXR: %s", path, e.what());
  } catch (...) {
    return bk_fail(err, BK_ERR_INPUT, "%s: cannot read OpenEXR (unknown error)", path);
  }
  return BK_OK;
}
