# cmake -P script of test_install_example (tests/install/CMakeLists.txt): install, check the prefix, build and run
# the example against it. Every step fails the test with its output.
foreach(var BUILD_DIR SOURCE_DIR WORK_DIR CXX GENERATOR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "install_example.cmake: -D${var}=... is missing")
  endif()
endforeach()
set(prefix ${WORK_DIR}/prefix)
file(REMOVE_RECURSE ${WORK_DIR})
string(TIMESTAMP t0 "%s")

# Runs a command; fails with its output unless it exits 0. Sets `output` in the caller.
function(step what)
  string(TIMESTAMP start "%s")
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
  string(TIMESTAMP end "%s")
  math(EXPR seconds "${end} - ${start}")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} failed (${rc}) after ${seconds} s:\n${ARGN}\n${out}")
  endif()
  message(STATUS "${what}: ${seconds} s")
  set(output "${out}" PARENT_SCOPE)
endfunction()

step("install" ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(f include/rtslam/pipeline/image_slam.hpp include/rtslam/models/sensors/pinhole_camera.hpp
          lib/librtslam_core.a lib/librtslam_pipeline.a lib/cmake/rtslam/rtslamConfig.cmake
          lib/cmake/rtslam/rtslamConfigVersion.cmake lib/cmake/rtslam/rtslamTargets.cmake bin/rtslam
          share/rtslam/config/sim_mono.yaml share/doc/rtslam/install.md lib/rtslam/librtslam_opencv_codecs.so)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "the install has no ${f} (prefix ${prefix})")
  endif()
endforeach()

step("installed rtslam --help" ${prefix}/bin/rtslam --help)
if(NOT output MATCHES "run")
  message(FATAL_ERROR "installed rtslam --help does not list the run command:\n${output}")
endif()

# The installed CLI loads the installed OpenCV codecs plugin (found from its own folder: bin/../lib/rtslam), not the
# build tree's.
step("installed rtslam --version" ${prefix}/bin/rtslam --version)
file(REAL_PATH ${prefix} real_prefix)  # the CLI finds it from its resolved path (/proc/self/exe)
string(FIND "${output}" "OpenCV codecs plugin: ${real_prefix}/lib/rtslam/librtslam_opencv_codecs.so\n" at)
if(at EQUAL -1)
  message(FATAL_ERROR "installed rtslam --version does not name the installed codecs plugin:\n${output}")
endif()

set(configure_args -S ${SOURCE_DIR}/examples -B ${WORK_DIR}/build -G ${GENERATOR} -DCMAKE_BUILD_TYPE=Release
                   -DCMAKE_CXX_COMPILER=${CXX} -DCMAKE_PREFIX_PATH=${prefix})
if(LAUNCHER)
  list(APPEND configure_args -DCMAKE_CXX_COMPILER_LAUNCHER=${LAUNCHER})
endif()
step("configure examples/ (find_package(rtslam))" ${CMAKE_COMMAND} ${configure_args})
step("build examples/" ${CMAKE_COMMAND} --build ${WORK_DIR}/build)

# 60 images of the simulator with the installed preset (a few seconds).
step("run the example on the simulator" ${WORK_DIR}/build/run_dataset ${prefix}/share/rtslam/config/sim_mono.yaml
     --frames 60)
if(NOT output MATCHES "trajectory: ([0-9]+) poses" OR CMAKE_MATCH_1 LESS 50)
  message(FATAL_ERROR "the example printed no trajectory of at least 50 poses:\n${output}")
endif()
string(REGEX MATCH "trajectory: [^\n]*" summary "${output}")
string(TIMESTAMP t1 "%s")
math(EXPR total "${t1} - ${t0}")
message(STATUS "${summary}")
message(STATUS "total: ${total} s")
