# Helpers to build the Rust crate from CMake (used by the top-level
# CMakeLists.txt only).

include("${CMAKE_CURRENT_LIST_DIR}/PreciseMCVersion.cmake")

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
