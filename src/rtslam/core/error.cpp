#include "rtslam/core/error.hpp"

namespace rtslam {

void throw_invariant(const char* cond, const char* file, int line, const std::string& msg) {
  throw InvariantError(fmt::format("invariant '{}' failed at {}:{}: {}", cond, file, line, msg));
}

}  // namespace rtslam
