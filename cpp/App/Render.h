// Off-screen pictures of the precisemc tool: --compare and --distance.
#ifndef precisemc_app_Render_h
#define precisemc_app_Render_h

#include "vtkSmartPointer.h"

#include <string>
#include <vector>

class vtkImageData;
class vtkPolyData;

namespace pmcapp
{

// One data set in a picture.
struct Panel
{
  std::string Name;                     // "tube", or the input file name
  vtkSmartPointer<vtkImageData> Volume; // the input volume
  vtkSmartPointer<vtkPolyData> MC;      // vtkMarchingCubes's surface (world coordinates)
  unsigned long long MCDropped = 0;     // its triangles dropped: non-finite points
  vtkSmartPointer<vtkPolyData> Refined; // PreciseMC's surface (world coordinates)
  std::string RefinedLabel;             // e.g. "PreciseMC (eps 0.01, level <= 5)"

  // Filled by ComputeDistance(): MC coloured by its distance to Refined.
  vtkSmartPointer<vtkPolyData> Distance;
  double MaxDistance = 0.0;
  double MeanDistance = 0.0;
  long long Unmeasured = 0; // MC points with no finite distance, not in the two
};

// vtkMarchingCubes on component 0 of the volume's scalars (the one
// PreciseMC contours) at the given values, in the same world coordinates
// as vtkPreciseMarchingCubes (direction matrix applied). Its triangles
// with a non-finite point (next to NaN samples) are dropped, and counted
// in *dropped when given. Throws pmcapp::Error on a VTK error.
vtkSmartPointer<vtkPolyData> RunMarchingCubes(vtkImageData* volume,
  const std::vector<double>& values, unsigned long long* dropped = nullptr);

// Distance of every MC point to the refined surface, in cell units (index
// space of the volume): fills panel.Distance, MaxDistance, MeanDistance
// and Unmeasured.
void ComputeDistance(Panel& panel);

// Renders MC (left) beside the refined surface (right), one row per
// panel, into file, the temporary of the PNG png (PendingFiles::Add).
// Throws pmcapp::Error.
void RenderCompare(
  const std::vector<Panel>& panels, const std::string& png, const std::string& file);

// Renders each panel's MC surface coloured by Distance, with a colour bar,
// into file, the temporary of the PNG png. Throws pmcapp::Error.
void RenderDistance(
  const std::vector<Panel>& panels, const std::string& png, const std::string& file);

}

#endif
