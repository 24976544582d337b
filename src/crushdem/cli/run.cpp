#include "crushdem/cli/cli.hpp"
#include "crushdem/core/error.hpp"
namespace crushdem::cli {
int run_main(const std::vector<std::string>&) { throw ConfigError("run: not built yet"); }
int check_main(const std::vector<std::string>&) { throw ConfigError("check: not built yet"); }
}
