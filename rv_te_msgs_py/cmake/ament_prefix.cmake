# Where are ament and rosidl? rv_te_find_ament_prefix(<out_var>) answers, in this order:
#
#  1. -DROS_WHEEL_PREFIX=<prefix> was given: that prefix (an explicit override).
#  2. A prefix on AMENT_PREFIX_PATH registers rosidl_typesupport_c in its ament index: a real
#     ament environment (a sourced /opt/ros/<distro>/setup.sh, a colcon underlay).
#     <out_var> is set empty and nothing changes: the normal ROS 2 build, untouched.
#     (Skipped under pip / scikit-build-core, SKBUILD defined: a wheel is built against the
#     ros-jazzy-* wheels of its build environment even where a ROS 2 install is sourced.)
#  3. The Python interpreter (Python3_EXECUTABLE if set, else the one find_package(Python3)
#     picks: an active venv first) imports rosidl_adapter from
#     <prefix>/lib/python3.X/site-packages/ and <prefix> registers rosidl_typesupport_c: the
#     PyPI ros-jazzy-* wheels in a venv, or pip's isolated build environment. <out_var> is
#     <prefix>; the caller puts it on CMAKE_PREFIX_PATH and AMENT_PREFIX_PATH.
#  4. Neither: <out_var> is empty, and find_package(ament_cmake) fails with CMake's message.
#
# Why the wheels need this: the ament index (typesupport discovery) is read from
# AMENT_PREFIX_PATH at configure time, and a venv sets no such variable, so rosidl stops with
# "No 'rosidl_typesupport_c' found". Tested in script mode by tests/msgs/test_ament_prefix.py.

function(_rv_te_registers_typesupport prefix out_var)
  if(NOT "${prefix}" STREQUAL "" AND
     EXISTS "${prefix}/share/ament_index/resource_index/packages/rosidl_typesupport_c")
    set(${out_var} TRUE PARENT_SCOPE)
  else()
    set(${out_var} FALSE PARENT_SCOPE)
  endif()
endfunction()

function(rv_te_find_ament_prefix out_var)
  if(DEFINED ROS_WHEEL_PREFIX AND NOT "${ROS_WHEEL_PREFIX}" STREQUAL "")
    message(STATUS "ament prefix: ${ROS_WHEEL_PREFIX} (given as ROS_WHEEL_PREFIX)")
    set(${out_var} "${ROS_WHEEL_PREFIX}" PARENT_SCOPE)
    return()
  endif()
  if(DEFINED ENV{AMENT_PREFIX_PATH} AND NOT DEFINED SKBUILD)
    string(REPLACE ":" ";" _prefixes "$ENV{AMENT_PREFIX_PATH}")
    foreach(_p IN LISTS _prefixes)
      _rv_te_registers_typesupport("${_p}" _found)
      if(_found)
        message(STATUS "ament prefix: ${_p} from AMENT_PREFIX_PATH (sourced ROS 2); "
                       "no wheel prefix detection")
        set(${out_var} "" PARENT_SCOPE)
        return()
      endif()
    endforeach()
  endif()
  if(NOT DEFINED Python3_EXECUTABLE)
    find_package(Python3 COMPONENTS Interpreter)
  endif()
  if(NOT Python3_EXECUTABLE)
    message(STATUS "ament prefix: none on AMENT_PREFIX_PATH and no Python interpreter found")
    set(${out_var} "" PARENT_SCOPE)
    return()
  endif()
  execute_process(
    COMMAND "${Python3_EXECUTABLE}" -c
      "import pathlib, rosidl_adapter; print(pathlib.Path(rosidl_adapter.__file__).resolve().parents[4])"
    OUTPUT_VARIABLE _prefix OUTPUT_STRIP_TRAILING_WHITESPACE
    ERROR_QUIET RESULT_VARIABLE _rc)
  _rv_te_registers_typesupport("${_prefix}" _found)
  if(_rc EQUAL 0 AND _found)
    message(STATUS "ament prefix: ${_prefix} (ROS wheels, found from rosidl_adapter of "
                   "${Python3_EXECUTABLE})")
    set(${out_var} "${_prefix}" PARENT_SCOPE)
  else()
    message(STATUS "ament prefix: none on AMENT_PREFIX_PATH and ${Python3_EXECUTABLE} has no "
                   "ROS wheels (rosidl_adapter)")
    set(${out_var} "" PARENT_SCOPE)
  endif()
endfunction()
