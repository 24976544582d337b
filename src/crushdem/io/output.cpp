#include "crushdem/io/output.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "crushdem/core/error.hpp"

namespace crushdem {

std::string format_double(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

CsvWriter::~CsvWriter() {
  if (f_) std::fclose(f_);
}

void CsvWriter::flush() {
  // Every row is on disk before the run goes on: a full disk or a lost mount stops the run at
  // once, naming the file, instead of leaving a silently truncated series (the last checkpoint
  // stays; resume continues from it).
  if (std::fflush(f_) != 0 || std::ferror(f_)) {
    const int err = errno;
    throw RuntimeFailure("cannot write '" + path_ + "': " + std::strerror(err) +
                         "; the run stops here (its last checkpoint is kept)");
  }
}

void CsvWriter::put(const std::string& text) {
  std::fputs(text.c_str(), f_);
  digest_ = fnv1a64(text.data(), text.size(), digest_);
  flush();
}

void CsvWriter::start(const std::vector<std::string>& columns) {
  if (f_) std::fclose(f_);
  f_ = std::fopen(path_.c_str(), "w");
  if (!f_) throw ConfigError("cannot write '" + path_ + "'");
  columns_ = columns;
  digest_ = kFnvOffset;
  std::string header;
  for (std::size_t k = 0; k < columns.size(); ++k) {
    if (k) header += ',';
    header += columns[k];
  }
  header += '\n';
  put(header);
}

void CsvWriter::write_line(const std::string& line) {
  if (!f_) throw std::logic_error("CsvWriter::write_line before start(): " + path_);
  // Text rows cannot be mapped by name: a resumed file refuses another count of fields.
  const auto fields = static_cast<std::size_t>(std::count(line.begin(), line.end(), ',')) + 1;
  if (resumed_ && fields != columns_.size()) {
    throw ConfigError("cannot go on with '" + path_ + "': this crushdem writes " +
                      std::to_string(fields) + " fields to a row and the file has " +
                      std::to_string(columns_.size()) +
                      " columns (another build wrote it: run.log names the builds that ran the "
                      "run); go on with the build that wrote it, --keep-columns cannot map these "
                      "rows");
  }
  put(line + "\n");
}

void CsvWriter::write(const std::vector<std::pair<std::string, double>>& row) {
  if (!f_) {
    std::vector<std::string> columns;
    columns.reserve(row.size());
    for (const auto& kv : row) columns.push_back(kv.first);
    start(columns);
  }
  std::size_t k = 0;  // the first column that differs from the header's
  while (k < row.size() && k < columns_.size() && row[k].first == columns_[k]) ++k;
  if ((k < row.size() || k < columns_.size()) && resumed_ && keep_columns_) {
    put(kept_line(row));
    return;
  }
  if (k < row.size() || k < columns_.size()) {
    const std::string here = k < row.size() ? "'" + row[k].first + "'" : "nothing";
    const std::string file = k < columns_.size() ? "'" + columns_[k] + "'" : "nothing";
    const std::string where = "column " + std::to_string(k + 1) + " is " + here +
                              " in this crushdem's rows and " + file + " in the file";
    if (resumed_) {
      // A crushdem that writes other columns than the one that started the run (a column added
      // since): its rows would not line up with the file's header.
      throw ConfigError("cannot go on with '" + path_ + "': it was written with other columns (" +
                        where + "), by another build of crushdem (run.log names the builds " +
                        "that ran the run); go on with that build, or with this one and " +
                        "--keep-columns (`crushdem-sand resume DIR --keep-columns`, or with " +
                        "`run --from` for a branch), the files keeping their columns");
    }
    throw std::logic_error("CSV row of '" + path_ + "' does not match its header: " + where);
  }
  std::string line;
  for (std::size_t c = 0; c < row.size(); ++c) {
    if (c) line += ',';
    line += format_double(row[c].second);
  }
  line += '\n';
  put(line);
}

std::string CsvWriter::kept_line(const std::vector<std::pair<std::string, double>>& row) {
  bool same = row_names_.size() == row.size();
  for (std::size_t c = 0; same && c < row.size(); ++c) same = row_names_[c] == row[c].first;
  if (!same) {
    row_names_.clear();
    for (const auto& kv : row) row_names_.push_back(kv.first);
    at_.clear();
    for (const std::string& name : columns_) {
      const auto it = std::find(row_names_.begin(), row_names_.end(), name);
      if (it == row_names_.end()) {
        throw ConfigError("cannot go on with '" + path_ + "': it has a column '" + name +
                          "' that this crushdem does not write, so its rows cannot go on even "
                          "with --keep-columns; go on with the build that wrote it (run.log "
                          "names the builds that ran the run)");
      }
      at_.push_back(static_cast<std::size_t>(it - row_names_.begin()));
    }
    for (const std::string& name : row_names_) {
      if (std::find(columns_.begin(), columns_.end(), name) == columns_.end() &&
          std::find(left_out_.begin(), left_out_.end(), name) == left_out_.end()) {
        left_out_.push_back(name);
      }
    }
  }
  std::string line;
  for (std::size_t c = 0; c < at_.size(); ++c) {
    if (c) line += ',';
    line += format_double(row[at_[c]].second);
  }
  return line + '\n';
}

long long CsvWriter::size() const {
  return f_ ? static_cast<long long>(std::ftell(f_)) : -1;
}

void CsvWriter::resume(long long size, const std::vector<std::string>& columns,
                       const std::uint64_t* digest) {
  namespace fs = std::filesystem;
  if (f_) std::fclose(f_);
  f_ = nullptr;
  columns_.clear();
  digest_ = kFnvOffset;
  resumed_ = size >= 0;
  std::error_code ec;
  if (size < 0) {
    fs::remove(path_, ec);
    return;
  }
  // A result file missing or changed is a refusal, as for the kept files (run/driver.cpp): the
  // directory's state, not a failed run (ConfigError, exit status 2).
  if (!fs::exists(path_) || fs::file_size(path_) < static_cast<std::uintmax_t>(size)) {
    throw ConfigError("cannot resume: '" + path_ + "' is missing or shorter than at the " +
                      "checkpoint (" + std::to_string(size) + " bytes)");
  }
  digest_ = file_digest(path_, size);  // continued as rows are appended
  if (digest && digest_ != *digest) {
    throw ConfigError("cannot resume: '" + path_ +
                      "' was changed after the checkpoint (its first " + std::to_string(size) +
                      " bytes differ from what the run wrote); restore it or start the run "
                      "again with --overwrite");
  }
  fs::resize_file(path_, static_cast<std::uintmax_t>(size), ec);
  if (ec) throw RuntimeFailure("cannot resume: '" + path_ + "': " + ec.message());
  f_ = std::fopen(path_.c_str(), "a");
  if (!f_) throw RuntimeFailure("cannot resume: cannot append to '" + path_ + "'");
  columns_ = columns;
}

namespace {
std::string json_escape(const std::string& s) {
  std::string o = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      o += '\\';
      o += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char b[8];
      std::snprintf(b, sizeof b, "\\u%04x", c);
      o += b;
    } else {
      o += c;
    }
  }
  return o + "\"";
}
}  // namespace

