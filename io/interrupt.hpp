// Stopping a run on SIGINT / SIGTERM (README "Stopping a run"). The first signal asks the engine
// to stop at its next event or step; the run then writes every output and publishes them as
// usual, with status "interrupted". A second signal ends the process at once (exit 128 + signal)
// unless the outputs are being published, which then finishes first: the output folder never
// holds a mix of two runs.
#pragma once

#include <signal.h>

#include <atomic>

namespace matep {

// Installs the handlers (idempotent). Without them the stop flag never changes.
void install_interrupt_handlers();
// For a host process with handlers of its own (the Python module): installs matep's handlers with
// the stop flag cleared, and restores the host's handlers when it ends.
class InterruptScope {
 public:
  InterruptScope();
  ~InterruptScope();
  InterruptScope(const InterruptScope&) = delete;
  InterruptScope& operator=(const InterruptScope&) = delete;

 private:
  struct sigaction old_int_ {}, old_term_ {};
};
// The flag the engines poll (EdmSettings::stop, TdmSettings::stop).
const std::atomic<bool>& stop_flag();
// The signal that asked for the stop (0: none).
int stop_signal();
// "SIGINT", "SIGTERM", or "a stop request".
const char* stop_signal_name();

// While one lives, a second signal is held back; when the last one ends, a held-back signal ends
// the process (the caller's folder is then consistent).
class PublishGuard {
 public:
  PublishGuard();
  ~PublishGuard();
  PublishGuard(const PublishGuard&) = delete;
  PublishGuard& operator=(const PublishGuard&) = delete;
};

}  // namespace matep
