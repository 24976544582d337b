#include "crushdem/run/signals.hpp"

#include <atomic>
#include <csignal>
#include <ctime>

namespace crushdem {

namespace {

volatile std::sig_atomic_t g_stop_signal = 0;
// When the pending request came [ms, CLOCK_MONOTONIC]; lock-free, so the handler may write it.
std::atomic<long long> g_first_ms{0};
static_assert(std::atomic<long long>::is_always_lock_free);

long long monotonic_ms() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);  // async-signal-safe (POSIX.1-2008)
  return static_cast<long long>(t.tv_sec) * 1000 + t.tv_nsec / 1000000;
}

extern "C" void stop_on_signal(int sig) {
  // The run saves a checkpoint and stops within seconds; a second signal ends it at once. A
  // repeat within kSameRequestMs is the same request: GNU timeout signals the process and then
  // its group, a terminal's Ctrl-C reaches a front end and its run at once and the front end
  // passes it on. Ending there would lose the work since the last checkpoint.
  const long long now = monotonic_ms();
  if (g_stop_signal == 0) {
    g_first_ms.store(now);
    request_stop(sig);
    return;
  }
  if (now - g_first_ms.load() < kSameRequestMs) return;
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

}  // namespace

void request_stop(int signal) {
  g_stop_signal = signal;
}

int stop_signal() {
  return static_cast<int>(g_stop_signal);
}

void clear_stop_request() {
  g_stop_signal = 0;
}

StopOnSignals::StopOnSignals()
    : int_(std::signal(SIGINT, stop_on_signal)), term_(std::signal(SIGTERM, stop_on_signal)) {}

StopOnSignals::~StopOnSignals() {
  std::signal(SIGINT, int_);
  std::signal(SIGTERM, term_);
}

}  // namespace crushdem
