/* fdstream.h: a std::ostream onto a new file that remembers why it failed.
 *
 * The C++ writers (OpenVDB, OpenEXR) write through std::ostream and never
 * look at its state afterwards; a std::ofstream on a full disk just goes
 * quiet. This stream keeps the errno of the first failed write(2) (ENOSPC,
 * EDQUOT, EIO) so the caller can refuse to rename the file into place and
 * say why. It also starts the disk writing as it goes, so that the fsync
 * before the rename has little left to wait for. Header-only: formats/ C++
 * files include it. */
#ifndef BAKER_FDSTREAM_H
#define BAKER_FDSTREAM_H

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <fcntl.h>
#include <ostream>
#include <streambuf>
#include <unistd.h>

class bk_fd_streambuf : public std::streambuf {
public:
  explicit bk_fd_streambuf(const char *path)
      : fd_(open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)),
        error_(fd_ < 0 ? errno : 0) {
    setp(buf_, buf_ + sizeof buf_);
  }
  ~bk_fd_streambuf() override { close_file(); }
  /* Flushes and closes; returns 0 or the errno of the first failure. */
  int close_file() {
    if (fd_ >= 0) {
      flush_buffer();
      if (close(fd_) != 0 && !error_) error_ = errno;
      fd_ = -1;
    }
    return error_;
  }
  int error() const { return error_; }

protected:
  int_type overflow(int_type ch) override {
    if (!flush_buffer()) return traits_type::eof();
    if (!traits_type::eq_int_type(ch, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(ch);
      pbump(1);
    }
    return traits_type::not_eof(ch);
  }
  int sync() override { return flush_buffer() ? 0 : -1; }
  /* A block at least the buffer's size goes to write(2) as it is, not
   * copied through the buffer (a grid's compressed leaves: hundreds of MB). */
  std::streamsize xsputn(const char *s, std::streamsize n) override {
    if (n < (std::streamsize)sizeof buf_) return std::streambuf::xsputn(s, n);
    if (!flush_buffer() || !write_all(s, (size_t)n)) return 0;
    start_writeback();
    return n;
  }
  /* OpenVDB's seekable archives tell and seek to record grid offsets. */
  pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode) override {
    if (!flush_buffer() || fd_ < 0) return pos_type(off_type(-1));
    int whence = dir == std::ios_base::beg ? SEEK_SET : dir == std::ios_base::cur ? SEEK_CUR : SEEK_END;
    off_t r = lseek(fd_, (off_t)off, whence);
    if (r < 0) error_ = errno;
    return pos_type(off_type(r));
  }
  pos_type seekpos(pos_type pos, std::ios_base::openmode mode) override {
    return seekoff(off_type(pos), std::ios_base::beg, mode);
  }

private:
  /* write(2) the buffer out. */
  bool flush_buffer() {
    write_all(pbase(), (size_t)(pptr() - pbase()));
    setp(buf_, buf_ + sizeof buf_);
    start_writeback();
    return !error_;
  }
  /* write(2) [p, p + left), retrying short writes and EINTR. */
  bool write_all(const char *p, size_t left) {
    while (left > 0 && !error_) {
      ssize_t n = fd_ < 0 ? -1 : write(fd_, p, left);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        error_ = n < 0 ? errno : EIO;
        break;
      }
      p += n;
      left -= (size_t)n;
      unkicked_ += (uint64_t)n;
    }
    return !error_;
  }
  /* Every WRITEBACK_BYTES written (2 MB: 1-2 MB gave the shortest 256³
   * write, 4-32 MB longer ones), the disk starts writing the file's
   * dirty pages (Linux: sync_file_range without waiting), so that the
   * fsync before the rename waits for the last stretch only, not for the
   * whole file (~100 ms for a 250 MB bake). Where the call is missing this
   * does nothing. */
  void start_writeback() {
#ifdef SYNC_FILE_RANGE_WRITE
    if (fd_ >= 0 && unkicked_ >= WRITEBACK_BYTES) {
      (void)sync_file_range(fd_, 0, 0, SYNC_FILE_RANGE_WRITE); /* 0, 0: the whole file */
      unkicked_ = 0;
    }
#endif
  }
  static constexpr uint64_t WRITEBACK_BYTES = 2u << 20;
  int fd_;
  int error_;
  uint64_t unkicked_ = 0; /* bytes written since the last start */
  char buf_[1 << 16];
};

#endif
