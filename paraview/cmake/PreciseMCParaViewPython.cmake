# Debian 12 splits ParaView's Python side into python3-paraview, which
# conflicts with python3-vtk9 (both install vtkmodules/ into the system
# dist-packages), and the project's VTK tests need python3-vtk9. ParaView's
# CMake package (paraview-dev) nevertheless imports targets whose files come
# from python3-paraview (the Python modules of VTK and ParaView, and
# /usr/bin/pvpython), and CMake's generated target files stop with "The
# imported target ... references the file ... but this file does not exist"
# when that package is absent.
#
# The plugin uses none of those files. When they are missing, the affected
# target files are imported here first, from a copy without the final
# existence check (targets and properties unchanged); ParaView's own
# find_package() then finds every target defined and skips the files.

# Imports <targets_file> without its existence check when <probe> (one of
# the files it references) does not exist.
function (precisemc_import_unchecked targets_file probe)
  if (NOT EXISTS "${targets_file}" OR EXISTS "${probe}")
    return ()
  endif ()
  get_filename_component(dir "${targets_file}" DIRECTORY)
  get_filename_component(name "${targets_file}" NAME)
  file(READ "${targets_file}" content)
  string(REPLACE "\${CMAKE_CURRENT_LIST_FILE}" "${targets_file}" content "${content}")
  string(REPLACE "\${CMAKE_CURRENT_LIST_DIR}" "${dir}" content "${content}")
  string(REPLACE "# Loop over all imported files and verify that they actually exist"
    "set(_cmake_import_check_targets)" content "${content}")
  set(copy "${CMAKE_BINARY_DIR}/paraview-unchecked/${name}")
  file(WRITE "${copy}" "${content}")
  include("${copy}")
  message(STATUS "Imported ${name} without checking its files (missing: ${probe})")
endfunction ()

# Finds ParaView's CMake package (ParaView_DIR or the usual places) and
# imports the target files that reference python3-paraview's files.
function (precisemc_prepare_paraview_python)
  find_path(PRECISEMC_PARAVIEW_CONFIG_DIR
    NAMES paraview-config.cmake
    HINTS "${ParaView_DIR}"
    PATH_SUFFIXES
      "lib/${CMAKE_LIBRARY_ARCHITECTURE}/cmake/paraview-5.11"
      "lib/cmake/paraview-5.11"
    DOC "Folder of ParaView's CMake package")
  if (NOT PRECISEMC_PARAVIEW_CONFIG_DIR)
    return ()
  endif ()
  # <prefix>/lib/<arch>/cmake/paraview-5.11 or <prefix>/lib/cmake/paraview-5.11
  get_filename_component(prefix "${PRECISEMC_PARAVIEW_CONFIG_DIR}" DIRECTORY)
  get_filename_component(prefix "${prefix}" DIRECTORY)
  get_filename_component(prefix "${prefix}" DIRECTORY)
  if (NOT EXISTS "${prefix}/include/paraview-5.11")
    get_filename_component(prefix "${prefix}" DIRECTORY)
  endif ()
  set(site "${prefix}/lib/python3/dist-packages")
  precisemc_import_unchecked(
    "${PRECISEMC_PARAVIEW_CONFIG_DIR}/vtk/VTKPython-targets.cmake"
    "${site}/vtkmodules/vtkCommonCore.so")
  precisemc_import_unchecked(
    "${PRECISEMC_PARAVIEW_CONFIG_DIR}/ParaViewPython-targets.cmake"
    "${site}/paraview/modules/vtkRemotingCore.so")
  precisemc_import_unchecked(
    "${PRECISEMC_PARAVIEW_CONFIG_DIR}/ParaViewTools-targets.cmake"
    "${prefix}/bin/pvpython")
endfunction ()

# The wrapping hierarchy files of ParaView's modules (read by the
# client-server wrapping of the plugin's module) are also in
# python3-paraview. When they are missing, the module targets are pointed at
# the copies under <root>, a folder where python3-paraview was unpacked
# (`dpkg -x python3-paraview_*.deb <root>`; tests/paraview/run.sh does that
# in build/paraview-root).
function (precisemc_relocate_hierarchies root)
  get_property(targets DIRECTORY PROPERTY IMPORTED_TARGETS)
  set(count 0)
  set(missing 0)
  foreach (target IN LISTS targets)
    get_property(file TARGET "${target}" PROPERTY INTERFACE_vtk_module_hierarchy)
    if (NOT file OR EXISTS "${file}")
      continue ()
    endif ()
    string(REGEX REPLACE "^/" "" relative "${file}")
    if (root AND EXISTS "${root}/${relative}")
      set_property(TARGET "${target}" PROPERTY INTERFACE_vtk_module_hierarchy "${root}/${relative}")
      math(EXPR count "${count} + 1")
    else ()
      math(EXPR missing "${missing} + 1")
    endif ()
  endforeach ()
  if (count)
    message(STATUS "Wrapping hierarchies of ${count} ParaView modules taken from ${root}")
  endif ()
  if (missing)
    message(FATAL_ERROR "${missing} wrapping hierarchy files of ParaView's modules are missing "
      "(they come with python3-paraview): unpack that package into a folder and pass it as "
      "PRECISEMC_PARAVIEW_ROOT")
  endif ()
endfunction ()
