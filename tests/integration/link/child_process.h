// Test helpers: child processes (posix_spawn) with output to files, a
// timeout and an unconditional kill on destruction; free loopback ports;
// reading files and flat JSON numbers.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "tests/temp_dir.h"  // make_temp_dir

namespace hemm::test {

class ChildProcess {
 public:
  // Starts argv[0] with stdout/stderr redirected to the given files and
  // stdin from stdin_path (never the test's own terminal: a station reads
  // keys from a terminal on stdin).
  ChildProcess(std::vector<std::string> argv, const std::string& stdout_path, const std::string& stderr_path,
               const std::string& stdin_path = "/dev/null");
  ~ChildProcess();  // SIGKILL + reap if still running
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  bool started() const { return pid_ > 0; }
  pid_t pid() const { return pid_; }
  // Exit status, or nullopt if it did not exit within the timeout (then it is killed: -9).
  std::optional<int> wait(std::chrono::milliseconds timeout);
  void signal(int sig);
  bool running();

 private:
  pid_t pid_ = -1;
  std::optional<int> status_;
};

// A port that was free a moment ago on 127.0.0.1 (TCP and UDP both free).
int free_port();

std::string read_file(const std::string& path);
// Polls until `path` contains `needle` or the timeout passes.
bool wait_for_text(const std::string& path, const std::string& needle, std::chrono::milliseconds timeout);
// Value of "key": <number> in a flat JSON object; nullopt if absent.
std::optional<double> json_number(const std::string& json, const std::string& key);

// Runs argv to completion (killed after `timeout`: rc -1) with stdout and
// stderr through files in `dir`, and returns the exit code and both outputs.
struct ProcessResult {
  int rc = -1;
  std::string out, err;
};
ProcessResult run_to_completion(std::vector<std::string> argv, const std::string& dir,
                                std::chrono::milliseconds timeout);

}  // namespace hemm::test
