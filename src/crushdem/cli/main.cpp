#include <string>
#include <vector>

#include "crushdem/cli/cli.hpp"

int main(int argc, char** argv) {
  return crushdem::cli::cli_main(std::vector<std::string>(argv + 1, argv + argc));
}
