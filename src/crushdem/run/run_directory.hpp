// The rules of a run directory: a new run starts in a new or empty directory (or replaces an
// old crushdem run with overwrite), a lock keeps a second run out while one writes, and a branch
// starts from another run's state at a stage boundary with that run's files as they stood there.
#pragma once

#include <cstddef>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "crushdem/io/config.hpp"

namespace crushdem {

class Driver;

/// DIR/manifest.json: marks DIR as a crushdem run directory and lists every entry crushdem
/// created in it (names at its top level: result files, vtk/, stages/, figures), so that
/// --overwrite and a restarted resume remove those and nothing else. It is rewritten (whole,
/// atomically) each time an entry is added.
class RunManifest {
 public:
  static constexpr const char* kName = "manifest.json";
  /// The manifest of `dir` as it stands (empty when there is none; a manifest that cannot be
  /// read is refused, naming it).
  explicit RunManifest(std::filesystem::path dir);
  /// Records a top-level entry crushdem is about to create (nothing happens if listed).
  void add(const std::string& name);
  /// A run of a release before manifests, resumed: lists the files such a run wrote that are
  /// there (its CSVs are added as the resumed run names them).
  void adopt_earlier_run();
  const std::vector<std::string>& names() const { return names_; }
  static bool present(const std::filesystem::path& dir);

 private:
  void write() const;
  std::filesystem::path dir_;
  std::vector<std::string> names_;
};

/// A new run starts in a new or empty directory: finished or stopped work is never overwritten
/// or mixed with a new run's files unless asked (overwrite), and then only in a directory
/// crushdem's manifest marks as a run, and only the entries it lists are removed (a user's
/// other files stay). The current directory and its parents are never cleared. The errors say
/// what the directory holds and how to go on (resume, another --out, --overwrite).
void prepare_new_run_directory(const std::filesystem::path& dir, bool overwrite,
                               bool restart = false);

/// A branch never writes into the run it starts from: `out` may be neither `from` nor a folder
/// that holds it (ConfigError naming --out otherwise).
void check_branch_directories(const std::filesystem::path& out, const std::filesystem::path& from);

/// An exclusive lock on DIR/.lock for the life of the run: a second run or resume into the
/// same directory stops at once instead of splicing its rows into the first one's files.
class DirectoryLock {
 public:
  explicit DirectoryLock(const std::filesystem::path& dir);
  ~DirectoryLock();
  DirectoryLock(const DirectoryLock&) = delete;
  DirectoryLock& operator=(const DirectoryLock&) = delete;

 private:
  int fd_ = -1;
};

/// The first key where two resolved configurations differ, with both values ("" when they are
/// the same): "body[0].friction = 0.5 (the original run's: 0.275)", `original_source` naming
/// where the first came from ("the original run", "the checkpoint"). The top-level sections in
/// `skip` are left out, and the keys `ignored` of section `partly`.
std::string config_difference(const toml::Table& original, const toml::Table& current,
                              const std::string& original_source,
                              const std::set<std::string>& skip = {},
                              const std::string& partly = {},
                              const std::set<std::string>& ignored = {});

/// Where a branch starts (the stage index, from `spec`: an index, a name, or empty for the first
/// stage that differs) and whether its configuration may start there: the stages before it, the
/// grains, the material and the strength draws must be the original's (compared key by key on
/// the resolved TOML; errors name the first key that differs).
std::size_t branch_stage(const std::string& original_text, const RunConfig& cfg,
                         const std::string& spec, const std::filesystem::path& from);

/// Copies the original run's result files (CSV) into a branch's directory, each recorded in
/// `manifest` first; returns their names. A file of that name already there (a user's) is
/// refused, naming it, rather than replaced.
std::vector<std::string> copy_run_files(const std::filesystem::path& from,
                                        const std::filesystem::path& dir, RunManifest& manifest);

/// After the branch state is loaded: the CSVs it does not list are removed (the original wrote
/// them later); the files it keeps (the sample, its snapshots, the states of the stages before
/// the branch) are copied and checked against their recorded checksums.
void keep_branch_files(const std::filesystem::path& from, const std::filesystem::path& dir,
                       const Driver& driver, std::size_t stage,
                       const std::vector<std::string>& copied);

}  // namespace crushdem
