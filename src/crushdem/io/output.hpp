// Result files: CSV time series and JSON summaries (the ParaView files: vtk.hpp). Numbers are
// written with 17 significant digits so that files round-trip exactly and runs can be compared
// byte for byte.
#pragma once

#include <cstdio>
#include <string>
#include <utility>
#include <vector>

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
  const std::vector<std::string>& columns() const { return columns_; }
  /// Continues a file written by an interrupted run: cuts it back to `size` bytes (what the
  /// checkpoint saw) and appends from there; size < 0 removes it (it had no row yet).
  void resume(long long size, const std::vector<std::string>& columns);

 private:
  void flush();  // throws RuntimeFailure naming the file when the bytes cannot be written
  std::string path_;
  std::FILE* f_ = nullptr;
  std::vector<std::string> columns_;
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
  std::string dump(int indent = 0) const;
  /// The number written under `key` (NaN when there is none or it is not a number).
  double number_value(const std::string& key) const;
};
void write_text_file(const std::string& path, const std::string& text);
/// The whole file as bytes (ConfigError naming the path when it cannot be read).
std::string read_binary_file(const std::string& path);
/// Writes PATH.tmp and renames it onto PATH, so that a crash while writing leaves the previous
/// file intact (checkpoints, cached states).
void write_file_atomically(const std::string& path, const std::string& bytes);

std::string format_double(double v);

}  // namespace crushdem
