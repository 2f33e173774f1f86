# Python bindings (docs/python.md): the `rtslam` extension module of python/, built with pybind11.
#
# RTSLAM_PYTHON: AUTO (default: build the module when pybind11 and the Python development files are found), ON (fail
# without them), OFF. Never under RTSLAM_SANITIZE: an ASan-instrumented module cannot be loaded into an
# uninstrumented interpreter. Sets RTSLAM_HAVE_PYTHON; the interpreter is Python3_EXECUTABLE (give Debian's
# /usr/bin/python3 when the first python3 on the PATH lacks numpy, which the tests need).
#
# The module is a shared object linking the static module libraries, so those are compiled as position-independent
# code when it is built (rtslam_add_module reads RTSLAM_HAVE_PYTHON).
set(RTSLAM_PYTHON AUTO CACHE STRING "Python bindings: AUTO (when found), ON (required) or OFF")
set_property(CACHE RTSLAM_PYTHON PROPERTY STRINGS AUTO ON OFF)
set(RTSLAM_HAVE_PYTHON OFF)
set(RTSLAM_PYTHON_NUMPY OFF)  # the interpreter imports numpy (the Python tests are registered only then)

if(RTSLAM_PYTHON STREQUAL "OFF")
  message(STATUS "Python: off (RTSLAM_PYTHON=OFF); the rtslam module is not built")
elseif(RTSLAM_SANITIZE)
  if(RTSLAM_PYTHON STREQUAL "ON")
    message(FATAL_ERROR "RTSLAM_PYTHON=ON and RTSLAM_SANITIZE=ON do not mix (an ASan module in a plain interpreter)")
  endif()
  message(STATUS "Python: off under RTSLAM_SANITIZE; the rtslam module is not built")
else()
  find_package(Python3 QUIET COMPONENTS Interpreter Development.Module)
  if(Python3_FOUND)
    find_package(pybind11 CONFIG QUIET)
  endif()
  if(Python3_FOUND AND pybind11_FOUND)
    set(RTSLAM_HAVE_PYTHON ON)
    execute_process(COMMAND ${Python3_EXECUTABLE} -c "import numpy" RESULT_VARIABLE _numpy_rc OUTPUT_QUIET ERROR_QUIET)
    if(_numpy_rc EQUAL 0)
      set(RTSLAM_PYTHON_NUMPY ON)
    else()
      message(STATUS "Python: ${Python3_EXECUTABLE} lacks numpy: test_python is not registered "
                     "(give -DPython3_EXECUTABLE=/usr/bin/python3, whose python3-numpy scripts/deps.sh installs)")
    endif()
    message(STATUS "Python: ${Python3_EXECUTABLE} (${Python3_VERSION}), pybind11 ${pybind11_VERSION}, "
                   "numpy: ${RTSLAM_PYTHON_NUMPY}; building the rtslam module")
  elseif(RTSLAM_PYTHON STREQUAL "ON")
    message(FATAL_ERROR "RTSLAM_PYTHON=ON but Python3 (Interpreter, Development.Module: ${Python3_FOUND}) or "
                        "pybind11 (${pybind11_FOUND}) is missing (bash scripts/deps.sh installs the Debian packages)")
  else()
    message(STATUS "Python: not found (Python3 development: ${Python3_FOUND}, pybind11: ${pybind11_FOUND}); "
                   "the rtslam module is not built")
  endif()
endif()
