# Configures the tree twice (math only, to keep it short) and reads the
# compile commands: -Werror only with -DHEMM_WERROR=ON.
# Under a directory of its own (string(RANDOM) is seeded from the system's
# random source), so two ctest runs of one build tree at once do not
# configure into the same place.
string(RANDOM LENGTH 12 ALPHABET 0123456789abcdefghijklmnopqrstuvwxyz _run)
set(WORK_DIR ${WORK_DIR}/${_run})
function(configure_and_read werror out)
  set(dir ${WORK_DIR}/${werror})
  file(REMOVE_RECURSE ${dir})
  execute_process(COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${dir} -G ${GENERATOR} -DCMAKE_BUILD_TYPE=Release
                          -DHEMM_WERROR=${werror} -DHEMM_COMPONENTS=math -DHEMM_BENCH=OFF
                  RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "configure with HEMM_WERROR=${werror} failed:\n${err}")
  endif()
  file(READ ${dir}/compile_commands.json cc)
  file(REMOVE_RECURSE ${dir})
  set(${out} "${cc}" PARENT_SCOPE)
endfunction()

configure_and_read(OFF plain)
configure_and_read(ON strict)
file(REMOVE_RECURSE ${WORK_DIR})
if(NOT plain MATCHES "workspace_maps\\.cpp")
  message(FATAL_ERROR "no compile command for common/math in the plain configuration")
endif()
if(plain MATCHES "-Werror")
  message(FATAL_ERROR "a plain configuration (HEMM_WERROR off, the default) compiles with -Werror")
endif()
if(NOT strict MATCHES "-Werror")
  message(FATAL_ERROR "-DHEMM_WERROR=ON does not add -Werror")
endif()
message(STATUS "plain build: warnings are warnings; HEMM_WERROR=ON: errors")
