#pragma once
// The viewer page's files, embedded into the binary at build time (src/rtslam/viz/CMakeLists.txt runs
// embed_assets.cpp over web/ and, when npm was available at build time, three.js's own dist files from
// node_modules): nothing is fetched at run time, so the viewer works offline.
#include <cstddef>
#include <span>
#include <string_view>

namespace rtslam::viz {

struct Asset {
  std::string_view path;  // URL path, e.g. "/index.html", "/vendor/three/three.module.js"
  std::string_view mime;  // Content-Type
  const unsigned char* data;
  std::size_t size;
};

/// Every embedded file.
std::span<const Asset> embedded_assets();
/// The asset at a URL path ("/" is "/index.html"), or nullptr.
const Asset* find_asset(std::string_view path);
/// Whether three.js was bundled (npm ci ran at build time); without it the page shows no 3D view.
bool three_js_bundled();

}  // namespace rtslam::viz
