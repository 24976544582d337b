// Result files: a write that fails (full disk: /dev/full) stops the run at once with the file
// named, instead of leaving a silently truncated series (io/output.cpp).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "crushdem/core/error.hpp"
#include "crushdem/io/output.hpp"

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

}  // namespace
}  // namespace crushdem
