// Result files: CSV time series and JSON summaries (the ParaView files: vtk.hpp). Numbers are
// written with 17 significant digits so that files round-trip exactly and runs can be compared
// byte for byte.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "crushdem/core/state_io.hpp"
#include "crushdem/particles/particle_store.hpp"

namespace crushdem {

/// Appends rows to a CSV file; the header is written with the first row. Each row is flushed so
/// that an interrupted run keeps everything it has finished.
class CsvWriter {
 public:
  explicit CsvWriter(std::string path) : path_(std::move(path)) {}
  ~CsvWriter();
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;
  void write(const std::vector<std::pair<std::string, double>>& row);
  /// Opens the file with just its header (rows of text follow with write_line).
  void start(const std::vector<std::string>& columns);
  /// Appends one preformatted line (rows with text fields), flushed.
  void write_line(const std::string& line);
  /// Bytes written so far (-1 before the first row); everything up to here is on disk.
  long long size() const;
  /// fnv1a64 of the bytes written so far (kept as they are written, so a checkpoint can record
  /// it without reading the file back).
  std::uint64_t digest() const { return digest_; }
  const std::vector<std::string>& columns() const { return columns_; }
  /// Continues a file written by an interrupted run: cuts it back to `size` bytes (what the
  /// checkpoint saw) and appends from there; size < 0 removes it (it had no row yet). With a
  /// `digest` (checkpoints from format 6 on) the first `size` bytes must still hash to it:
  /// otherwise the file was changed after the checkpoint and the run is refused, naming it.
  void resume(long long size, const std::vector<std::string>& columns,
              const std::uint64_t* digest = nullptr);
  /// A resumed file keeps the columns it was started with when this crushdem writes others (a
  /// resume by a newer build, `resume --keep-columns`): each row gives the header's columns by
  /// name and leaves the others out; a header column the row lacks is still refused. Without
  /// it such a resume is refused at the first row.
  void keep_columns(bool keep) { keep_columns_ = keep; }
  /// The columns of this crushdem's rows that keep_columns has left out so far, in row order.
  const std::vector<std::string>& left_out() const { return left_out_; }

 private:
  /// The row's values in the header's columns (keep_columns), noting what it leaves out.
  std::string kept_line(const std::vector<std::pair<std::string, double>>& row);
  void put(const std::string& text);  // writes, hashes and flushes
  void flush();  // throws RuntimeFailure naming the file when the bytes cannot be written
  std::string path_;
  std::FILE* f_ = nullptr;
  std::vector<std::string> columns_;
  std::uint64_t digest_ = kFnvOffset;
  bool resumed_ = false;  // its rows so far were written by the run's earlier process
  bool keep_columns_ = false;
  std::vector<std::string> left_out_;
  std::vector<std::string> row_names_;  // the row layout `at_` maps (rows repeat their layout)
  std::vector<std::size_t> at_;         // the row's index of each header column
};

/// A flat JSON object of numbers and strings, written in the order given.
struct JsonObject {
  std::vector<std::pair<std::string, std::string>> fields;  // values already JSON-encoded
  void number(const std::string& key, double v);
  void integer(const std::string& key, long long v);
  void boolean(const std::string& key, bool v);
  void string(const std::string& key, const std::string& v);
  void object(const std::string& key, const JsonObject& v);
  void array(const std::string& key, const std::vector<JsonObject>& v);
  void numbers(const std::string& key, const std::vector<double>& v);
  void strings(const std::string& key, const std::vector<std::string>& v);
  std::string dump(int indent = 0) const;
  /// The number written under `key` (NaN when there is none or it is not a number).
  double number_value(const std::string& key) const;
};
void write_text_file(const std::string& path, const std::string& text);
/// The largest file crushdem reads whole (checkpoints of 10^7 grains stay far below it).
inline constexpr std::uintmax_t kMaxReadBytes = std::uintmax_t{64} << 30;
/// The whole file as bytes. Only a regular file (a link is followed) of at most `max_bytes` is
/// read: a device, a pipe or a larger file is refused with a ConfigError naming the path, as is
/// a file that cannot be read.
std::string read_binary_file(const std::string& path, std::uintmax_t max_bytes = kMaxReadBytes);
/// fnv1a64 of the file's first `bytes` bytes (all of it when bytes < 0); ConfigError naming the
/// path when it is missing, shorter or unreadable.
std::uint64_t file_digest(const std::string& path, long long bytes = -1);
/// Writes PATH.tmp and renames it onto PATH, so that a crash while writing leaves the previous
/// file intact (checkpoints, cached states).
void write_file_atomically(const std::string& path, const std::string& bytes);

std::string format_double(double v);

}  // namespace crushdem
