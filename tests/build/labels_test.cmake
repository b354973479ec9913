# Lists the tests labelled timing or loopback and checks REQUIRED (comma
# separated) are among them.
string(REPLACE "," ";" REQUIRED "${REQUIRED}")
execute_process(COMMAND ${CTEST} -N -L "timing|loopback" WORKING_DIRECTORY ${BUILD_DIR}
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "ctest -N failed: ${err}")
endif()
foreach(name IN LISTS REQUIRED)
  string(FIND "${out}" ": ${name}\n" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "${name} runs on the wall clock but is not labelled timing or loopback")
  endif()
endforeach()
message(STATUS "labelled: ${REQUIRED}")
