// --measure: the distance of a surface to the trilinear isosurface S_K of
// the volume, measured by the PreciseMC core (pmc_measure).
#ifndef precisemc_app_Measure_h
#define precisemc_app_Measure_h

#include <cstdint>

class vtkImageData;
class vtkPolyData;

namespace pmcapp
{

struct Distance
{
  double Max = 0.0;  // cells (index space of the volume)
  double Mean = 0.0; // cells, weighted by triangle area
  uint64_t Samples = 0;
  uint64_t Unresolved = 0;
  uint64_t Triangles = 0; // triangles measured
};

// Measures how far the triangles of `surface` (world coordinates, as VTK
// places the samples of `volume`: origin + direction * (spacing * index),
// whatever the extent and the direction matrix) lie from the isovalue
// `value` of the trilinear interpolant of component 0 of `volume`'s
// scalars, sampling each triangle on a barycentric grid of `density`
// subdivisions per edge, on `threads` threads (0: all cores; --threads).
// Every triangle of `surface` is measured: it must be the surface of
// `value` alone. Throws pmcapp::Error.
Distance MeasureDistance(
  vtkImageData* volume, double value, vtkPolyData* surface, unsigned density, unsigned threads);

}

#endif
