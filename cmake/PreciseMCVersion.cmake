# The crate version, read from Cargo.toml: the one version number of the
# library, the VTK filter (cpp/), the ParaView plugin (paraview/) and the
# command-line tool. Included by PreciseMCCargo.cmake and by cpp/ and
# paraview/ before their project() calls.

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
      # A new version in Cargo.toml reconfigures the build (SONAME,
      # package version, the tool's --version).
      set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS "${manifest}")
      return()
    endif()
  endforeach()
  message(FATAL_ERROR "No [package] version found in ${manifest}")
endfunction()
