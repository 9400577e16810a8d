// Child processes and condition waits for the end-to-end tests.
#ifndef TOTALGRAD_TESTS_SERVICE_PROCESS_UTIL_H_
#define TOTALGRAD_TESTS_SERVICE_PROCESS_UTIL_H_

#include <sys/types.h>

#include <chrono>
#include <functional>
#include <string>
#include <vector>

namespace totalgrad::testing {

// A child process with stdout+stderr appended to a log file. The destructor
// SIGKILLs it if it is still running.
class Process {
 public:
  Process(std::vector<std::string> argv, std::string log_path);
  ~Process();
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const { return pid_; }
  bool Running();
  void Signal(int signal_number);
  // Waits up to `timeout` for the process to exit; returns its exit status as
  // from waitpid (or -1 if it is still running).
  int Wait(std::chrono::milliseconds timeout);
  const std::string& log_path() const { return log_path_; }
  std::string Log() const;

 private:
  pid_t pid_ = -1;
  bool reaped_ = false;
  int status_ = 0;
  std::string log_path_;
};

// Polls `condition` every 20 ms until it holds or `timeout` passes.
bool WaitFor(const std::function<bool()>& condition, std::chrono::milliseconds timeout);

// Runs a command, captures stdout and stderr, returns the exit code.
int RunCommand(const std::vector<std::string>& argv, std::string* out, std::string* err);

std::string ReadFile(const std::string& path);
void WriteFile(const std::string& path, const std::string& text);

}  // namespace totalgrad::testing

#endif  // TOTALGRAD_TESTS_SERVICE_PROCESS_UTIL_H_
