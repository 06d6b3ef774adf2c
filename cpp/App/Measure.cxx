// --measure: maps a VTK surface back to the index frame of its volume and
// calls pmc_measure_distance of the PreciseMC C API.
#include "Measure.h"

#include "Common.h"

#include "precisemc.h"
#include "vtkPreciseMarchingCubes.h"

#include "vtkCellArray.h"
#include "vtkCellArrayIterator.h"
#include "vtkDataArray.h"
#include "vtkImageData.h"
#include "vtkMatrix3x3.h"
#include "vtkPointData.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkSmartPointer.h"

#include <memory>
#include <string>
#include <vector>

namespace pmcapp
{

namespace
{

// The library's message of its last failure on this thread, "" if none.
std::string LastLibraryError()
{
  size_t size = pmc_last_error_message(nullptr, 0);
  if (size == 0)
  {
    return std::string();
  }
  std::vector<char> text(size + 1, '\0');
  pmc_last_error_message(text.data(), text.size());
  return std::string(text.data());
}

}

Distance MeasureDistance(
  vtkImageData* volume, double value, vtkPolyData* surface, unsigned density, unsigned threads)
{
  vtkDataArray* scalars = volume->GetPointData()->GetScalars();
  if (!scalars)
  {
    throw Error("--measure: the volume has no point scalars");
  }
  const int type = vtkPreciseMarchingCubes::LibraryScalarType(scalars->GetDataType());
  if (type < 0)
  {
    throw Error(std::string("--measure: unsupported scalar type ") +
      scalars->GetDataTypeAsString());
  }
  vtkSmartPointer<vtkDataArray> contiguous = scalars;
  if (!scalars->HasStandardMemoryLayout())
  {
    contiguous =
      vtkSmartPointer<vtkDataArray>::Take(vtkDataArray::CreateDataArray(scalars->GetDataType()));
    contiguous->DeepCopy(scalars);
  }
  const int comps = contiguous->GetNumberOfComponents();
  int dims[3], extent[6];
  volume->GetDimensions(dims);
  volume->GetExtent(extent);

  // The measure works in the index frame of the samples: origin 0, spacing
  // 1, so the distances come out in cells.
  pmc_volume v = pmc_volume(); // zeroed, then struct_size first
  v.struct_size = sizeof(v);
  v.data = contiguous->GetVoidPointer(0);
  v.len = static_cast<uint64_t>(contiguous->GetNumberOfValues());
  v.scalar_type = static_cast<pmc_scalar_type>(type);
  for (int i = 0; i < 3; ++i)
  {
    v.dims[i] = static_cast<uint64_t>(dims[i]);
    v.origin[i] = 0.0;
    v.spacing[i] = 1.0;
  }
  v.strides[0] = comps;
  v.strides[1] = static_cast<int64_t>(comps) * dims[0];
  v.strides[2] = static_cast<int64_t>(comps) * dims[0] * dims[1];

  // world -> index: index_i = sum_j D[j][i] (w_j - o_j) / s_i - extent_min_i
  // (the direction matrix is orthonormal for a valid image; VTK places
  // sample index q at origin + D (spacing * q)).
  double origin[3], spacing[3];
  volume->GetOrigin(origin);
  volume->GetSpacing(spacing);
  vtkMatrix3x3* d = volume->GetDirectionMatrix();
  double inverse[3][3];
  vtkMatrix3x3::Invert(d->GetData(), &inverse[0][0]);

  Distance result;
  vtkPoints* points = surface ? surface->GetPoints() : nullptr;
  vtkCellArray* polys = surface ? surface->GetPolys() : nullptr;
  if (!points || !polys || polys->GetNumberOfCells() == 0)
  {
    return result;
  }
  const vtkIdType np = points->GetNumberOfPoints();
  std::vector<double> xyz(3 * static_cast<size_t>(np));
  for (vtkIdType p = 0; p < np; ++p)
  {
    double w[3];
    points->GetPoint(p, w);
    double r[3] = { w[0] - origin[0], w[1] - origin[1], w[2] - origin[2] };
    for (int i = 0; i < 3; ++i)
    {
      double local = inverse[i][0] * r[0] + inverse[i][1] * r[1] + inverse[i][2] * r[2];
      xyz[3 * p + i] = local / spacing[i] - extent[2 * i];
    }
  }

  std::vector<int64_t> tris;
  tris.reserve(3 * static_cast<size_t>(polys->GetNumberOfCells()));
  auto it = vtk::TakeSmartPointer(polys->NewIterator());
  for (it->GoToFirstCell(); !it->IsDoneWithTraversal(); it->GoToNextCell())
  {
    vtkIdType n;
    const vtkIdType* ids;
    it->GetCurrentCell(n, ids);
    if (n < 3)
    {
      continue;
    }
    // Polygons are fanned into triangles (the contour filters give
    // triangles only).
    for (vtkIdType k = 1; k + 1 < n; ++k)
    {
      tris.push_back(ids[0]);
      tris.push_back(ids[k]);
      tris.push_back(ids[k + 1]);
    }
  }
  result.Triangles = tris.size() / 3;
  if (tris.empty())
  {
    return result;
  }
  pmc_distance out = pmc_distance();
  out.struct_size = sizeof(out);
  std::unique_ptr<pmc_measure_options, void (*)(pmc_measure_options*)> settings(
    pmc_measure_options_new(), pmc_measure_options_free);
  pmc_status status = settings ? PMC_STATUS_OK : PMC_STATUS_INTERNAL_ERROR;
  if (status == PMC_STATUS_OK)
  {
    status = pmc_measure_options_set_density(settings.get(), density);
  }
  if (status == PMC_STATUS_OK)
  {
    status = pmc_measure_options_set_threads(settings.get(), threads);
  }
  if (status == PMC_STATUS_OK)
  {
    status = pmc_measure(&v, value, xyz.data(), static_cast<uint64_t>(np), tris.data(),
      static_cast<uint64_t>(tris.size() / 3), settings.get(), &out);
  }
  if (status != PMC_STATUS_OK)
  {
    std::string why = LastLibraryError();
    throw Error(std::string("--measure: pmc_measure failed: ") + pmc_status_string(status) +
      (why.empty() ? std::string() : " (" + why + ")"));
  }
  result.Max = out.max;
  result.Mean = out.mean;
  result.Samples = out.samples;
  result.Unresolved = out.unresolved;
  return result;
}

}
