// Results must not depend on the thread count: a last-bit difference would change which grain
// breaks first. Two runs of one configuration on 1 and 2 threads write identical files.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>
#include <vector>

#include "crushdem/core/deterministic.hpp"
#include "crushdem/io/config.hpp"
#include "crushdem/io/toml.hpp"
#include "crushdem/run/runner.hpp"
#include "fixtures.hpp"

#ifdef CRUSHDEM_HAVE_OPENMP
#include <omp.h>
#endif

namespace crushdem {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

// 300 grains compressed by servo walls and one wall moving in.
const std::string kConfig =
    testing::test_data("grains_300.toml") + testing::test_data("compression_300.toml");

#ifdef CRUSHDEM_HAVE_OPENMP
/// Runs `config` on 1 and 2 threads into base/t1 and base/t2 and compares every file but
/// timing.json; returns the number compared.
std::size_t compare_thread_counts(const std::string& config, const fs::path& base) {
  fs::remove_all(base);
  fs::create_directories(base);
  const RunConfig cfg = run_config_from_toml(toml::parse(config, "test"), "test", base.string());
  const int saved = omp_get_max_threads();
  const std::size_t saved_threshold = threading_threshold();
  threading_threshold() = 0;  // thread even these small systems
  for (int t : {1, 2}) {
    omp_set_num_threads(t);
    RunOptions opt;
    opt.out_dir = (base / (t == 1 ? "t1" : "t2")).string();
    opt.progress = false;
    run_to_directory(cfg, opt);
  }
  omp_set_num_threads(saved);
  threading_threshold() = saved_threshold;
  std::size_t compared = 0;
  for (const auto& e : fs::recursive_directory_iterator(base / "t1")) {
    const auto name = e.path().filename();
    if (!e.is_regular_file() || name == "timing.json" || name == "run.log") continue;
    const fs::path other = base / "t2" / fs::relative(e.path(), base / "t1");
    EXPECT_TRUE(fs::exists(other)) << other;
    EXPECT_EQ(slurp(e.path()), slurp(other)) << "differs: " << fs::relative(e.path(), base / "t1");
    ++compared;
  }
  return compared;
}
#endif

TEST(Determinism, OneAndTwoThreadsWriteIdenticalFiles) {
#ifndef CRUSHDEM_HAVE_OPENMP
  GTEST_SKIP() << "built without OpenMP";
#else
  const testing::TempDir temp("threads");
  const fs::path& base = temp.path();
  // Table 1's free rotation: the spins' updates threaded too (the crushing test below runs the
  // default set, rotation blocked).
  EXPECT_GE(compare_thread_counts("parameters = \"table1\"\n" + kConfig, base),
            7u);  // config, timeseries, summary, 2 x 3 vtk
  // The run did something: the grains were compressed into a contact network.
  const std::string summary = slurp(base / "t1" / "summary.json");
  const auto k = summary.find("\"coordination_number\": ");
  ASSERT_NE(k, std::string::npos);
  EXPECT_GT(std::stod(summary.substr(k + 23)), 3.0);
#endif
}

TEST(Determinism, OneAndTwoThreadsWriteIdenticalFilesWithCrushing) {
#ifndef CRUSHDEM_HAVE_OPENMP
  GTEST_SKIP() << "built without OpenMP";
#else
  // Weak grains (sigma_lim0 = 0.3 GPa) so that many break; the smallest fragments are removed.
  const std::string config =
      std::string(kConfig) + "[crushing]\nsigma_lim0 = 3e8\nd_min = 0.05e-3\nseed = 5\n";
  const testing::TempDir temp("threads");
  const fs::path& base = temp.path();
  EXPECT_GE(compare_thread_counts(config, base), 9u);  // + breakage.csv, grading.csv
  const std::string log = slurp(base / "t1" / "breakage.csv");
  EXPECT_GE(std::count(log.begin(), log.end(), '\n'), 6);  // header + at least 5 breakages
  EXPECT_EQ(log.substr(0, log.find('\n')).substr(log.find("fragment_ids")),
            "fragment_ids,x_m,y_m,z_m");
#endif
}

TEST(Determinism, OneAndTwoThreadsWriteIdenticalFilesWithRollingResistance) {
#ifndef CRUSHDEM_HAVE_OPENMP
  GTEST_SKIP() << "built without OpenMP";
#else
  // The rolling moment of a pair is written to both grains from one column (as the forces).
  std::string config(kConfig);
  const std::string law = "law = \"rough\"\n";
  config.replace(config.find(law), law.size(), law + "rolling_friction = 0.3\n");
  const testing::TempDir temp("threads");
  const fs::path& base = temp.path();
  EXPECT_GE(compare_thread_counts(config, base), 7u);
  EXPECT_NE(slurp(base / "t1" / "config.toml").find("rolling_friction = 0.3"), std::string::npos);
#endif
}

// The sort behind the list's spatial order and scatter columns: std::stable_sort's order on any
// team size, with many equal keys (the order among them is the input's) and block counts that
// leave a block without a partner in a merge round.
TEST(Determinism, ParallelStableSortEqualsStableSortOnAnyTeam) {
  const std::size_t saved_threshold = threading_threshold();
  threading_threshold() = 0;
#ifdef CRUSHDEM_HAVE_OPENMP
  const int saved_threads = omp_get_max_threads();
#endif
  std::vector<std::pair<int, int>> input;
  std::uint64_t state = 12345;
  for (int k = 0; k < 10007; ++k) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    input.emplace_back(static_cast<int>((state >> 33) % 97), k);  // key, then input position
  }
  const auto by_key = [](const std::pair<int, int>& a, const std::pair<int, int>& b) {
    return a.first < b.first;
  };
  for (const int threads : {1, 2, 3, 5, 8}) {
#ifdef CRUSHDEM_HAVE_OPENMP
    omp_set_num_threads(threads);
#endif
    for (const std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{7}, input.size()}) {
      std::vector<std::pair<int, int>> v(input.begin(), input.begin() + static_cast<long>(n));
      std::vector<std::pair<int, int>> want = v;
      std::stable_sort(want.begin(), want.end(), by_key);
      parallel_stable_sort(v, by_key);
      EXPECT_EQ(v, want) << threads << " threads, " << n << " items";
    }
  }
#ifdef CRUSHDEM_HAVE_OPENMP
  omp_set_num_threads(saved_threads);
#endif
  threading_threshold() = saved_threshold;
}

}  // namespace
}  // namespace crushdem
