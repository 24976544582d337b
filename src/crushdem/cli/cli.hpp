// The command-line front end: `crushdem run|check|bench|resume ...`. Kept in a library so the
// Python package's `crushdem` command runs exactly the same code.
#pragma once

#include <string>
#include <vector>

namespace crushdem::cli {

/// Entry point; returns the process exit code (2 for bad input, 1 for a failed run).
int cli_main(const std::vector<std::string>& args);

int bench_main(const std::vector<std::string>& args);
int run_main(const std::vector<std::string>& args);
int check_main(const std::vector<std::string>& args);
int resume_main(const std::vector<std::string>& args);

/// "cpu" or "cuda" (the latter only in a build with CUDA); anything else is a ConfigError.
void check_backend(const std::string& backend);

/// Sets the OpenMP thread count (0 = leave the default).
void set_threads(long n);
int current_threads();

/// Minimal option parser: --key value pairs and positionals; unknown options are errors.
class Args {
 public:
  Args(const std::vector<std::string>& args, std::string command);
  std::string value(const std::string& key, const std::string& fallback);
  long integer(const std::string& key, long fallback);
  bool flag(const std::string& key);
  std::vector<std::string> positionals() const { return positional_; }
  /// Throws ConfigError if an option was given that nobody asked for.
  void finish() const;

 private:
  std::string command_;
  std::vector<std::pair<std::string, std::string>> options_;
  std::vector<std::string> flags_;
  std::vector<std::string> positional_;
  std::vector<std::string> used_;
};

}  // namespace crushdem::cli
