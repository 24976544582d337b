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
/// the ParaView snapshots by step and time (for the .pvd collections); 6 records a checksum of
/// each result file's bytes and the size and checksum of every file written whole before it
/// (sample, snapshots, stage states), which resume and branches check; 7 keeps each ParaView
/// frame's ageing clock; 8 lists the crushdem builds that ran the run so far.
constexpr int kStateVersion = 8;

/// The start value of fnv1a64, for a hash continued over pieces.
inline constexpr std::uint64_t kFnvOffset = 14695981039346656037ULL;

/// 64-bit FNV-1a hash of the bytes (checkpoint checksums, settled-state headers, result files);
/// `hash` continues one over earlier bytes.
inline std::uint64_t fnv1a64(const char* data, std::size_t n, std::uint64_t hash = kFnvOffset) {
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
  /// A count of entries of at least one byte each read just now: more than the bytes left
  /// means a damaged or foreign file (refused before anything is sized by it).
  void check_count(std::uint64_t n, const char* what) const {
    if (n > buf_.size() - pos_) fail(what);
  }
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

/// One declaration of an object's state serves both directions (as cereal's `serialize`): an
/// object that keeps state between steps has `void state(StateArchive& a)`, which names each
/// field once, in file order; the archive writes it (save_state()) or reads it into the same
/// member (load_state()). A field that a later format added says since which
/// (`a.since(3, v)`): an older file does not hold it, and the member keeps its value. Checks
/// that only a read needs go under `if (a.loading())`. kStateVersion is the newest `since`.
class StateArchive {
 public:
  explicit StateArchive(StateWriter& out) : out_(&out) {}
  explicit StateArchive(StateReader& in) : in_(&in) {}
  bool loading() const { return in_ != nullptr; }
  /// The format being read, or kStateVersion when writing.
  int version() const { return in_ ? in_->version() : kStateVersion; }
  /// A named marker, checked when reading: a mismatch means a corrupt or foreign file.
  void section(const char* name) {
    if (out_) {
      out_->tag(name);
    } else {
      in_->tag(name);
    }
  }
  /// Fields: plain values, vectors of them, strings, lists of strings, random engines.
  template <class... T>
  void operator()(T&... v) {
    (one(v), ...);
  }
  /// Fields held from format `version` on.
  template <class... T>
  void since(int version, T&... v) {
    if (this->version() >= version) (one(v), ...);
  }
  /// A field with no member behind it (a count, a size): `v` is written, the value read is
  /// returned.
  template <class T>
  T value(T v) {
    one(v);
    return v;
  }
  /// value() for a number of entries that follow: a read count beyond the bytes left is
  /// refused.
  std::uint64_t count(std::uint64_t n, const char* what) {
    one(n);
    if (in_) in_->check_count(n, what);
    return n;
  }

 private:
  template <class T>
  void one(T& v) {
    if (out_) {
      out_->put(static_cast<const T&>(v));
    } else {
      in_->get(v);
    }
  }
  StateWriter* out_ = nullptr;
  StateReader* in_ = nullptr;
};

/// Writes the state `obj` declares (its state(StateArchive&), which a write only reads).
template <class T>
void save_state(const T& obj, StateWriter& out) {
  StateArchive a(out);
  const_cast<T&>(obj).state(a);
}

/// Reads the state `obj` declares.
template <class T>
void load_state(T& obj, StateReader& in) {
  StateArchive a(in);
  obj.state(a);
}

}  // namespace crushdem
