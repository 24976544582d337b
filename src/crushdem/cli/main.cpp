#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "crushdem/cli/cli.hpp"

int main(int argc, char** argv) {
  // Called by the old name (the `crushdem` link beside the executable): say the new one.
  const std::string_view self = argc > 0 ? argv[0] : "";
  if (self.substr(self.find_last_of('/') + 1) == "crushdem") {
    std::fputs(crushdem::cli::kAliasNote, stderr);
  }
  return crushdem::cli::cli_main(std::vector<std::string>(argv + 1, argv + argc));
}
