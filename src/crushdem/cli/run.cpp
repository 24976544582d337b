// `crushdem-sand run CONFIG.toml --out DIR [--threads N]`, `crushdem-sand resume DIR [--threads N]`
// and `crushdem-sand check CONFIG.toml`.
#include <cstdio>
#include <filesystem>
#include <functional>

#include "crushdem/backend/stepper.hpp"
#include "crushdem/cli/cli.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/run/runner.hpp"

namespace crushdem::cli {

namespace {

/// --from DIR[:STAGE]: the directory, and the stage when a ':' follows a directory that exists.
void split_branch(const std::string& from, std::string& dir, std::string& stage) {
  const std::size_t colon = from.rfind(':');
  if (std::filesystem::is_directory(from) || colon == std::string::npos) {
    dir = from;
    stage.clear();
  } else {
    dir = from.substr(0, colon);
    stage = from.substr(colon + 1);
  }
  if (!std::filesystem::is_directory(dir)) {
    throw ConfigError(bad_value("--from", from, "DIR[:STAGE], DIR a crushdem run directory"));
  }
}

/// Runs (or resumes) with the stop handlers installed; an interrupted run says how to go on.
int run_or_resume(const std::function<RunSummary()>& go, const std::string& out) {
  try {
    const StopOnSignals handlers;
    const RunSummary s = go();
    std::printf(
        "crushdem-sand run: %llu steps, t = %.6e s, %zu particles, %.2f s wall-clock (%.0f %% %s); "
        "results in %s\n",
        static_cast<unsigned long long>(s.steps), s.time, s.particles, s.wall_seconds,
        100.0 * s.dominant_fraction, s.dominant_part.c_str(), out.c_str());
    return 0;
  } catch (const Interrupted& e) {
    std::fprintf(stderr, "crushdem: %s\n", e.what());
    return 128 + e.signal();
  }
}

}  // namespace

int run_main(const RunArgs& a) {
  check_backend_name(a.backend);
  const RunConfig cfg = load_run_config(a.config);  // validated before anything runs
  set_threads(a.threads);
  RunOptions opt;
  opt.out_dir = a.out;
  opt.progress = !a.quiet;
  opt.backend = a.backend;
  opt.overwrite = a.overwrite;
  if (!a.from.empty()) split_branch(a.from, opt.branch_dir, opt.branch_stage);
  opt.keep_columns = a.keep_columns;
  return run_or_resume([&]() { return run_to_directory(cfg, opt); }, a.out);
}

int resume_main(const ResumeArgs& a) {
  check_backend_name(a.backend);
  set_threads(a.threads);
  RunOptions opt;
  opt.progress = !a.quiet;
  opt.backend = a.backend;
  opt.keep_columns = a.keep_columns;
  return run_or_resume([&]() { return resume_directory(a.dir, opt); }, a.dir);
}

int check_main(const std::string& config) {
  const RunConfig cfg = load_run_config(config);
  check_start(cfg);
  for (const std::string& w : cfg.warnings()) std::printf("warning: %s\n", w.c_str());
  for (const std::string& line : parameter_set_report(cfg.parameters, cfg.simulation.contact,
                                                      cfg.crushing, cfg.crushing.enabled)) {
    std::printf("%s\n", line.c_str());
  }
  std::printf("%s: configuration is valid\n", config.c_str());
  return 0;
}

}  // namespace crushdem::cli