void JsonObject::number(const std::string& key, double v) {
  fields.emplace_back(key, std::isfinite(v) ? format_double(v) : "null");
}
void JsonObject::integer(const std::string& key, long long v) {
  fields.emplace_back(key, std::to_string(v));
}
void JsonObject::boolean(const std::string& key, bool v) {
  fields.emplace_back(key, v ? "true" : "false");
}
void JsonObject::string(const std::string& key, const std::string& v) {
  fields.emplace_back(key, json_escape(v));
}
void JsonObject::object(const std::string& key, const JsonObject& v) {
  fields.emplace_back(key, v.dump(2));
}

void JsonObject::array(const std::string& key, const std::vector<JsonObject>& v) {
  std::string o = "[";
  for (std::size_t k = 0; k < v.size(); ++k) o += (k ? ", " : "") + v[k].dump(4);
  fields.emplace_back(key, o + "]");
}
void JsonObject::numbers(const std::string& key, const std::vector<double>& v) {
  std::string o = "[";
  for (std::size_t k = 0; k < v.size(); ++k) {
    o += (k ? ", " : "") + (std::isfinite(v[k]) ? format_double(v[k]) : std::string("null"));
  }
  fields.emplace_back(key, o + "]");
}

void JsonObject::strings(const std::string& key, const std::vector<std::string>& v) {
  std::string o = "[";
  for (std::size_t k = 0; k < v.size(); ++k) o += (k ? ", " : "") + json_escape(v[k]);
  fields.emplace_back(key, o + "]");
}

