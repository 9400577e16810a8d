// SIGINT/SIGTERM delivered as events a thread can wait for.
//
// The handler only writes the signal number to a pipe (async-signal-safe),
// so it may run on any thread, including threads that libraries start before
// main() could block signals; the waiting thread does the real work outside
// signal context.
#ifndef TOTALGRAD_RUNTIME_SIGNALS_H_
#define TOTALGRAD_RUNTIME_SIGNALS_H_

namespace totalgrad {

// Installs handlers for SIGINT and SIGTERM. Call once, early in main().
// Returns false if the pipe or the handlers could not be set up.
bool InstallShutdownSignals();
// Blocks until one of the signals arrives; returns its number.
int WaitForShutdownSignal();

}  // namespace totalgrad

#endif  // TOTALGRAD_RUNTIME_SIGNALS_H_
