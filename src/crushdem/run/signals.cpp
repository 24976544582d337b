#include "crushdem/run/signals.hpp"

#include <csignal>

namespace crushdem {

namespace {

volatile std::sig_atomic_t g_stop_signal = 0;

extern "C" void stop_on_signal(int sig) {
  // The run saves a checkpoint and stops within seconds; a second signal ends it at once.
  request_stop(sig);
  std::signal(sig, SIG_DFL);
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