double JsonObject::number_value(const std::string& key) const {
  for (const auto& [k, v] : fields) {
    if (k != key) continue;
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    return end != v.c_str() && *end == '\0' ? x : std::nan("");
  }
  return std::nan("");
}

std::string JsonObject::dump(int indent) const {
  const std::string pad(static_cast<std::size_t>(indent) + 2, ' ');
  std::string o = "{\n";
  for (std::size_t k = 0; k < fields.size(); ++k) {
    o += pad + json_escape(fields[k].first) + ": " + fields[k].second;
    o += k + 1 < fields.size() ? ",\n" : "\n";
  }
  return o + std::string(static_cast<std::size_t>(indent), ' ') + "}";
}

void write_text_file(const std::string& path, const std::string& text) {
  std::ofstream f(path);
  if (!f) throw ConfigError("cannot write '" + path + "'");
  f << text;
  f.flush();  // a full disk shows here, not at the close
  if (!f) throw ConfigError("cannot write '" + path + "'");
}

std::string read_binary_file(const std::string& path, std::uintmax_t max_bytes) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) throw ConfigError("cannot read '" + path + "': no such file");
  if (!fs::is_regular_file(st)) {
    throw ConfigError("cannot read '" + path + "': not a regular file (a device, pipe or folder)");
  }
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) throw ConfigError("cannot read '" + path + "': " + ec.message());
  if (size > max_bytes) {
    throw ConfigError("cannot read '" + path + "': " + std::to_string(size) +
                      " bytes, more than the " + std::to_string(max_bytes) +
                      " bytes such a file can hold");
  }
  std::ifstream f(path, std::ios::binary);
  if (!f) throw ConfigError("cannot read '" + path + "'");
  std::string bytes(static_cast<std::size_t>(size), '\0');
  f.read(bytes.data(), static_cast<std::streamsize>(size));
  if (f.gcount() != static_cast<std::streamsize>(size)) {
    throw ConfigError("cannot read '" + path + "': it changed while it was read");
  }
  return bytes;
}

std::uint64_t file_digest(const std::string& path, long long bytes) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw ConfigError("cannot read '" + path + "'");
  std::uint64_t hash = kFnvOffset;
  std::vector<char> buf(std::size_t{1} << 20);
  long long left = bytes;
  while (bytes < 0 || left > 0) {
    const auto want = bytes < 0 ? static_cast<std::streamsize>(buf.size())
                                : static_cast<std::streamsize>(std::min<long long>(
                                      left, static_cast<long long>(buf.size())));
    f.read(buf.data(), want);
    const std::streamsize got = f.gcount();
    hash = fnv1a64(buf.data(), static_cast<std::size_t>(got), hash);
    left -= got;
    if (got < want) break;
  }
  if (bytes >= 0 && left > 0) {
    throw ConfigError("cannot read '" + path + "': shorter than " + std::to_string(bytes) +
                      " bytes");
  }
  return hash;
}

void write_file_atomically(const std::string& path, const std::string& bytes) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    f.flush();
    if (!f) throw RuntimeFailure("cannot write '" + tmp + "'");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw RuntimeFailure("cannot write '" + path + "': " + ec.message());
}

}  // namespace crushdem
