# Checks that the shared library cargo built has the SONAME the package
# promises (IMPORTED_SONAME, the install's links). build.rs gives it one
# only when PRECISEMC_SONAME is set, so a plain `cargo build` into a
# shared target directory leaves a library without it, and programs linked
# against that record its path instead.
#
#   cmake -DPMC_LIBRARY=<file> -DPMC_SONAME=<name> -DPMC_READELF=<readelf>
#         [-DPMC_HINT=<what to do>] -P PreciseMCCheckSoname.cmake
# (or include()d with those variables set, as the install step does).

foreach(_var PMC_LIBRARY PMC_SONAME PMC_READELF)
  if(NOT ${_var})
    message(FATAL_ERROR "PreciseMCCheckSoname.cmake: ${_var} not set")
  endif()
endforeach()
if(NOT EXISTS "${PMC_LIBRARY}")
  message(FATAL_ERROR "PreciseMC: ${PMC_LIBRARY} does not exist. ${PMC_HINT}")
endif()
execute_process(COMMAND "${PMC_READELF}" -d "${PMC_LIBRARY}"
  RESULT_VARIABLE _status OUTPUT_VARIABLE _dynamic ERROR_VARIABLE _error)
if(NOT _status EQUAL 0)
  message(FATAL_ERROR "PreciseMC: ${PMC_READELF} -d ${PMC_LIBRARY} failed: ${_error}")
endif()
set(_found "")
if(_dynamic MATCHES "\\(SONAME\\)[^\n]*\\[([^]\n]*)\\]")
  set(_found "${CMAKE_MATCH_1}")
endif()
if(NOT _found STREQUAL PMC_SONAME)
  if(_found STREQUAL "")
    set(_found "no SONAME")
  else()
    set(_found "the SONAME ${_found}")
  endif()
  message(FATAL_ERROR "PreciseMC: ${PMC_LIBRARY} has ${_found}, not ${PMC_SONAME}, "
    "so programs linked against it would record its path. build.rs gives the library "
    "its SONAME only when cargo runs with PRECISEMC_SONAME=${PMC_SONAME}: a build "
    "without it (a plain `cargo build` into the same target directory) linked this "
    "file. ${PMC_HINT}")
endif()
