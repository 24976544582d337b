#include "crushdem/cli/cli.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <exception>

#include "crushdem/core/error.hpp"

#ifdef CRUSHDEM_HAVE_OPENMP
#include <omp.h>
#endif

namespace crushdem::cli {

Args::Args(const std::vector<std::string>& args, std::string command)
    : command_(std::move(command)) {
  for (std::size_t k = 0; k < args.size(); ++k) {
    const std::string& a = args[k];
    if (a.rfind("--", 0) == 0) {
      const auto eq = a.find('=');
      if (eq != std::string::npos) {
        options_.emplace_back(a.substr(0, eq), a.substr(eq + 1));
      } else if (k + 1 < args.size() && args[k + 1].rfind("--", 0) != 0) {
        options_.emplace_back(a, args[k + 1]);  // may turn out to be a flag + positional
        ++k;
      } else {
        flags_.push_back(a);
      }
    } else {
      positional_.push_back(a);
    }
  }
}

std::string Args::value(const std::string& key, const std::string& fallback) {
  used_.push_back(key);
  for (const auto& [k, v] : options_) {
    if (k == key) return v;
  }
  if (std::find(flags_.begin(), flags_.end(), key) != flags_.end()) {
    throw ConfigError("crushdem " + command_ + ": option " + key + " needs a value");
  }
  return fallback;
}

long Args::integer(const std::string& key, long fallback) {
  const std::string v = value(key, "");
  if (v.empty()) return fallback;
  char* end = nullptr;
  const long x = std::strtol(v.c_str(), &end, 10);
  if (end == v.c_str() || *end != '\0') {
    throw ConfigError(bad_value(key, v, "an integer"));
  }
  return x;
}

bool Args::flag(const std::string& key) {
  used_.push_back(key);
  if (std::find(flags_.begin(), flags_.end(), key) != flags_.end()) return true;
  // "--flag positional" was read as an option; give the positional back.
  for (auto it = options_.begin(); it != options_.end(); ++it) {
    if (it->first == key) {
      positional_.push_back(it->second);
      options_.erase(it);
      return true;
    }
  }
  return false;
}

void Args::finish() const {
  auto known = [&](const std::string& k) {
    return std::find(used_.begin(), used_.end(), k) != used_.end();
  };
  for (const auto& [k, v] : options_) {
    if (!known(k)) throw ConfigError("crushdem " + command_ + ": unknown option " + k);
  }
  for (const auto& k : flags_) {
    if (!known(k)) throw ConfigError("crushdem " + command_ + ": unknown option " + k);
  }
}

void check_backend(const std::string& backend) {
  if (backend != "cpu" && backend != "cuda") {
    throw ConfigError(bad_value("--backend", backend, "cpu or cuda"));
  }
#ifndef CRUSHDEM_HAVE_CUDA
  if (backend == "cuda") {
    throw ConfigError(
        "--backend cuda: this crushdem was built without CUDA (configure with -DCRUSHDEM_CUDA=ON)");
  }
#endif
}

void set_threads(long n) {
  if (n < 0) throw ConfigError(bad_value("--threads", std::to_string(n), "a count >= 1"));
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
const char* kUsage =
    "usage: crushdem <command> [options]\n"
    "  run CONFIG.toml --out DIR [--threads N] [--backend cpu|cuda]\n"
    "                                            run a simulation described by a TOML file\n"
    "  resume DIR [--threads N]                  continue an interrupted run from "
    "DIR/checkpoint.bin\n"
    "  check CONFIG.toml                         validate a configuration without running\n"
    "  bench [--packing FILE] [--steps N] [--warm N] [--threads N] [--law hertz|rough]\n"
    "        [--state-out FILE] [--backend cpu|cuda] [--settle N [--settled-state FILE]]\n"
    "        [--prune 0|1]\n"
    "        peer reference benchmark\n";
}

int cli_main(const std::vector<std::string>& args) {
  if (args.empty() || args[0] == "-h" || args[0] == "--help" || args[0] == "help") {
    std::fputs(kUsage, args.empty() ? stderr : stdout);
    return args.empty() ? 2 : 0;
  }
  const std::string& cmd = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  try {
    if (cmd == "bench") return bench_main(rest);
    if (cmd == "run") return run_main(rest);
    if (cmd == "check") return check_main(rest);
    if (cmd == "resume") return resume_main(rest);
    if (cmd == "--version") {
      std::puts("crushdem 0.1.0");
      return 0;
    }
    std::fprintf(stderr, "crushdem: unknown command '%s'\n%s", cmd.c_str(), kUsage);
    return 2;
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "crushdem %s: error: %s\n", cmd.c_str(), e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "crushdem %s: failed: %s\n", cmd.c_str(), e.what());
    return 1;
  }
}

}  // namespace crushdem::cli
