#pragma once
// Child processes for batches and plotting (POSIX): spawn with output to a log file, poll, wait.
#include <string>
#include <sys/types.h>
#include <vector>

namespace rtslam::eval {

/// A started child process.
struct ChildProcess {
  pid_t pid = -1;
};

/// Starts argv[0] (searched in PATH when it has no '/') with stdin from /dev/null and stdout+stderr appended to
/// `log_path` (or inherited if empty), in `work_dir` if non-empty. Throws IoError naming the program on failure.
ChildProcess spawn_process(const std::vector<std::string>& argv, const std::string& log_path,
                           const std::string& work_dir = "");

/// Non-blocking check: true (and the exit code: 128+signal for a signalled child) once the child has ended.
bool poll_process(const ChildProcess& child, int& exit_code);

/// Blocks until the child ends; returns its exit code (128+signal if signalled).
int wait_process(const ChildProcess& child);

/// Runs a command to completion; returns its exit code.
int run_process(const std::vector<std::string>& argv, const std::string& log_path, const std::string& work_dir = "");

/// Full path of an executable found in PATH, or "" if absent.
std::string find_in_path(const std::string& name);

/// The running executable (/proc/self/exe), or "" if it cannot be read.
std::string self_executable();

/// Quotes a word for a POSIX shell (single quotes).
std::string shell_quote(const std::string& word);

}  // namespace rtslam::eval
