// The command-line front end: `crushdem-sand run|resume|check|bench ...`, parsed by CLI11. Kept in
// a library so the Python package's `crushdem-sand` command runs exactly the same code.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace crushdem::cli {

/// The command's name (the project is crushdem; `crushdem` on PyPI is another project's, so the
/// command and the Python package carry the distribution's name). `crushdem` stays an alias
/// until 0.2 (CMakeLists.txt, pyproject.toml).
inline constexpr const char* kCommand = "crushdem-sand";

/// The note an invocation by the old name prints first (on stderr).
inline constexpr const char* kAliasNote =
    "note: `crushdem` is now `crushdem-sand`; the old name is an alias until version 0.2\n";

/// A command that a front end runs itself, listed in the top-level help with the others:
/// its name and one line of description.
using FrontEndCommand = std::pair<std::string, std::string>;

/// Entry point; returns the process exit code (0, 2 for bad input, 1 for a failed run, 128 + the
/// signal for a run stopped by SIGINT / SIGTERM). `front_end`: the commands of the caller (the
/// Python package), listed in the help; without them the help names them in a footer.
int cli_main(const std::vector<std::string>& args,
             const std::vector<FrontEndCommand>& front_end = {});

struct RunArgs {
  std::string config, out, backend = "cpu", from;
  long threads = 0;
  bool quiet = false, overwrite = false, keep_columns = false;
};
struct ResumeArgs {
  std::string dir, backend = "cpu";
  long threads = 0;
  bool quiet = false;
  bool keep_columns = false;
};
struct BenchArgs {
  std::string packing;  // --packing or PACKING, or
  std::string run;      // --run: a run directory's sample with the run's configuration
  bool law_given = false;
  long steps = 10000, warm = 500, threads = 0, settle = 0, prune = 1;
  std::string law = "hertz", state_out, backend = "cpu", settled_state;
};

int run_main(const RunArgs& a);
int resume_main(const ResumeArgs& a);
int check_main(const std::string& config);
int bench_main(const BenchArgs& a);

/// Sets the OpenMP thread count (0 = leave the default).
/// The most threads a run takes: far beyond any machine's cores, below what would exhaust the
/// process creating them.
inline constexpr long kMaxThreads = 1024;
/// Sets the thread count (0: OpenMP's default); ConfigError naming `key` outside 0..kMaxThreads.
void set_threads(long n, const char* key = "--threads");
int current_threads();

}  // namespace crushdem::cli
