#include "crushdem/run/signals.hpp"

#include <atomic>
#include <csignal>
#include <ctime>

namespace crushdem {

namespace {

// Lock-free atomics: the handler may run on any thread of the run's team.
std::atomic<int> g_stop_signal{0};
// When each signal first came while its handler was installed [ms, CLOCK_MONOTONIC]; -1: not yet.
std::atomic<long long> g_first_int{-1}, g_first_term{-1};
static_assert(std::atomic<int>::is_always_lock_free);
static_assert(std::atomic<long long>::is_always_lock_free);

long long monotonic_ms() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);  // async-signal-safe (POSIX.1-2008)
  return static_cast<long long>(t.tv_sec) * 1000 + t.tv_nsec / 1000000;
}

extern "C" void stop_on_signal(int sig) {
  // The run saves a checkpoint and stops within seconds; the same signal again ends it at once.
  // A repeat within kSameRequestMs is the same request: GNU timeout signals the process and then
  // its group, and a terminal's Ctrl-C reaches a front end and its run together. The other
  // signal (a front end's SIGTERM after Ctrl-C) is another request, as it always was.
  std::atomic<long long>& first = sig == SIGINT ? g_first_int : g_first_term;
  const long long now = monotonic_ms();
  const long long then = first.load();
  if (then < 0) {
    first.store(now);
    request_stop(sig);
    return;
  }
  if (now - then < kSameRequestMs) return;
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

}  // namespace

void request_stop(int signal) {
  g_stop_signal.store(signal);
}

int stop_signal() {
  return g_stop_signal.load();
}

void clear_stop_request() {
  g_stop_signal.store(0);
}

StopOnSignals::StopOnSignals() : int_(nullptr), term_(nullptr) {
  g_first_int.store(-1);
  g_first_term.store(-1);
  int_ = std::signal(SIGINT, stop_on_signal);
  term_ = std::signal(SIGTERM, stop_on_signal);
}

StopOnSignals::~StopOnSignals() {
  std::signal(SIGINT, int_);
  std::signal(SIGTERM, term_);
}

}  // namespace crushdem
