// Little-endian binary writing and bounds-checked reading, shared by the
// formats core encodes as bytes (trial checkpoints, episode trajectories):
// integers little-endian, doubles as their IEEE-754 bits (exact, NaN kept),
// strings and vectors length-prefixed (u64), matrices as u64 rows, u64 cols
// and the elements row by row. A Reader never reads past its input: the
// first failure (truncation, a count larger than what is left or than
// kMaxElements) is kept in error() and every later read returns zeros.
//
// Header only; core/ still writes no files: this is bytes in memory.
#ifndef TOTALGRAD_CORE_COMMON_BINARY_CODEC_H_
#define TOTALGRAD_CORE_COMMON_BINARY_CODEC_H_

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "absl/strings/str_cat.h"
#include "core/common/types.h"

namespace totalgrad::binary {

// No field of a format comes near this; a larger count is corruption.
inline constexpr uint64_t kMaxElements = uint64_t{1} << 28;

// FNV-1a, 64 bits: the formats' checksum of everything before it.
inline uint64_t Fnv1a(std::string_view bytes) {
  uint64_t hash = 14695981039346656037ULL;
  for (unsigned char c : bytes) {
    hash ^= c;
    hash *= 1099511628211ULL;
  }
  return hash;
}

class Writer {
 public:
  void U8(uint8_t v) { out_.push_back(static_cast<char>(v)); }
  void U32(uint32_t v) {
    for (int i = 0; i < 4; ++i) U8(static_cast<uint8_t>(v >> (8 * i)));
  }
  void U64(uint64_t v) {
    for (int i = 0; i < 8; ++i) U8(static_cast<uint8_t>(v >> (8 * i)));
  }
  void I64(int64_t v) { U64(static_cast<uint64_t>(v)); }
  void F64(double v) {
    uint64_t bits;
    std::memcpy(&bits, &v, sizeof(bits));
    U64(bits);
  }
  void Str(const std::string& s) {
    U64(s.size());
    out_.append(s);
  }
  void Vec(const Vector& v) {
    U64(static_cast<uint64_t>(v.size()));
    for (Eigen::Index i = 0; i < v.size(); ++i) F64(v(i));
  }
  void Mat(const RowMatrix& m) {
    U64(static_cast<uint64_t>(m.rows()));
    U64(static_cast<uint64_t>(m.cols()));
    for (Eigen::Index r = 0; r < m.rows(); ++r) {
      for (Eigen::Index c = 0; c < m.cols(); ++c) F64(m(r, c));
    }
  }
  void Bytes(const char* data, size_t size) { out_.append(data, size); }
  std::string& out() { return out_; }

 private:
  std::string out_;
};

class Reader {
 public:
  explicit Reader(std::string_view in) : in_(in) {}
  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  size_t left() const { return in_.size() - pos_; }

  uint8_t U8(const char* what) {
    if (!Need(1, what)) return 0;
    return static_cast<uint8_t>(in_[pos_++]);
  }
  uint32_t U32(const char* what) {
    uint32_t v = 0;
    for (int i = 0; i < 4 && ok(); ++i) v |= static_cast<uint32_t>(U8(what)) << (8 * i);
    return v;
  }
  uint64_t U64(const char* what) {
    uint64_t v = 0;
    for (int i = 0; i < 8 && ok(); ++i) v |= static_cast<uint64_t>(U8(what)) << (8 * i);
    return v;
  }
  int64_t I64(const char* what) { return static_cast<int64_t>(U64(what)); }
  double F64(const char* what) {
    const uint64_t bits = U64(what);
    double v;
    std::memcpy(&v, &bits, sizeof(v));
    return v;
  }
  std::string Str(const char* what) {
    const uint64_t n = Count(what, 1);
    if (!Need(n, what)) return "";
    std::string s(in_.substr(pos_, n));
    pos_ += n;
    return s;
  }
  Vector Vec(const char* what) {
    const uint64_t n = Count(what, 8);
    Vector v(static_cast<Eigen::Index>(ok() ? n : 0));
    for (Eigen::Index i = 0; i < v.size() && ok(); ++i) v(i) = F64(what);
    return v;
  }
  RowMatrix Mat(const char* what) {
    const uint64_t rows = Count(what, 0);
    const uint64_t cols = Count(what, 0);
    if (ok() && rows != 0 && cols > kMaxElements / rows) Fail(what, "too many elements");
    if (ok() && rows * cols * 8 > left()) Fail(what, "truncated");
    RowMatrix m(ok() ? static_cast<Eigen::Index>(rows) : 0,
                ok() ? static_cast<Eigen::Index>(cols) : 0);
    for (Eigen::Index r = 0; r < m.rows() && ok(); ++r) {
      for (Eigen::Index c = 0; c < m.cols() && ok(); ++c) m(r, c) = F64(what);
    }
    return m;
  }
  void Fail(const char* what, const std::string& why) {
    if (error_.empty()) error_ = absl::StrCat(what, ": ", why);
  }

 private:
  // A count of elements of `element_bytes` each that must fit in what is left.
  uint64_t Count(const char* what, uint64_t element_bytes) {
    const uint64_t n = U64(what);
    if (!ok()) return 0;
    if (n > kMaxElements || (element_bytes > 0 && n * element_bytes > left())) {
      Fail(what, absl::StrCat("a count of ", n, " does not fit the ", left(), " bytes left"));
      return 0;
    }
    return n;
  }
  bool Need(uint64_t n, const char* what) {
    if (!ok()) return false;
    if (n > left()) {
      Fail(what, "truncated");
      return false;
    }
    return true;
  }

  std::string_view in_;
  size_t pos_ = 0;
  std::string error_;
};

}  // namespace totalgrad::binary

#endif  // TOTALGRAD_CORE_COMMON_BINARY_CODEC_H_
