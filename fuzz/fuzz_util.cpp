#include "fuzz_util.hpp"

#include <cxxabi.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <typeinfo>

#include "rtslam/core/log.hpp"

namespace rtslam::fuzz {
namespace fs = std::filesystem;

namespace {

void remove_scratch() {
  std::error_code ec;
  fs::remove_all(scratch_dir(), ec);
}

}  // namespace

const std::string& scratch_dir() {
  // Never destroyed: the exit handler that removes the folder runs after static destructors would have.
  static const std::string* dir = [] {
    const fs::path p = fs::temp_directory_path() / ("rtslam-fuzz-" + std::to_string(::getpid()));
    fs::remove_all(p);
    fs::create_directories(p);
    auto* s = new std::string(p.string());
    std::atexit(remove_scratch);
    return s;
  }();
  return *dir;
}

std::string write_input(const std::string& rel, const std::uint8_t* data, std::size_t size) {
  const fs::path p = fs::path(scratch_dir()) / rel;
  fs::create_directories(p.parent_path());
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  out.close();
  if (!out) finding("cannot write the input to " + p.string());
  return p.string();
}

std::string write_input(const std::string& rel, std::string_view text) {
  return write_input(rel, reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
}

void finding(const std::string& what) {
  std::fprintf(stderr, "\n==== fuzz finding: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

void unexpected_exception(const char* call) {
  try {
    throw;
  } catch (const std::exception& e) {
    int status = 0;
    char* name = abi::__cxa_demangle(typeid(e).name(), nullptr, nullptr, &status);
    const std::string type = status == 0 && name ? name : typeid(e).name();
    std::free(name);
    finding(std::string(call) + " threw " + type + " (not IoError/ConfigError/DataError): " + e.what());
  } catch (...) {
    finding(std::string(call) + " threw an exception that is not a std::exception");
  }
}

void quiet_logs() { set_log_level("off"); }

void check_message(const Error& e, std::string_view names, const char* call) {
  const std::string msg = e.what();
  if (msg.find(names) == std::string::npos) {
    finding(std::string(call) + ": the error message does not name '" + std::string(names) + "': " + msg);
  }
}

}  // namespace rtslam::fuzz
