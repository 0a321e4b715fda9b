#include "io/interrupt.hpp"

#include <csignal>
#include <cstring>
#include <unistd.h>

namespace matep {

namespace {

std::atomic<bool> g_stop{false};
volatile std::sig_atomic_t g_signal = 0;     // the first signal
volatile std::sig_atomic_t g_publishing = 0; // PublishGuards alive
volatile std::sig_atomic_t g_held = 0;       // a second signal arrived while publishing

void say(const char* text) {
  // write(2) is async-signal-safe; a failed write has nowhere to be reported.
  const ssize_t n = ::write(STDERR_FILENO, text, std::strlen(text));
  (void)n;
}

void on_signal(int sig) {
  if (g_signal == 0) {
    g_signal = sig;
    g_stop.store(true, std::memory_order_relaxed);
    say("\nmatep: stopping at the next event or step and writing the outputs (signal again to stop at once)\n");
    return;
  }
  if (g_publishing > 0) {
    g_held = sig;
    return;
  }
  say("\nmatep: stopped at once; the output folder keeps the previous run's files\n");
  ::_exit(128 + sig);
}

}  // namespace

void install_interrupt_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

InterruptScope::InterruptScope() {
  g_stop.store(false, std::memory_order_relaxed);
  g_signal = 0;
  g_held = 0;
  sigaction(SIGINT, nullptr, &old_int_);
  sigaction(SIGTERM, nullptr, &old_term_);
  install_interrupt_handlers();
}

InterruptScope::~InterruptScope() {
  sigaction(SIGINT, &old_int_, nullptr);
  sigaction(SIGTERM, &old_term_, nullptr);
}

const std::atomic<bool>& stop_flag() { return g_stop; }

int stop_signal() { return g_signal; }

const char* stop_signal_name() {
  switch (g_signal) {
    case SIGINT: return "SIGINT";
    case SIGTERM: return "SIGTERM";
    default: return "a stop request";
  }
}

PublishGuard::PublishGuard() { g_publishing = g_publishing + 1; }

PublishGuard::~PublishGuard() {
  g_publishing = g_publishing - 1;
  if (g_publishing == 0 && g_held != 0) {
    say("\nmatep: stopped at once after publishing the outputs\n");
    ::_exit(128 + g_held);
  }
}

}  // namespace matep
