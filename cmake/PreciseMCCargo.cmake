# Helpers to build the Rust crate from CMake (used by the top-level
# CMakeLists.txt only).

# Reads the [package] version of the crate from Cargo.toml into <out_var>.
function(precisemc_cargo_version manifest out_var)
  file(STRINGS "${manifest}" _lines)
  set(_in_package FALSE)
  foreach(_line IN LISTS _lines)
    if(_line MATCHES "^\\[package\\]")
      set(_in_package TRUE)
    elseif(_line MATCHES "^\\[")
      set(_in_package FALSE)
    elseif(_in_package AND _line MATCHES "^version *= *\"([0-9]+\\.[0-9]+\\.[0-9]+)[^\"]*\"")
      set(${out_var} "${CMAKE_MATCH_1}" PARENT_SCOPE)
      return()
    endif()
  endforeach()
  message(FATAL_ERROR "No [package] version found in ${manifest}")
endfunction()

# The native libraries the Rust static library needs, as printed by
#   cargo rustc --release --lib --crate-type staticlib -- --print native-static-libs
# (on Linux/glibc: -lgcc_s -lutil -lrt -lpthread -lm -ldl -lc). Override with
# -DPRECISEMC_NATIVE_STATIC_LIBS=... on other platforms or toolchains.
if(WIN32)
  set(_pmc_native_default "kernel32;advapi32;ntdll;userenv;ws2_32;dbghelp")
elseif(APPLE)
  set(_pmc_native_default "System;c;m")
else()
  set(_pmc_native_default "gcc_s;util;rt;pthread;m;dl;c")
endif()
set(PRECISEMC_NATIVE_STATIC_LIBS "${_pmc_native_default}" CACHE STRING
    "Native libraries linked after the Rust static library libprecisemc")
