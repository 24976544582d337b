// What built this binary, for the result files: the version (CMake's project VERSION, macro
// CRUSHDEM_VERSION) and the git commit of the source tree.
#pragma once

namespace crushdem {

/// The git commit of the source tree this library was built from (12 hex digits, "-dirty" when
/// the tree had uncommitted changes), or "unknown" when it was not built from a git checkout.
const char* build_commit();

}  // namespace crushdem
