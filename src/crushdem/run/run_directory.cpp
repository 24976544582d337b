#include "crushdem/run/run_directory.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <set>

#include "crushdem/core/build_info.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/run/driver.hpp"

namespace crushdem {

namespace {

constexpr const char* kLockName = ".lock";

// One value as TOML text (for comparing two configurations key by key).
std::string toml_text(const toml::Value& v) {
  toml::Table t;
  t["v"] = v;
  return toml::serialize(t);
}

// One value as it is written after `key = ` (for the messages).
std::string value_text(const toml::Value* v) {
  if (!v) return "not set";
  if (v->type == toml::Type::Array && !v->array.empty() &&
      v->array.front().type == toml::Type::Table) {
    return std::to_string(v->array.size()) + (v->array.size() == 1 ? " entry" : " entries");
  }
  std::string t = toml_text(*v);
  if (t.rfind("v = ", 0) != 0) return "a table";
  t = t.substr(4);
  while (!t.empty() && t.back() == '\n') t.pop_back();
  return t.size() > 80 ? t.substr(0, 77) + "..." : t;
}

// The first key under `prefix` where two values differ, with both values ("" when they are
// equal): "body[0].friction = 0.5 (the original run's: 0.275)", `a_source` naming where a came
// from. Tables and arrays of tables of one length are compared entry by entry.
std::string first_difference(const toml::Value* a, const toml::Value* b, const std::string& prefix,
                             const std::string& a_source,
                             const std::set<std::string>& ignored = {}) {
  const auto differ = [&]() {
    if (!b) return prefix + " is not set here (" + a_source + "'s: " + value_text(a) + ")";
    if (!a) return prefix + " = " + value_text(b) + " (not set in " + a_source + ")";
    return prefix + " = " + value_text(b) + " (" + a_source + "'s: " + value_text(a) + ")";
  };
  if (!a || !b) return differ();
  if (a->type == toml::Type::Array && b->type == toml::Type::Array &&
      a->array.size() == b->array.size() && !a->array.empty() &&
      a->array.front().type == toml::Type::Table) {  // ([[body]]; arrays of values: whole)
    for (std::size_t i = 0; i < a->array.size(); ++i) {
      std::string d = first_difference(&a->array[i], &b->array[i],
                                       prefix + "[" + std::to_string(i) + "]", a_source);
      if (!d.empty()) return d;
    }
    return "";
  }
  if (a->type == toml::Type::Table && b->type == toml::Type::Table) {
    std::set<std::string> keys;
    for (const auto& [k, v] : *a->table) keys.insert(k);
    for (const auto& [k, v] : *b->table) keys.insert(k);
    for (const std::string& k : keys) {
      if (ignored.count(k)) continue;
      const auto ia = a->table->find(k), ib = b->table->find(k);
      std::string d = first_difference(ia == a->table->end() ? nullptr : &ia->second,
                                       ib == b->table->end() ? nullptr : &ib->second,
                                       prefix + "." + k, a_source);
      if (!d.empty()) return d;
    }
    return "";
  }
  return toml_text(*a) == toml_text(*b) ? "" : differ();
}

}  // namespace

std::string config_difference(const toml::Table& a, const toml::Table& b,
                              const std::string& a_source, const std::set<std::string>& skip,
                              const std::string& partly, const std::set<std::string>& ignored) {
  std::set<std::string> sections;
  for (const auto& [key, v] : a) sections.insert(key);
  for (const auto& [key, v] : b) sections.insert(key);
  for (const std::string& key : sections) {
    if (skip.count(key)) continue;
    const auto ia = a.find(key), ib = b.find(key);
    std::string d = first_difference(ia == a.end() ? nullptr : &ia->second,
                                     ib == b.end() ? nullptr : &ib->second, key, a_source,
                                     key == partly ? ignored : std::set<std::string>{});
    if (!d.empty()) return d;
  }
  return "";
}

RunManifest::RunManifest(std::filesystem::path dir) : dir_(std::move(dir)) {
  const std::filesystem::path path = dir_ / kName;
  if (!std::filesystem::exists(path)) return;
  const std::string text = read_binary_file(path.string(), std::uintmax_t{1} << 24);
  // The list under "entries": JSON strings, as write() puts them.
  const std::size_t key = text.find("\"entries\"");
  std::size_t k = key == std::string::npos ? key : text.find('[', key);
  const auto damaged = [&]() {
    return ConfigError("'" + path.string() +
                       "' is damaged (no list of entries): crushdem cannot tell its files from "
                       "others there; restore it or remove the folder yourself");
  };
  if (k == std::string::npos) throw damaged();
  for (++k; k < text.size() && text[k] != ']'; ++k) {
    if (text[k] != '"') continue;
    std::string name;
    for (++k; k < text.size() && text[k] != '"'; ++k) {
      if (text[k] == '\\' && k + 1 < text.size()) ++k;
      name += text[k];
    }
    if (k >= text.size()) throw damaged();
    const std::filesystem::path p(name);
    // Only names at the top level: a damaged list must not reach outside the directory.
    if (name.empty() || name == "." || name == ".." || p.has_parent_path() || p.is_absolute()) {
      throw ConfigError("'" + path.string() + "' lists '" + name.substr(0, 80) +
                        "', which is not a name in the run directory: it is damaged");
    }
    if (std::find(names_.begin(), names_.end(), name) == names_.end()) names_.push_back(name);
  }
  if (k >= text.size()) throw damaged();
}

bool RunManifest::present(const std::filesystem::path& dir) {
  std::error_code ec;
  return std::filesystem::is_regular_file(dir / kName, ec);
}

void RunManifest::add(const std::string& name) {
  if (std::find(names_.begin(), names_.end(), name) != names_.end()) return;
  // What another writer added meanwhile (`crushdem-sand plot`'s figures) is kept.
  for (const std::string& n : RunManifest(dir_).names_) {
    if (std::find(names_.begin(), names_.end(), n) == names_.end()) names_.push_back(n);
  }
  names_.push_back(name);
  write();
}

void RunManifest::write() const {
  std::string list;
  for (const std::string& n : names_) {
    std::string quoted = "\"";
    for (char c : n) quoted += (c == '"' || c == '\\') ? std::string("\\") + c : std::string(1, c);
    list += (list.empty() ? "\n    " : ",\n    ") + quoted + "\"";
  }
  JsonObject m;
  m.boolean("crushdem_run", true);
  m.string("version", CRUSHDEM_VERSION);
  m.fields.emplace_back("entries", "[" + list + "\n  ]");
  write_file_atomically((dir_ / kName).string(), m.dump() + "\n");
}

namespace {

// The files and folders a run writes besides its CSVs, by name.
constexpr const char* kRunEntries[] = {"config.toml",  "checkpoint.bin", "checkpoint.bin.tmp",
                                       "summary.json", "timing.json",    "branch.json",
                                       "sample.txt",   "stages",         "run.log"};

// A run directory of an earlier release (before manifests): its config.toml and one of the
// files only a run writes.
bool earlier_run(const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  return fs::exists(dir / "config.toml") &&
         (fs::exists(dir / "checkpoint.bin") || fs::exists(dir / "summary.json") ||
          fs::exists(dir / "timing.json"));
}

// `dir` is the current directory or holds it.
bool holds_current_directory(const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path d = fs::weakly_canonical(dir, ec);
  fs::path cwd = fs::current_path(ec);
  if (ec) return false;
  for (; !cwd.empty(); cwd = cwd.parent_path()) {
    if (cwd == d) return true;
    if (cwd == cwd.parent_path()) break;
  }
  return false;
}

}  // namespace

void prepare_new_run_directory(const std::filesystem::path& dir, bool overwrite, bool restart) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(dir, ec)) return;
  if (!fs::is_directory(dir, ec)) {
    throw ConfigError("--out '" + dir.string() + "': exists and is not a directory");
  }
  std::vector<fs::path> entries;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
    if (e.path().filename() != kLockName) entries.push_back(e.path());
  }
  if (ec) throw ConfigError("--out '" + dir.string() + "': cannot read it: " + ec.message());
  if (entries.empty()) return;
  const bool is_run = RunManifest::present(dir);
  if (!overwrite) {
    std::string what;
    if (fs::exists(dir / "checkpoint.bin")) {
      what =
          "holds a run that stopped before its end (checkpoint.bin): continue it with "
          "`crushdem-sand resume " +
          dir.string() + "`, or start it again with --overwrite";
    } else if (fs::exists(dir / "summary.json")) {
      what =
          "holds a finished run (summary.json): choose another --out, or replace it with "
          "--overwrite";
    } else if (is_run) {
      what =
          "holds a run that stopped before its first checkpoint: start it again with "
          "`crushdem-sand resume " +
          dir.string() + "` or --overwrite";
    } else {
      what =
          "is not empty and is not a crushdem run directory: choose a new or empty "
          "directory";
    }
    throw ConfigError("--out '" + dir.string() + "' " + what);
  }
  if (!restart && holds_current_directory(dir)) {
    throw ConfigError("--out '" + dir.string() +
                      "' is the current directory or holds it, which --overwrite never clears: "
                      "give the run a folder of its own");
  }
  if (!is_run) {
    throw ConfigError(
        "--out '" + dir.string() + "' " +
        (earlier_run(dir)
             ? "holds a run of an earlier crushdem (no manifest.json, so its files cannot be "
               "told from others): --overwrite replaces only runs with a manifest; remove the "
               "folder yourself or choose another --out"
             : "is not a crushdem run directory (no manifest.json), and --overwrite replaces "
               "only crushdem runs: choose a new or empty directory"));
  }
  const RunManifest manifest(dir);
  for (const std::string& name : manifest.names()) {
    if (name == kLockName) continue;
    fs::remove_all(dir / name, ec);
    if (ec) {
      throw ConfigError("--overwrite: cannot remove '" + (dir / name).string() +
                        "': " + ec.message());
    }
  }
  fs::remove(dir / RunManifest::kName, ec);
}

