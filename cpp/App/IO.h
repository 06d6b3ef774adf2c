// Volume input and surface output of the precisemc tool, through VTK's
// readers and writers chosen by file extension.
#ifndef precisemc_app_IO_h
#define precisemc_app_IO_h

#include "vtkSmartPointer.h"

#include <string>
#include <vector>

class vtkDataArray;
class vtkImageData;
class vtkPolyData;

namespace pmcapp
{

// Reads a 3D volume with point scalars (the active scalars, else the
// first point array): .vti, .vtk, .mha, .mhd, .nii, .nii.gz, .nrrd, .nhdr,
// or a DICOM series when path is a directory. Throws pmcapp::Error with
// the reason (missing, unknown format, unreadable, not a 3D volume, no
// scalars). `array` names the point array to contour ("" for the default).
// What the volume's file gives but the tool cannot apply is appended to
// `warnings`, one sentence each (a DICOM series' patient position and
// orientation). `range` receives FiniteRange() of the scalars contoured
// (as read, NIfTI scaling applied), which the caller reuses: one pass over
// the samples, not one per use.
vtkSmartPointer<vtkImageData> ReadVolume(const std::string& path, const std::string& array,
  std::vector<std::string>& warnings, double range[2]);

// The smallest and largest finite value of component 0 of `scalars`, in
// one pass (range[0] > range[1] when none is finite). VTK 9.1's
// GetFiniteRange starts its minimum at 1e+299: with every value above it
// the minimum came out as 1e+299.
void FiniteRange(vtkDataArray* scalars, double range[2]);

// "48x48x20, unsigned char" for the table (", array 'p'" after it when the
// volume has several point arrays).
std::string DescribeVolume(vtkImageData* volume);

// Throws pmcapp::Error (status 2) unless path has a surface extension
// (.vtp, .ply, .stl, .obj).
void CheckSurfaceFormat(const std::string& path);

// Writes the surface in the format of path's extension into file, the
// temporary of path (PendingFiles::Add), which the caller renames onto
// path; warns on stderr unless quiet. Throws pmcapp::Error.
void WriteSurface(
  vtkPolyData* surface, const std::string& path, const std::string& file, bool quiet);

}

#endif
