#include "crushdem/cli/cli.hpp"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "crushdem/core/error.hpp"

#ifdef CRUSHDEM_HAVE_OPENMP
#include <omp.h>
#endif

namespace crushdem::cli {

void set_threads(long n, const char* key) {
  if (n < 0 || n > kMaxThreads) {
    throw ConfigError(
        bad_value(key, std::to_string(n), "a count from 1 to " + std::to_string(kMaxThreads)));
  }
#ifdef CRUSHDEM_HAVE_OPENMP
  if (n > 0) omp_set_num_threads(static_cast<int>(n));
#else
  if (n > 1) std::fprintf(stderr, "crushdem: built without OpenMP, running on 1 thread\n");
#endif
}

int current_threads() {
#ifdef CRUSHDEM_HAVE_OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

namespace {

// The standalone executable's footer; through the Python package's command the same commands
// are listed with the others (cli_main's front_end_commands).
constexpr const char* kPythonCommands =
    "\nplot, reproduce, sensitivity, sweep, calibrate and pile come with the Python package's\n"
    "crushdem-sand command (pip install .). Each command has its own --help.\n";

constexpr const char* kBackendHelp =
    "what advances the simulation: cpu (default), cuda (a GPU, in a build with CUDA) or emulated "
    "(the GPU's step run on the host: its results without a GPU, slowly)";

void add_threads(CLI::App* c, long& threads) {
  c->add_option("--threads", threads,
                "OpenMP threads (default: every core); results do not "
                "depend on it")
      ->check(CLI::NonNegativeNumber);
}

}  // namespace

int cli_main(const std::vector<std::string>& args, const std::vector<FrontEndCommand>& front_end) {
  CLI::App app(std::string(kCommand) + " " CRUSHDEM_VERSION +
                   ": discrete element simulation of crushable sand (grains that break over time)",
               kCommand);
  app.set_version_flag("--version", std::string(kCommand) + " " CRUSHDEM_VERSION);
  app.fallthrough();  // --version after a subcommand too
  app.require_subcommand(0, 1);

  RunArgs run;
  CLI::App* c_run = app.add_subcommand("run", "run a simulation described by a TOML file");
  c_run->add_option("CONFIG", run.config, "the configuration (docs/configuration.md)")->required();
  c_run->add_option("--out", run.out, "directory for the results (new or empty)")->required();
  add_threads(c_run, run.threads);
  c_run->add_option("--backend", run.backend, kBackendHelp);
  c_run->add_flag("--quiet", run.quiet, "no progress lines");
  c_run
      ->add_option("--from", run.from,
                   "branch: start from the run in DIR at the start of its stage STAGE (index "
                   "or name; default: the first stage CONFIG changes)")
      ->type_name("DIR[:STAGE]");
  c_run->add_flag("--overwrite", run.overwrite,
                  "replace the crushdem run already in --out (otherwise refused)");
  c_run->add_flag("--keep-columns", run.keep_columns,
                  "with --from: branch from a run whose result files a crushdem of other "
                  "columns wrote (an older build): they keep their columns and run.log names "
                  "the ones left out");

  ResumeArgs resume;
  CLI::App* c_resume = app.add_subcommand(
      "resume",
      "continue a stopped run from DIR/checkpoint.bin (or start it again when it "
      "stopped before its first checkpoint)");
  c_resume->add_option("DIR", resume.dir, "the run directory")->required();
  add_threads(c_resume, resume.threads);
  c_resume->add_option("--backend", resume.backend, kBackendHelp);
  c_resume->add_flag("--quiet", resume.quiet, "no progress lines");
  c_resume->add_flag("--keep-columns", resume.keep_columns,
                     "continue with a crushdem that writes other columns than the one that "
                     "started the run (a newer build): the result files keep their columns and "
                     "run.log names the ones left out");

  std::string check_config;
  CLI::App* c_check = app.add_subcommand("check", "validate a configuration without running it");
  c_check->add_option("CONFIG", check_config, "the configuration")->required();

  BenchArgs bench;
  CLI::App* c_bench = app.add_subcommand(
      "bench",
      "time the peer reference problem (11,500 spheres at 5 MPa; bench/README.md), or a "
      "run's prepared sample, and print particle_steps_per_s last; options fall back on the "
      "peer harness's environment variables");
  CLI::Option* o_packing =
      c_bench
          ->add_option("--packing", bench.packing,
                       "the packing file (bench/README.md: the reference one) with the peers' "
                       "constants")
          ->envname("PACKING");
  c_bench
      ->add_option("--run", bench.run,
                   "a run directory: its prepared sample (sample.txt) with the run's own "
                   "configuration (config.toml: law, grains, bodies; a chamber sample's chamber "
                   "and symmetry planes), its walls and bodies fixed")
      ->excludes(o_packing);
  c_bench->add_option("--steps", bench.steps, "timed steps")
      ->envname("STEPS")
      ->check(CLI::PositiveNumber);
  c_bench->add_option("--warm", bench.warm, "untimed steps first")
      ->envname("WARM")
      ->check(CLI::NonNegativeNumber);
  c_bench->add_option("--threads", bench.threads, "OpenMP threads (default: every core)")
      ->envname("THREADS")
      ->check(CLI::NonNegativeNumber);
  c_bench->add_option("--law", bench.law, "contact law")->check(CLI::IsMember({"hertz", "rough"}));
  c_bench->add_option("--state-out", bench.state_out, "write the final state to this file")
      ->envname("STATE_OUT");
  c_bench->add_option("--backend", bench.backend, kBackendHelp);
  c_bench
      ->add_option("--settle", bench.settle,
                   "steps at rest under servo walls before timing (the law's own state)")
      ->check(CLI::NonNegativeNumber);
  c_bench->add_option("--settled-state", bench.settled_state,
                      "keep the settled state in this file (needs --settle)");
  c_bench->add_option("--prune", bench.prune, "1: pruned neighbour list; 0: the full list")
      ->envname("PRUNE")
      ->check(CLI::IsMember({0, 1}));

  // The commands a front end runs itself (the Python package's), in the same list: it handles
  // them before this parser sees its arguments.
  for (const auto& [name, description] : front_end) {
    app.add_subcommand(name, description)->allow_extras();
  }
  // Set after the subcommands, which would inherit it: their help is theirs alone.
  app.footer(front_end.empty() ? kPythonCommands : "\nEach command has its own --help.\n");

  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 reads them reversed
  try {
    if (args.size() == 1 && args[0] == "help") {
      std::fputs(app.help().c_str(), stdout);
      return 0;
    }
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help, --version
    const std::string where =
        app.get_subcommands().empty()
            ? std::string(kCommand)
            : std::string(kCommand) + " " + app.get_subcommands().front()->get_name();
    std::fprintf(stderr, "%s: error: %s\nRun '%s --help' for the options.\n", where.c_str(),
                 e.what(), where.c_str());
    return 2;
  }
  if (app.get_subcommands().empty()) {
    std::fputs(app.help().c_str(), stderr);
    return 2;
  }
  const std::string cmd = app.get_subcommands().front()->get_name();
  for (const auto& command : front_end) {
    if (command.first == cmd) {
      std::fprintf(stderr, "%s %s: run by the front end, not by this parser\n", kCommand,
                   cmd.c_str());
      return 2;
    }
  }
  try {
    if (c_run->parsed()) return run_main(run);
    if (c_resume->parsed()) return resume_main(resume);
    if (c_check->parsed()) return check_main(check_config);
    bench.law_given = c_bench->count("--law") > 0;
    return bench_main(bench);
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "%s %s: error: %s\n", kCommand, cmd.c_str(), e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s %s: failed: %s\n", kCommand, cmd.c_str(), e.what());
    return 1;
  }
}

}  // namespace crushdem::cli
