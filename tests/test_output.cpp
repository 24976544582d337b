// Result files: a write that fails (full disk: /dev/full) stops the run at once with the file
// named, instead of leaving a silently truncated series (io/output.cpp); the first row of a test
// measures the contacts of the state it starts from.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "crushdem/core/error.hpp"
#include "crushdem/io/output.hpp"
#include "crushdem/run/runner.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

TEST(Output, AFailedWriteStopsWithTheFileNamed) {
  if (!std::filesystem::is_character_file("/dev/full")) GTEST_SKIP() << "no /dev/full here";
  CsvWriter csv("/dev/full");
  try {
    csv.write({{"time_s", 1.0}, {"step", 2.0}});
    FAIL() << "a write to a full device went unnoticed";
  } catch (const RuntimeFailure& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("cannot write '/dev/full'"), std::string::npos) << what;
    EXPECT_NE(what.find("No space left"), std::string::npos) << what;
    EXPECT_NE(what.find("checkpoint is kept"), std::string::npos) << what;
  }
  EXPECT_THROW(write_text_file("/dev/full", std::string(100000, 'x')), ConfigError);
}

TEST(Output, AResumedFileIsRefusedRowsWithOtherColumnsNamingTheFirst) {
  // A run continued by a crushdem that writes a column more (or another one in a place): its
  // rows would not line up with the file's header.
  const testing::TempDir temp("columns");
  const std::string path = (temp.path() / "timeseries.csv").string();
  long long size = 0;
  std::uint64_t digest = 0;
  {
    CsvWriter csv(path);
    csv.write({{"time_s", 1.0}, {"step", 2.0}});
    size = csv.size();
    digest = csv.digest();
  }
  const std::pair<std::vector<std::pair<std::string, double>>, std::string> cases[] = {
      {{{"time_s", 2.0}, {"step", 3.0}, {"body_pile_moment_x_Nm", 0.0}},
       "column 3 is 'body_pile_moment_x_Nm' in this crushdem's rows and nothing in the file"},
      {{{"time_s", 2.0}, {"steps", 3.0}}, "column 2 is 'steps' in this crushdem's rows and 'step'"},
  };
  for (const auto& [row, expected] : cases) {
    CsvWriter csv(path);
    csv.resume(size, {"time_s", "step"}, &digest);
    try {
      csv.write(row);
      FAIL() << "a row with other columns was appended";
    } catch (const ConfigError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(expected), std::string::npos) << what;
      EXPECT_NE(what.find("go on with that build, or with this one and --keep-columns"),
                std::string::npos)
          << what;
    }
  }
  CsvWriter csv(path);  // the same columns still go on
  csv.resume(size, {"time_s", "step"}, &digest);
  csv.write({{"time_s", 2.0}, {"step", 3.0}});
  EXPECT_EQ(testing::read_file(path), "time_s,step\n1,2\n2,3\n");
}

TEST(Output, AResumedFileKeepsItsColumnsWhenAskedAndNamesWhatItLeavesOut) {
  // resume --keep-columns: a newer crushdem's rows go on in the file's own columns, by name;
  // what the file lacks is left out, and a column it has that the rows lack is still refused.
  const testing::TempDir temp("keep_columns");
  const std::string path = (temp.path() / "timeseries.csv").string();
  long long size = 0;
  std::uint64_t digest = 0;
  {
    CsvWriter csv(path);
    csv.write({{"time_s", 1.0}, {"step", 2.0}, {"q_Pa", 3.0}});
    size = csv.size();
    digest = csv.digest();
  }
  {
    CsvWriter csv(path);
    csv.keep_columns(true);
    csv.resume(size, {"time_s", "step", "q_Pa"}, &digest);
    csv.write({{"time_s", 2.0}, {"moment_Nm", 9.0}, {"step", 3.0}, {"q_Pa", 4.0}});
    csv.write({{"time_s", 3.0}, {"moment_Nm", 9.0}, {"step", 4.0}, {"q_Pa", 5.0}});
    csv.write({{"time_s", 4.0}, {"step", 5.0}, {"q_Pa", 6.0}, {"f_Pa", 7.0}});
    EXPECT_EQ(csv.left_out(), (std::vector<std::string>{"moment_Nm", "f_Pa"}));
  }
  EXPECT_EQ(testing::read_file(path), "time_s,step,q_Pa\n1,2,3\n2,3,4\n3,4,5\n4,5,6\n");
  // Not resumed: a row's layout is the caller's error whatever keep_columns says.
  {
    CsvWriter fresh((temp.path() / "fresh.csv").string());
    fresh.keep_columns(true);
    fresh.write({{"a", 1.0}});
    EXPECT_THROW(fresh.write({{"b", 1.0}}), std::logic_error);
  }
  CsvWriter csv(path);
  csv.keep_columns(true);
  csv.resume(size, {"time_s", "step", "q_Pa"}, &digest);
  try {
    csv.write({{"time_s", 2.0}, {"step", 3.0}});
    FAIL() << "a row without the file's column q_Pa was appended";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("a column 'q_Pa' that this crushdem does not write"),
              std::string::npos)
        << e.what();
  }
  // Text rows (breakage.csv) cannot be mapped: another count of fields is refused either way.
  const std::string text = (temp.path() / "breakage.csv").string();
  {
    CsvWriter b(text);
    b.start({"time_s", "id", "fragments"});
    b.write_line("1,2,3 4");
    size = b.size();
    digest = b.digest();
  }
  CsvWriter b(text);
  b.keep_columns(true);
  b.resume(size, {"time_s", "id", "fragments"}, &digest);
  EXPECT_THROW(b.write_line("2,3,5 6,0.1"), ConfigError);
  b.write_line("2,3,5 6");
  EXPECT_EQ(testing::read_file(text), "time_s,id,fragments\n1,2,3 4\n2,3,5 6\n");
}

// With crushing on, the crusher's set-up invalidates the forces; the first row of the test must
// still see the two touching grains (and their Love-Weber stress), not an empty contact list.
TEST(Output, TheFirstRowOfACrushingTestMeasuresTheContacts) {
  namespace fs = std::filesystem;
  const testing::TempDir temp("run");
  const fs::path& dir = temp.path();
  std::ofstream(dir / "pair.txt") << "1 0.0005 0.0005 0.00041 0.0002\n"
                                     "2 0.0005 0.0005 0.00059 0.0002\n";
  std::ofstream(dir / "run.toml")
      << "[box]\nmin = [0, 0, 0]\nmax = [1e-3, 1e-3, 1e-3]\n[particles]\nfile = \"pair.txt\"\n"
         "[crushing]\nd0 = 1e-3\n[[stage]]\ntype = \"hold\"\nsteps = 10\n";
  RunOptions opt;
  opt.progress = false;
  opt.out_dir = (dir / "out").string();
  run_to_directory(load_run_config((dir / "run.toml").string()), opt);
  const auto rows = testing::read_csv((dir / "out" / "timeseries.csv").string());
  ASSERT_FALSE(rows.at("n_contacts").empty());
  EXPECT_EQ(rows.at("n_contacts").front(), 1.0);
  EXPECT_GT(rows.at("mean_Fn_N").front(), 0.0);
}

}  // namespace
}  // namespace crushdem