void RunManifest::adopt_earlier_run() {
  for (const char* name : kRunEntries) {
    if (std::filesystem::exists(dir_ / name)) add(name);
  }
}

void check_branch_directories(const std::filesystem::path& out, const std::filesystem::path& from) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path o = fs::weakly_canonical(out, ec);
  for (fs::path f = fs::weakly_canonical(from, ec); !f.empty(); f = f.parent_path()) {
    if (f == o) {
      throw ConfigError("--out '" + out.string() + "' " +
                        (f == fs::weakly_canonical(from, ec) ? "is" : "holds") +
                        " the run it branches from (--from '" + from.string() +
                        "'): a branch writes into a folder of its own");
    }
    if (f == f.parent_path()) break;
  }
}

DirectoryLock::DirectoryLock(const std::filesystem::path& dir) {
  const std::string path = (dir / kLockName).string();
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) throw ConfigError("cannot open the lock file '" + path + "'");
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd_);
    throw ConfigError("'" + dir.string() +
                      "' is being written by another crushdem run (its .lock is held); wait "
                      "for it to end or stop it first");
  }
}

DirectoryLock::~DirectoryLock() {
  ::close(fd_);
}

std::size_t branch_stage(const std::string& original_text, const RunConfig& cfg,
                         const std::string& spec, const std::filesystem::path& from) {
  const std::string src = (from / "config.toml").string();
  const RunConfig old =
      saved_run_config_from_toml(toml::parse(original_text, src), src, from.string());
  const toml::Table a = to_toml(old), b = to_toml(cfg);
  const auto stages_of = [](const toml::Table& t) {
    const auto it = t.find("stage");
    return it == t.end() ? std::vector<toml::Value>{} : it->second.array;
  };
  const std::vector<toml::Value> sa = stages_of(a), sb = stages_of(b);
  if (sa.empty()) throw ConfigError("--from '" + from.string() + "': the run has no [[stage]]");
  std::size_t k = 0;
  if (spec.empty()) {
    while (k < sa.size() && k < sb.size() && toml_text(sa[k]) == toml_text(sb[k])) ++k;
    if (k == sa.size()) {
      throw ConfigError("--from '" + from.string() +
                        "': the stages are the original's; name the stage to branch from "
                        "(--from DIR:STAGE, its index or name)");
    }
  } else if (std::all_of(spec.begin(), spec.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    k = spec.size() > 9 ? sa.size() : std::stoul(spec);  // (too many digits: refused below)
  } else {
    k = sa.size();
    for (std::size_t i = 0; i < old.stages.size(); ++i) {
      if (old.stages[i].name == spec) k = std::min(k, i);
    }
    if (k == sa.size()) {
      std::string names;
      for (const auto& st : old.stages) names += (names.empty() ? "" : ", ") + st.name;
      throw ConfigError(bad_value("--from", spec, "a stage of the original run (" + names + ")"));
    }
  }
  if (k >= sa.size()) {
    throw ConfigError(
        bad_value("--from", spec, "a stage index below " + std::to_string(sa.size())));
  }
  for (std::size_t i = 0; i < k; ++i) {
    const std::string d = first_difference(&sa[i], i < sb.size() ? &sb[i] : nullptr,
                                           "stage[" + std::to_string(i) + "]", "the original run");
    if (!d.empty()) {
      throw ConfigError(d + ": differs from the original run, but a branch at stage " +
                        std::to_string(k) + " keeps the stages before it as they ran");
    }
  }
  // Crushing keys that act at run time only (the strengths and cracks already drawn stay).
  const std::set<std::string> runtime = {"crack_growth", "v0",       "n",
                                         "r_prime",      "interval", "density_scaling"};
  // `parameters` names where the keys came from; their values are compared in their sections.
  const std::string d = config_difference(a, b, "the original run",
                                          {"stage", "output", "parameters"}, "crushing", runtime);
  if (!d.empty()) {
    throw ConfigError(d +
                      ": cannot change in a branch (it sets the grains, the material or a "
                      "state drawn before the branch; a branch may change the stages from its "
                      "own on, [output] and crushing's " +
                      "crack_growth, v0, n, r_prime, interval, density_scaling)");
  }
  return k;
}

std::vector<std::string> copy_run_files(const std::filesystem::path& from,
                                        const std::filesystem::path& dir, RunManifest& manifest) {
  namespace fs = std::filesystem;
  std::vector<std::string> copied;
  for (const fs::directory_entry& e : fs::directory_iterator(from)) {
    if (!e.is_regular_file() || e.path().extension() != ".csv") continue;
    const std::string name = e.path().filename().string();
    if (fs::exists(dir / name)) {
      throw ConfigError("--out '" + dir.string() + "' holds " + name +
                        ", which the branch would copy from --from '" + from.string() +
                        "': move it away or choose another --out");
    }
    manifest.add(name);
    fs::copy_file(e.path(), dir / name);
    copied.push_back(name);
  }
  return copied;
}

void keep_branch_files(const std::filesystem::path& from, const std::filesystem::path& dir,
                       const Driver& driver, std::size_t stage,
                       const std::vector<std::string>& copied) {
  namespace fs = std::filesystem;
  const std::vector<std::string> listed = driver.file_names();
  // Only what the branch copied and its state does not list (the original wrote it later).
  for (const std::string& name : copied) {
    if (std::find(listed.begin(), listed.end(), name) == listed.end()) fs::remove(dir / name);
  }
  fs::create_directories(dir / "vtk");
  const auto keep = [&](const std::string& file) {
    const fs::path f = from / file;
    if (!fs::exists(f)) return;
    fs::create_directories((dir / file).parent_path());
    fs::copy_file(f, dir / file, fs::copy_options::overwrite_existing);
  };
  // Format 6 on: every file the state lists; then checked against its checksum.
  for (const KeptFile& k : driver.kept_files()) keep(k.path);
  for (std::size_t k = 0; k < driver.legacy_snapshots(); ++k) {
    for (const char* kind : {"particles_", "box_"})
      keep("vtk/" + (kind + ordinal_stamp(k)) + ".vtk");
  }
  for (const Snapshot& snap : driver.snapshot_list()) {
    for (const std::string& kind : driver.snapshot_kinds()) {
      keep("vtk/" + kind + "_" + step_stamp(snap.step) + ".vtp");
    }
  }
  driver.write_collections();
  fs::create_directories(dir / "stages");
  for (std::size_t k = 0; k < stage; ++k) keep("stages/stage_" + std::to_string(k) + ".bin");
  driver.check_kept_files();
}

}  // namespace crushdem
