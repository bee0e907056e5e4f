# Pinocchio's C++ package from the PyPI wheel `pin` (a cmeel prefix holding
# lib/cmake/pinocchio and its dependencies), for the programs that compare
# rbdkit with Pinocchio's C++ library (tests/pinocchio_so; bench/CMakeLists.txt
# does the same under its RBDKIT_BENCH_* names).
#   RBDKIT_PINOCCHIO_PREFIX        the prefix (empty: found from RBDKIT_PINOCCHIO_PYTHON's `pinocchio`)
#   RBDKIT_PINOCCHIO_EXTRA_PREFIX  more prefixes searched first: `pin` 4.1's package needs
#                                  urdfdom_headers, which no wheel it depends on ships
#                                  (scripts/pinocchio_prefix.sh fetches them)
# Defines the imported targets pinocchio::*.
set(RBDKIT_PINOCCHIO_EXTRA_PREFIX "" CACHE STRING "more prefixes for Pinocchio's dependencies (e.g. urdfdom_headers)")
set(RBDKIT_PINOCCHIO_PREFIX "" CACHE PATH "prefix holding lib/cmake/pinocchio (empty: found from Python)")
if(NOT RBDKIT_PINOCCHIO_PREFIX)
  find_program(RBDKIT_PINOCCHIO_PYTHON NAMES python3 python)
  # walk up from the pinocchio package to the folder holding lib/cmake/pinocchio
  execute_process(
    COMMAND ${RBDKIT_PINOCCHIO_PYTHON} -c
"import os, pinocchio
p = os.path.dirname(os.path.abspath(pinocchio.__file__))
while os.path.dirname(p) != p and not os.path.isfile(os.path.join(p, 'lib', 'cmake', 'pinocchio', 'pinocchioConfig.cmake')):
    p = os.path.dirname(p)
print(p if os.path.dirname(p) != p else '')"
    OUTPUT_VARIABLE _pin_prefix OUTPUT_STRIP_TRAILING_WHITESPACE
    ERROR_VARIABLE _pin_err RESULT_VARIABLE _pin_rc)
  if(NOT _pin_rc EQUAL 0 OR NOT _pin_prefix)
    message(FATAL_ERROR "Pinocchio's CMake package not found from ${RBDKIT_PINOCCHIO_PYTHON} (${_pin_err}); "
                        "pip install pin, or pass -DRBDKIT_PINOCCHIO_PREFIX=<prefix with lib/cmake/pinocchio>")
  endif()
  set(RBDKIT_PINOCCHIO_PREFIX "${_pin_prefix}" CACHE PATH "prefix holding lib/cmake/pinocchio (empty: found from Python)" FORCE)
endif()
message(STATUS "Pinocchio prefix ${RBDKIT_PINOCCHIO_PREFIX}")

# Pinocchio's dependencies (boost, coal, urdfdom, ...) from the same prefix
list(PREPEND CMAKE_PREFIX_PATH ${RBDKIT_PINOCCHIO_EXTRA_PREFIX} "${RBDKIT_PINOCCHIO_PREFIX}")
set(Boost_NO_WARN_NEW_VERSIONS ON)  # FindBoost of CMake < 3.31 does not know the prefix's Boost 1.90
find_package(urdfdom_headers CONFIG QUIET)
if(NOT urdfdom_headers_FOUND)
  message(FATAL_ERROR "Pinocchio's CMake package needs urdfdom_headers, not found in ${CMAKE_PREFIX_PATH}. "
                      "scripts/pinocchio_prefix.sh fetches them; by hand: pip install --no-deps --target DIR "
                      "cmeel-urdfdom-headers==<version> and pass -DRBDKIT_PINOCCHIO_EXTRA_PREFIX=DIR/cmeel.prefix")
endif()
find_package(pinocchio CONFIG REQUIRED)
message(STATUS "Pinocchio ${pinocchio_VERSION}")
