# One piece of code per job (issue 9 item 15): each check fails if a second
# copy of a shared helper comes back into the sources. Run as
#   cmake -DSOURCE_DIR=<repo> -DCHECK=<name> -P one_piece_per_job_test.cmake
# A check lists where a pattern may appear; anywhere else is a failure.
cmake_minimum_required(VERSION 3.20)
file(GLOB_RECURSE _files LIST_DIRECTORIES false RELATIVE ${SOURCE_DIR}
     ${SOURCE_DIR}/common/*.h ${SOURCE_DIR}/common/*.cpp ${SOURCE_DIR}/operator/*.h ${SOURCE_DIR}/operator/*.cpp
     ${SOURCE_DIR}/robot_side/*.h ${SOURCE_DIR}/robot_side/*.cpp ${SOURCE_DIR}/tests/*.h ${SOURCE_DIR}/tests/*.cpp)
list(LENGTH _files _n)
if(_n LESS 100)
  message(FATAL_ERROR "only ${_n} source files found under ${SOURCE_DIR}: wrong SOURCE_DIR?")
endif()

# only_in(<regex> <allowed files...>): fails listing every other file and line.
set(_failures "")
function(only_in regex)
  set(_allowed ${ARGN})
  foreach(f ${_files})
    file(STRINGS ${SOURCE_DIR}/${f} _hits REGEX "${regex}")
    if(_hits AND NOT f IN_LIST _allowed)
      foreach(h ${_hits})
        string(STRIP "${h}" h)
        list(APPEND _failures "${f}: ${h}")
      endforeach()
    endif()
  endforeach()
  set(_failures ${_failures} PARENT_SCOPE)
endfunction()

if(CHECK STREQUAL "mailbox")
  # One newest-wins triple buffer between threads.
  only_in("class [A-Za-z]*Mailbox[ {]" common/concurrency/newest_mailbox.h)
elseif(CHECK STREQUAL "pi")
  # std::numbers::pi, not a literal, M_PI or a project constant.
  only_in("M_PI|3\\.14159|6\\.28318|1\\.570796|constexpr double kPi|const double kPi")
elseif(CHECK STREQUAL "frames")
  # One SE(2) pose, one wheel-speed pair, one angle wrap.
  only_in("struct Pose2[ {]" common/math/frames.h)
  only_in("struct WheelSpeeds[ {]" common/math/workspace_maps.h)
  only_in("double wrap_angle\\(double" common/math/frames.h)
elseif(CHECK STREQUAL "clock")
  # One steady clock reading in nanoseconds.
  only_in("int64_t [a-z_]*now_ns\\(\\)" common/clock/steady_clock.h)
elseif(CHECK STREQUAL "json")
  # One JSON writer: protobuf messages printed by config::to_json; tests may
  # parse what it wrote.
  only_in("json_util\\.h" common/config/config.cpp tests/common/config/report_json.h tests/operator/station/nav_goal_test.cpp)
  only_in("<< \"\\{\\\\\"|\"\\{\\\\\"[a-z_]+\\\\\":" tests/common/net/relay/relay_test.cpp)
else()
  message(FATAL_ERROR "unknown CHECK '${CHECK}'")
endif()

if(_failures)
  list(JOIN _failures "\n  " _msg)
  message(FATAL_ERROR "${CHECK}: a second copy of a shared helper:\n  ${_msg}")
endif()
message(STATUS "${CHECK}: one piece of code (${_n} files)")
