#include "rtslam/io/codecs.hpp"

#include <dlfcn.h>
#include <link.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"

// Set by src/rtslam/io/CMakeLists.txt: the plugin's file in this build tree, in the installation prefix, the path
// from the installed executables' folder to it, and what identifies the build (the plugin carries the same).
#if !defined(RTSLAM_CODECS_BUILD_PATH) || !defined(RTSLAM_CODECS_INSTALL_PATH) || \
    !defined(RTSLAM_CODECS_FROM_BINDIR) || !defined(RTSLAM_CODECS_BUILD_ID)
#error "codecs.cpp needs RTSLAM_CODECS_BUILD_PATH, _INSTALL_PATH, _FROM_BINDIR and _BUILD_ID (io/CMakeLists.txt)"
#endif

namespace rtslam::io::codecs {
namespace {

namespace fs = std::filesystem;

struct Loaded {
  const PluginApi* api = nullptr;
  std::string path;
  std::string error;  // why nothing loaded (then api is null)
};

// Opens `path` and checks its interface and build; on failure says why in `why` and returns null (the library is
// closed).
const PluginApi* try_load(const std::string& path, std::string& why) {
  void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* e = dlerror();
    why = e != nullptr ? e : "dlopen failed";
    return nullptr;
  }
  using Entry = const PluginApi* (*)();
  auto entry = reinterpret_cast<Entry>(dlsym(handle, "rtslam_opencv_codecs_api"));
  const PluginApi* api = entry != nullptr ? entry() : nullptr;
  if (api == nullptr) {
    why = "not an rtslam codecs plugin (no rtslam_opencv_codecs_api)";
  } else if (api->interface_version != kPluginInterface) {
    why = fmt::format("interface version {}, this program needs {}", api->interface_version, kPluginInterface);
    api = nullptr;
  } else if (api->build == nullptr || std::strcmp(api->build, RTSLAM_CODECS_BUILD_ID) != 0) {
    why = fmt::format("built as '{}', this program as '{}'", api->build != nullptr ? api->build : "?",
                      RTSLAM_CODECS_BUILD_ID);
    api = nullptr;
  }
  if (api == nullptr) dlclose(handle);
  return api;  // kept loaded for the life of the process
}

// Whether this code was linked into the executable (not into a shared object, e.g. the Python module): its address
// lies in one of the main program's loaded segments (the first object dl_iterate_phdr reports).
bool in_main_program() {
  struct Query {
    std::uintptr_t address;
    bool inside = false;
  } q{reinterpret_cast<std::uintptr_t>(&in_main_program)};
  dl_iterate_phdr(
      [](dl_phdr_info* info, std::size_t, void* data) {
        auto* query = static_cast<Query*>(data);
        for (int i = 0; i < info->dlpi_phnum; ++i) {
          const ElfW(Phdr)& ph = info->dlpi_phdr[i];
          if (ph.p_type != PT_LOAD) continue;
          const std::uintptr_t begin = info->dlpi_addr + ph.p_vaddr;
          if (query->address >= begin && query->address < begin + ph.p_memsz) query->inside = true;
        }
        return 1;  // the main program only
      },
      &q);
  return q.inside;
}

Loaded load() {
  Loaded out;
  std::vector<std::string> candidates;
  const auto add = [&candidates](std::string path) {
    if (std::find(candidates.begin(), candidates.end(), path) == candidates.end()) candidates.push_back(std::move(path));
  };
  std::error_code ec;
  if (const char* env = std::getenv("RTSLAM_CODECS_PLUGIN"); env != nullptr && *env != '\0') {
    add(fs::absolute(env, ec).lexically_normal().string());  // only there: an explicit choice is not second-guessed
  } else {
    if (in_main_program()) {
      const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
      if (!ec) add((exe.parent_path() / RTSLAM_CODECS_FROM_BINDIR).lexically_normal().string());
    }
    add(RTSLAM_CODECS_BUILD_PATH);
    add(RTSLAM_CODECS_INSTALL_PATH);
  }
  std::string tried;
  for (const std::string& path : candidates) {
    std::string why;
    if (!fs::exists(path, ec)) {
      why = ec ? ec.message() : "no such file";
    } else if ((out.api = try_load(path, why)) != nullptr) {
      out.path = path;
      return out;
    }
    tried += fmt::format("{}{} ({})", tried.empty() ? "" : "; ", path, why);
  }
  out.error = fmt::format(
      "OpenCV codecs plugin librtslam_opencv_codecs.so (image formats other than 8-bit grey PNG, image and video "
      "writing, video and camera input) not loaded: tried {}; build or install rtslam with it, or set "
      "RTSLAM_CODECS_PLUGIN to its path",
      tried);
  return out;
}

const Loaded& loaded() {
  static const Loaded l = load();  // thread-safe, once
  return l;
}

const PluginApi& api() {
  const Loaded& l = loaded();
  if (l.api == nullptr) throw IoError(l.error);
  return *l.api;
}

}  // namespace

const std::string& load_plugin() {
  api();
  return loaded().path;
}

cv::Mat imread(const std::string& path, int flags) { return api().imread(path, flags); }

bool imwrite(const std::string& path, const cv::Mat& image, const std::vector<int>& params) {
  return api().imwrite(path, image, params);
}

bool imencode(const std::string& extension, const cv::Mat& image, std::vector<unsigned char>& out,
              const std::vector<int>& params) {
  return api().imencode(extension, image, out, params);
}

cv::Mat imdecode(const cv::Mat& buffer, int flags) { return api().imdecode(buffer, flags); }

std::unique_ptr<VideoReader> open_video(const std::string& path, int api_preference) {
  return api().open_video(path, api_preference);
}

std::unique_ptr<VideoReader> open_camera(int index, int api_preference) {
  return api().open_camera(index, api_preference);
}

std::unique_ptr<VideoWriter> open_video_writer(const std::string& path, int api_preference, int fourcc, double fps,
                                               cv::Size size, bool color) {
  return api().open_video_writer(path, api_preference, fourcc, fps, size, color);
}

}  // namespace rtslam::io::codecs
