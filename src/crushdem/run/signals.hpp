// Stopping a run cleanly: SIGINT / SIGTERM ask the running run to save its checkpoint and stop
// at its next chunk boundary (within seconds); Interrupted then tells the caller where the state
// is. The same signal again ends the process at once, unless it comes within kSameRequestMs of
// the first (one request delivered twice).
#pragma once

#include <stdexcept>
#include <string>

namespace crushdem {

/// A signal this soon after the first [ms] repeats its request rather than ending the process.
inline constexpr long long kSameRequestMs = 1000;

/// Asks the running run to write a checkpoint and stop at its next chunk boundary.
/// Async-signal-safe: the CLI calls it from its SIGINT / SIGTERM handler.
void request_stop(int signal);

/// The signal of a pending stop request, 0 if none.
int stop_signal();

/// Forgets a pending stop request (a new run starts without one).
void clear_stop_request();

/// SIGINT and SIGTERM call request_stop() for as long as this object lives, so that a run
/// saves its checkpoint and stops; the same signal again ends the process at once, one within
/// kSameRequestMs of the first is ignored. The previous
/// handlers (Python's, say) come back afterwards. Used by the CLI and by the Python run/resume.
class StopOnSignals {
 public:
  StopOnSignals();
  ~StopOnSignals();
  StopOnSignals(const StopOnSignals&) = delete;
  StopOnSignals& operator=(const StopOnSignals&) = delete;

 private:
  using Handler = void (*)(int);
  Handler int_, term_;
};

/// Thrown by run_to_directory when it stopped on request, after saving its checkpoint in
/// out_dir; what() tells the user where the state is and how to go on.
class Interrupted : public std::runtime_error {
 public:
  /// resume: the command that continues it (crushdem-sand resume DIR with the run's options).
  Interrupted(int signal, const std::string& out_dir, const std::string& resume)
      : std::runtime_error("stopped by signal " + std::to_string(signal) +
                           "; the state is saved in " + out_dir +
                           "/checkpoint.bin. Continue with: " + resume),
        signal_(signal),
        out_dir_(out_dir) {}
  int signal() const { return signal_; }
  const std::string& out_dir() const { return out_dir_; }

 private:
  int signal_;
  std::string out_dir_;
};

}  // namespace crushdem
