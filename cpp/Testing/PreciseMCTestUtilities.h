/*=========================================================================

  Program:   PreciseMC
  Module:    PreciseMCTestUtilities.h

  Helpers shared by the C++ tests: test volumes, an error observer and the
  comparison of two triangle meshes (points matched by position, triangles
  compared as sets of rotated triples, normals and scalars per point).

=========================================================================*/
#ifndef PreciseMCTestUtilities_h
#define PreciseMCTestUtilities_h

#include "vtkCellArray.h"
#include "vtkCommand.h"
#include "vtkDataArray.h"
#include "vtkIdList.h"
#include "vtkImageData.h"
#include "vtkMath.h"
#include "vtkMinimalStandardRandomSequence.h"
#include "vtkNew.h"
#include "vtkPointData.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkSmartPointer.h"
#include "vtkStaticPointLocator.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace pmctest
{

/// Counts (and silences) error and warning events of an object.
class ErrorObserver : public vtkCommand
{
public:
  static ErrorObserver* New() { return new ErrorObserver; }
  void Execute(vtkObject*, unsigned long event, void* callData) override
  {
    if (event == vtkCommand::ErrorEvent)
    {
      ++this->Errors;
      // Keep the text after the "ClassName (0x...): " prefix.
      this->LastMessage = callData ? static_cast<const char*>(callData) : "";
      size_t pos = this->LastMessage.find("): ");
      if (pos != std::string::npos)
      {
        this->LastMessage = this->LastMessage.substr(pos + 3);
      }
    }
    else if (event == vtkCommand::WarningEvent)
    {
      ++this->Warnings;
    }
  }
  void Reset()
  {
    this->Errors = 0;
    this->Warnings = 0;
    this->LastMessage.clear();
  }
  int Errors = 0;
  int Warnings = 0;
  std::string LastMessage;
};

/// A random volume of the given VTK type, values uniform in [lo, hi).
inline vtkSmartPointer<vtkImageData> RandomVolume(
  int type, const int dims[3], double lo, double hi, int seed, int components = 1)
{
  auto image = vtkSmartPointer<vtkImageData>::New();
  image->SetDimensions(dims[0], dims[1], dims[2]);
  auto array = vtkSmartPointer<vtkDataArray>::Take(vtkDataArray::CreateDataArray(type));
  array->SetName("random");
  array->SetNumberOfComponents(components);
  array->SetNumberOfTuples(image->GetNumberOfPoints());
  vtkNew<vtkMinimalStandardRandomSequence> random;
  random->SetSeed(seed);
  for (vtkIdType i = 0; i < array->GetNumberOfValues(); ++i)
  {
    double v = random->GetRangeValue(lo, hi);
    random->Next();
    if (type != VTK_FLOAT && type != VTK_DOUBLE)
    {
      v = std::floor(v);
    }
    array->SetComponent(i / components, static_cast<int>(i % components), v);
  }
  image->GetPointData()->SetScalars(array);
  return image;
}

/// Result of comparing two meshes.
struct Comparison
{
  bool Ok = true;
  vtkIdType Points = 0;
  vtkIdType Triangles = 0;
  double MaxPointDistance = 0.0;
  double MaxNormalDifference = 0.0;
  std::string Message;
};

using Triple = std::array<vtkIdType, 3>;

/// Rotate a triangle so its smallest id comes first (keeps the winding).
inline Triple Canonical(vtkIdType a, vtkIdType b, vtkIdType c)
{
  if (a <= b && a <= c)
  {
    return Triple{ { a, b, c } };
  }
  if (b <= a && b <= c)
  {
    return Triple{ { b, c, a } };
  }
  return Triple{ { c, a, b } };
}

/// Compares `ours` with `ref`: same number of points, each point of ours
/// within `tolerance` of a distinct point of ref, the same triangles with
/// the same winding, and (when asked) the same normals within
/// `normalTolerance` and the same scalars.
inline Comparison CompareMeshes(vtkPolyData* ours, vtkPolyData* ref, double tolerance,
  bool compareNormals, double normalTolerance, bool compareScalars, double scalarTolerance = 0.0)
{
  Comparison result;
  std::ostringstream msg;
  const vtkIdType n = ours->GetNumberOfPoints();
  result.Points = n;
  result.Triangles = ours->GetNumberOfPolys();
  if (n != ref->GetNumberOfPoints())
  {
    msg << "point count " << n << " != reference " << ref->GetNumberOfPoints();
    result.Ok = false;
    result.Message = msg.str();
    return result;
  }
  if (ours->GetNumberOfPolys() != ref->GetNumberOfPolys())
  {
    msg << "triangle count " << ours->GetNumberOfPolys() << " != reference "
        << ref->GetNumberOfPolys();
    result.Ok = false;
    result.Message = msg.str();
    return result;
  }
  std::vector<vtkIdType> map(static_cast<size_t>(n), -1);
  if (n > 0)
  {
    vtkNew<vtkStaticPointLocator> locator;
    locator->SetDataSet(ref);
    locator->BuildLocator();
    std::vector<char> used(static_cast<size_t>(n), 0);
    for (vtkIdType i = 0; i < n; ++i)
    {
      double x[3], y[3];
      ours->GetPoint(i, x);
      vtkIdType j = locator->FindClosestPoint(x);
      ref->GetPoint(j, y);
      double d = std::sqrt(vtkMath::Distance2BetweenPoints(x, y));
      result.MaxPointDistance = std::max(result.MaxPointDistance, d);
      if (d > tolerance)
      {
        msg << "point " << i << " (" << x[0] << ", " << x[1] << ", " << x[2]
            << ") has no reference point within " << tolerance << " (closest at " << d << ")";
        result.Ok = false;
        result.Message = msg.str();
        return result;
      }
      if (used[j])
      {
        msg << "reference point " << j << " matched twice";
        result.Ok = false;
        result.Message = msg.str();
        return result;
      }
      used[j] = 1;
      map[i] = j;
    }
  }

  // Triangles as sorted lists of rotated triples in reference ids.
  std::vector<Triple> a, b;
  vtkIdType npts;
  const vtkIdType* pts;
  vtkCellArray* polys = ours->GetPolys();
  for (polys->InitTraversal(); polys->GetNextCell(npts, pts);)
  {
    if (npts != 3)
    {
      result.Ok = false;
      result.Message = "non-triangle cell in output";
      return result;
    }
    a.push_back(Canonical(map[pts[0]], map[pts[1]], map[pts[2]]));
  }
  polys = ref->GetPolys();
  for (polys->InitTraversal(); polys->GetNextCell(npts, pts);)
  {
    b.push_back(Canonical(pts[0], pts[1], pts[2]));
  }
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  if (a != b)
  {
    size_t differ = 0;
    for (size_t i = 0; i < a.size(); ++i)
    {
      if (!std::binary_search(b.begin(), b.end(), a[i]))
      {
        ++differ;
      }
    }
    msg << differ << " of " << a.size() << " triangles differ (ids or winding)";
    result.Ok = false;
    result.Message = msg.str();
    return result;
  }

  if (compareNormals)
  {
    vtkDataArray* na = ours->GetPointData()->GetNormals();
    vtkDataArray* nb = ref->GetPointData()->GetNormals();
    if (!na || !nb)
    {
      result.Ok = false;
      result.Message = "missing normals";
      return result;
    }
    for (vtkIdType i = 0; i < n; ++i)
    {
      double u[3], v[3];
      na->GetTuple(i, u);
      nb->GetTuple(map[i], v);
      double d = std::sqrt(vtkMath::Distance2BetweenPoints(u, v));
      result.MaxNormalDifference = std::max(result.MaxNormalDifference, d);
      if (d > normalTolerance)
      {
        msg << "normal of point " << i << " (" << u[0] << ", " << u[1] << ", " << u[2]
            << ") != reference (" << v[0] << ", " << v[1] << ", " << v[2] << ")";
        result.Ok = false;
        result.Message = msg.str();
        return result;
      }
    }
  }

  if (compareScalars)
  {
    vtkDataArray* sa = ours->GetPointData()->GetScalars();
    vtkDataArray* sb = ref->GetPointData()->GetScalars();
    if (!sa || !sb)
    {
      result.Ok = false;
      result.Message = "missing scalars";
      return result;
    }
    for (vtkIdType i = 0; i < n; ++i)
    {
      double u = sa->GetComponent(i, 0);
      double v = sb->GetComponent(map[i], 0);
      if (std::fabs(u - v) > scalarTolerance)
      {
        msg << "scalar of point " << i << ": " << u << " != reference " << v;
        result.Ok = false;
        result.Message = msg.str();
        return result;
      }
    }
  }
  return result;
}

/// Largest coordinate magnitude of a data set's bounds.
inline double MaxAbsCoordinate(vtkDataSet* ds)
{
  double b[6];
  ds->GetBounds(b);
  double m = 0.0;
  for (double v : b)
  {
    m = std::max(m, std::fabs(v));
  }
  return m;
}

} // namespace pmctest

#endif
