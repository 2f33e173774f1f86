# Precompiled headers (RTSLAM_PCH, default ON; clang only, see rtslam_pch_apply): the system headers nearly every unit
# includes (the standard library, Eigen, fmt/spdlog, yaml-cpp, OpenCV's core, nlohmann/json; gtest for the tests) are
# parsed once per tree instead of once per unit. A clang -ftime-trace of the sanitizer tree (29 Nov 2026) spent 424
# of its 1900 compile seconds in #include'd text (docs/testing.md, "Build time").
#
# A precompiled header is valid only for units compiled with the options it was built with (clang checks the language
# options and every command-line macro). So there is one per kind of target, built by a holder target
# (rtslam_pch_module, rtslam_pch_test) that gets its options the way the targets of its kind do
# (rtslam_module_settings, rtslam_test_settings), and reused (REUSE_FROM) by each candidate of that kind whose own
# options are exactly the holder's: "module" for the module libraries and the programs built like them, "test" for
# the test executables. A candidate that adds options of its own (-ffp-contract=off of the filter and the
# simulator, the fuzzer's coverage hooks on core and io, a test's FULL_OPT, the -O1 of the test folders that keep it
# under the sanitizers: tests/CMakeLists.txt rtslam_tests_optimized) parses its headers itself, and so does a source
# file with options or definitions of its own (the ROS parts' -std=c++17, the viewer's embedded assets). The Release
# tree (GCC) uses none, so it still checks that every unit includes what it uses.
set(RTSLAM_PCH_HEADERS
  <algorithm> <array> <chrono> <cmath> <cstddef> <cstdint> <cstdio> <filesystem> <fstream> <functional> <map>
  <memory> <mutex> <optional> <ostream> <sstream> <string> <string_view> <thread> <unordered_map> <utility> <variant>
  <vector>
  <Eigen/Core> <Eigen/Dense> <Eigen/Geometry>
  <fmt/format.h> <nlohmann/json.hpp> <opencv2/core.hpp> <spdlog/spdlog.h> <yaml-cpp/yaml.h>)

# Called where a target of KIND ("module" or "test") is created: it may reuse that kind's precompiled header.
function(rtslam_pch_candidate target kind)
  set_property(GLOBAL APPEND PROPERTY RTSLAM_PCH_${kind} ${target})
endfunction()

# Called once, at the end of the top-level CMakeLists.txt (every target and its options known): builds each kind's
# holder and lets the candidates whose options match reuse it.
function(rtslam_pch_apply)
  # Clang only: GCC 12 compiles code differently through a precompiled header. Its middle-end warnings changed
  # (std::string's operator+ on a constant path gave false -Warray-bounds in two test units, fatal under -Werror,
  # depending on the path's length), and the Release tree gained only 12 % (1334 -> 1178 s of compile time).
  if(NOT RTSLAM_PCH OR NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    return()
  endif()
  foreach(kind module test)
    get_property(candidates GLOBAL PROPERTY RTSLAM_PCH_${kind})
    if(NOT candidates)
      continue()
    endif()
    set(holder rtslam_pch_${kind})
    set(source ${PROJECT_BINARY_DIR}/pch/${kind}.cpp)
    file(CONFIGURE OUTPUT ${source} CONTENT "// Compiles the precompiled header of rtslam's ${kind} targets.\n")
    add_library(${holder} OBJECT ${source})
    target_link_libraries(${holder} PRIVATE rtslam_options Eigen3::Eigen fmt::fmt spdlog::spdlog yaml-cpp
                                            nlohmann_json::nlohmann_json ${OpenCV_LIBS})
    set(headers ${RTSLAM_PCH_HEADERS})
    if(kind STREQUAL "module")
      rtslam_module_settings(${holder})
      if(BUILD_SHARED_LIBS)  # the modules are then shared libraries, compiled as position-independent code
        set_target_properties(${holder} PROPERTIES POSITION_INDEPENDENT_CODE ON)
      endif()
    else()
      target_link_libraries(${holder} PRIVATE GTest::gtest)
      rtslam_test_settings(${holder})
      list(APPEND headers <gtest/gtest.h>)
    endif()
    target_precompile_headers(${holder} PRIVATE ${headers})
    _rtslam_pch_options(${holder} holder_options)
    # Without file times in it, a header that ccache restores stays valid when cmake_pch.hxx is written again (a
    # fresh build folder at the same path); clang still checks the headers' sizes.
    target_compile_options(${holder} PRIVATE "SHELL:-Xclang -fno-pch-timestamp")
    foreach(target ${candidates})
      _rtslam_pch_options(${target} options)
      if(NOT "${options}" STREQUAL "${holder_options}")
        continue()  # options of its own: the shared header would not be valid for it
      endif()
      target_precompile_headers(${target} REUSE_FROM ${holder})
      # Sources with options of their own (not compiled in the unity units either) parse their headers themselves.
      get_target_property(sources ${target} SOURCES)
      get_target_property(dir ${target} SOURCE_DIR)
      foreach(src ${sources})
        if(NOT IS_ABSOLUTE ${src})  # relative to the target's folder, not to this (top-level) one
          set(src ${dir}/${src})
        endif()
        get_source_file_property(src_options ${src} DIRECTORY ${dir} COMPILE_OPTIONS)
        get_source_file_property(src_flags ${src} DIRECTORY ${dir} COMPILE_FLAGS)
        get_source_file_property(src_defs ${src} DIRECTORY ${dir} COMPILE_DEFINITIONS)
        if(src_options OR src_flags OR src_defs)
          set_source_files_properties(${src} DIRECTORY ${dir} PROPERTIES SKIP_PRECOMPILE_HEADERS ON)
        endif()
      endforeach()
    endforeach()
  endforeach()
endfunction()

# OUT: what of a target's own settings a precompiled header depends on, as one string: its compile options and its
# position-independence (shared libraries are by default). The language standard is every target's cxx_std_20 (from
# rtslam_options; a mismatch would be a hard error of clang's, not a silent one). Its own compile definitions are left
# out: those of our targets (RTSLAM_SOURCE_DIR, RTSLAM_CLI...) are read by no system header; a definition that
# changes a library's headers belongs on that library's target (and so on the holder's).
function(_rtslam_pch_options target out)
  get_target_property(type ${target} TYPE)
  set(key "")
  foreach(property COMPILE_OPTIONS POSITION_INDEPENDENT_CODE)
    get_target_property(value ${target} ${property})
    if(value MATCHES "-NOTFOUND$")  # unset
      set(value "")
      if(property STREQUAL "POSITION_INDEPENDENT_CODE" AND type MATCHES "^(SHARED|MODULE)_LIBRARY$")
        set(value ON)
      endif()
    elseif(property STREQUAL "POSITION_INDEPENDENT_CODE")  # a boolean: ON, True, 1...
      if(value)
        set(value ON)
      else()
        set(value "")
      endif()
    endif()
    string(APPEND key "${value}|")
  endforeach()
  set(${out} "${key}" PARENT_SCOPE)
endfunction()
