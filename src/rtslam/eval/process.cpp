#include "rtslam/eval/process.hpp"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"

extern char** environ;

namespace rtslam::eval {

namespace fs = std::filesystem;

namespace {
int decode_status(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}
}  // namespace

ChildProcess spawn_process(const std::vector<std::string>& argv, const std::string& log_path,
                           const std::string& work_dir) {
  if (argv.empty()) throw IoError("spawn_process: empty command");
  std::string program = argv[0];
  if (program.find('/') == std::string::npos) {
    program = find_in_path(argv[0]);
    if (program.empty()) throw IoError(fmt::format("program '{}' not found in PATH", argv[0]));
  }
  // With a working directory, run through `cd DIR && exec ...` in sh (posix_spawn has no portable chdir action).
  std::vector<std::string> args = argv;
  args[0] = program;
  if (!work_dir.empty()) {
    std::string cmd = "cd ";
    cmd.append(shell_quote(work_dir)).append(" && exec");
    for (const auto& a : args) cmd.append(" ").append(shell_quote(a));
    args = {"/bin/sh", "-c", cmd};
    program = "/bin/sh";
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  if (!log_path.empty()) {
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  }
  std::vector<char*> cargs;
  for (auto& a : args) cargs.push_back(a.data());
  cargs.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, program.c_str(), &actions, nullptr, cargs.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) throw IoError(fmt::format("cannot start '{}': {}", program, std::strerror(rc)));
  return ChildProcess{pid};
}

bool poll_process(const ChildProcess& child, int& exit_code) {
  int status = 0;
  const pid_t r = waitpid(child.pid, &status, WNOHANG);
  if (r == 0) return false;
  if (r < 0) {
    exit_code = -1;
    return true;
  }
  exit_code = decode_status(status);
  return true;
}

int wait_process(const ChildProcess& child) {
  int status = 0;
  pid_t r;
  do {
    r = waitpid(child.pid, &status, 0);
  } while (r < 0 && errno == EINTR);
  return r < 0 ? -1 : decode_status(status);
}

int run_process(const std::vector<std::string>& argv, const std::string& log_path, const std::string& work_dir) {
  return wait_process(spawn_process(argv, log_path, work_dir));
}

std::string find_in_path(const std::string& name) {
  const char* path = std::getenv("PATH");
  if (!path) return "";
  std::string p = path;
  std::size_t start = 0;
  while (start <= p.size()) {
    const std::size_t end = p.find(':', start);
    const std::string dir = p.substr(start, end == std::string::npos ? std::string::npos : end - start);
    if (!dir.empty()) {
      const fs::path candidate = fs::path(dir) / name;
      if (::access(candidate.c_str(), X_OK) == 0 && !fs::is_directory(candidate)) return candidate.string();
    }
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return "";
}

std::string self_executable() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? "" : p.string();
}

std::string shell_quote(const std::string& word) {
  if (!word.empty() && word.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-./=:,+@%") ==
                           std::string::npos)
    return word;
  std::string out(1, '\'');
  for (char c : word) {
    if (c == '\'') out.append("'\\''");
    else out.push_back(c);
  }
  out.push_back('\'');
  return out;
}

}  // namespace rtslam::eval
