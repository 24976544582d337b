// Binary state for checkpoints: every module writes the variables it keeps between steps, bit
// for bit, so that a resumed run continues exactly as the uninterrupted one would have (a
// last-bit difference changes which grain breaks first). Native byte order: a checkpoint is read
// back by the same build on the same kind of machine, not exchanged.
#pragma once

#include <cstdint>
#include <cstring>
#include <random>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "crushdem/core/error.hpp"

namespace crushdem {

/// The current checkpoint format: 1 the first; 2 adds the wall-clock seconds by part; 3 the
/// rolling-resistance history of the contacts; 4 ends with the checksum of everything before it
/// (fnv1a64), so that a damaged file is refused instead of resumed into other results; 5 lists
/// the ParaView snapshots by step and time (for the .pvd collections).
constexpr int kStateVersion = 5;

/// 64-bit FNV-1a hash of the bytes (checkpoint checksums, settled-state headers).
inline std::uint64_t fnv1a64(const char* data, std::size_t n) {
  std::uint64_t hash = 14695981039346656037ULL;
  for (std::size_t i = 0; i < n; ++i) {
    hash = (hash ^ static_cast<unsigned char>(data[i])) * 1099511628211ULL;
  }
  return hash;
}

class StateWriter {
 public:
  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>, "put() writes plain values");
    const auto* b = reinterpret_cast<const char*>(&v);
    buf_.append(b, sizeof(T));
  }
  template <class T>
  void put(const std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>, "put() writes vectors of plain values");
    put<std::uint64_t>(v.size());
    if (!v.empty()) buf_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  void put(const std::string& s) {
    put<std::uint64_t>(s.size());
    buf_.append(s);
  }
  void put(const std::vector<std::string>& v) {
    put<std::uint64_t>(v.size());
    for (const std::string& s : v) put(s);
  }
  void put(const std::vector<bool>&) = delete;
  /// A random engine's full state (the standard text form, exact).
  void put(const std::mt19937_64& e) {
    std::ostringstream o;
    o << e;
    put(o.str());
  }
  /// A named marker, checked on reading: a mismatch means a corrupt or foreign file.
  void tag(const char* name) { put(std::string(name)); }
  const std::string& bytes() const { return buf_; }

 private:
  std::string buf_;
};

class StateReader {
 public:
  StateReader(std::string bytes, std::string source)
      : buf_(std::move(bytes)), source_(std::move(source)) {}

  template <class T>
  void get(T& v) {
    static_assert(std::is_trivially_copyable_v<T>, "get() reads plain values");
    need(sizeof(T));
    std::memcpy(&v, buf_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
  }
  template <class T>
  void get(std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>, "get() reads vectors of plain values");
    std::uint64_t n = 0;
    get(n);
    constexpr std::size_t kSize = sizeof(T);  // never 0 for a complete type
    if (n > (buf_.size() - pos_) / kSize) fail("array length");
    v.resize(n);
    if (n > 0) {
      std::memcpy(v.data(), buf_.data() + pos_, n * sizeof(T));
      pos_ += n * sizeof(T);
    }
  }
  void get(std::string& s) {
    std::uint64_t n = 0;
    get(n);
    need(n);
    s.assign(buf_.data() + pos_, n);
    pos_ += n;
  }
  void get(std::vector<std::string>& v) {
    std::uint64_t n = 0;
    get(n);
    if (n > buf_.size() - pos_) fail("list length");
    v.resize(n);
    for (std::string& s : v) get(s);
  }
  void get(std::mt19937_64& e) {
    std::string s;
    get(s);
    std::istringstream in(s);
    in >> e;
    if (!in) fail("random stream");
  }
  template <class T>
  T value() {
    T v{};
    get(v);
    return v;
  }
  void tag(const char* name) {
    std::string s;
    get(s);
    if (s != name) fail(std::string("section '") + name + "'");
  }
  bool at_end() const { return pos_ == buf_.size(); }
  /// The checkpoint format version being read (kStateVersion unless the file is older): lets a
  /// module skip what older files do not hold.
  int version() const { return version_; }
  void set_version(int v) { version_ = v; }

 private:
  void need(std::uint64_t n) const {
    if (n > buf_.size() - pos_) fail("data (the file ends early)");
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw RuntimeFailure("checkpoint '" + source_ + "' is corrupt or from another crushdem: " +
                         "cannot read its " + what + " at byte " + std::to_string(pos_));
  }
  std::string buf_;
  std::string source_;
  std::size_t pos_ = 0;
  int version_ = kStateVersion;
};

}  // namespace crushdem
