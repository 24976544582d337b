// Files of the C++ tests: the fixtures in tests/data that the Python tests read too, and
// temporary directories that two checkouts (or two runs of the suite at once) never share.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace crushdem::testing {

/// The text of tests/data/`name` (CRUSHDEM_TEST_DATA_DIR, set by tests/CMakeLists.txt).
inline std::string test_data(const std::string& name) {
  const std::filesystem::path path = std::filesystem::path(CRUSHDEM_TEST_DATA_DIR) / name;
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot read the test fixture " + path.string());
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

/// An empty directory of the running test's own, removed with this object:
/// crushdem_<pid>_<suite>_<test>_<name> under the system's temporary directory.
class TempDir {
 public:
  explicit TempDir(const std::string& name) {
    const ::testing::TestInfo* test = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string id = "crushdem_" + std::to_string(::getpid());
    if (test != nullptr) id += std::string("_") + test->test_suite_name() + "_" + test->name();
    id += "_" + name;
    for (char& c : id) {
      if (c == '/') c = '_';  // a parameterised test's name is "Name/0"
    }
    path_ = std::filesystem::temp_directory_path() / id;
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace crushdem::testing
