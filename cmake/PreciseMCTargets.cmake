# Defines the imported targets of PreciseMC. Used by the top-level
# CMakeLists.txt (build tree) and installed next to PreciseMCConfig.cmake.
#
#   precisemc_define_targets(<prefix> <library dir> <include dir> <native libs>
#                            <soname> [GLOBAL])
#
# creates <prefix>precisemc (shared library) and <prefix>precisemc_static
# (static library, linking the native libraries Rust's standard library
# needs). <soname> is the shared library's SONAME ("" when it has none).

function(precisemc_define_targets prefix libdir incdir native_libs soname)
  set(_global ${ARGN})
  add_library(${prefix}precisemc SHARED IMPORTED ${_global})
  add_library(${prefix}precisemc_static STATIC IMPORTED ${_global})
  set(_shared "${libdir}/${CMAKE_SHARED_LIBRARY_PREFIX}precisemc${CMAKE_SHARED_LIBRARY_SUFFIX}")
  if(WIN32)
    set(_static "${libdir}/precisemc.lib")
    set_target_properties(${prefix}precisemc PROPERTIES
      IMPORTED_LOCATION "${libdir}/precisemc.dll"
      IMPORTED_IMPLIB "${libdir}/precisemc.dll.lib")
  else()
    set(_static "${libdir}/libprecisemc.a")
    set_target_properties(${prefix}precisemc PROPERTIES IMPORTED_LOCATION "${_shared}")
    if(soname)
      # Programs record the SONAME, found at run time beside the library.
      set_target_properties(${prefix}precisemc PROPERTIES IMPORTED_SONAME "${soname}")
    else()
      # A library without one: link by name so that the executable records
      # "libprecisemc.so", not the path it was linked from.
      set_target_properties(${prefix}precisemc PROPERTIES IMPORTED_NO_SONAME TRUE)
    endif()
  endif()
  set_target_properties(${prefix}precisemc PROPERTIES
    INTERFACE_INCLUDE_DIRECTORIES "${incdir}")
  # As linker flags (-lm), not names: a plain name would link a consumer's
  # own target of that name (a library called util or m) instead.
  set(_native "")
  foreach(_lib IN LISTS native_libs)
    if(NOT WIN32 AND NOT _lib MATCHES "^[-/]")
      set(_lib "-l${_lib}")
    endif()
    list(APPEND _native "${_lib}")
  endforeach()
  set_target_properties(${prefix}precisemc_static PROPERTIES
    IMPORTED_LOCATION "${_static}"
    IMPORTED_LINK_INTERFACE_LANGUAGES "C"
    INTERFACE_INCLUDE_DIRECTORIES "${incdir}"
    INTERFACE_LINK_LIBRARIES "${_native}")
endfunction()
