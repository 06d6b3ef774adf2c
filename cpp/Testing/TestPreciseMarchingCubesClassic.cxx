/*=========================================================================

  Program:   PreciseMC
  Module:    TestPreciseMarchingCubesClassic.cxx

  With the classic topology and refinement off (Epsilon 0),
  vtkPreciseMarchingCubes must produce the surface of vtkMarchingCubes:
  the same points (matched by position), the same triangles with the same
  winding, the same normals (central differences) and the same scalars.
  Checked on the wavelet source, a sampled sphere and random volumes of
  every scalar type, with several contour values, extents not starting at
  0, anisotropic spacing and a component of a multi-component array.

=========================================================================*/
#include "vtkPreciseMarchingCubes.h"

#include "PreciseMCTestUtilities.h"

#include "vtkImageExtractComponents.h"
#include "vtkMarchingCubes.h"
#include "vtkRTAnalyticSource.h"
#include "vtkSampleFunction.h"
#include "vtkSphere.h"

#include <cstdlib>
#include <limits>

namespace
{

vtkIdType TotalPoints = 0;
vtkIdType TotalTriangles = 0;
int Cases = 0;

// Runs both filters on `image` with `values` and compares them. The value
// stored in our scalars is the contour value cast to the input type.
bool RunCase(const std::string& name, vtkImageData* image, const std::vector<double>& values,
  bool compareNormals, int component = 0, vtkImageData* reference = nullptr)
{
  vtkNew<vtkMarchingCubes> mc;
  mc->SetInputData(reference ? reference : image);
  mc->ComputeNormalsOn();
  mc->ComputeScalarsOn();
  vtkNew<vtkPreciseMarchingCubes> pmc;
  pmc->SetInputData(image);
  pmc->SetTopologyToClassic();
  pmc->SetEpsilon(0.0);
  pmc->ComputeNormalsOn();
  pmc->SetNormalModeToCentralDifference();
  pmc->ComputeScalarsOn();
  pmc->SetArrayComponent(component);
  pmc->SetOutputPointsPrecision(vtkAlgorithm::DOUBLE_PRECISION);
  for (size_t i = 0; i < values.size(); ++i)
  {
    mc->SetValue(static_cast<int>(i), values[i]);
    pmc->SetValue(static_cast<int>(i), values[i]);
  }
  mc->Update();
  pmc->Update();
  vtkPolyData* ref = mc->GetOutput();
  vtkPolyData* ours = pmc->GetOutput();

  // Reference points are float: allow their rounding on top of 1e-6 cell.
  const double* spacing = image->GetSpacing();
  double cell = std::min(std::fabs(spacing[0]), std::min(std::fabs(spacing[1]), std::fabs(spacing[2])));
  double tol = 1e-6 * cell + 4.0 * std::numeric_limits<float>::epsilon() * pmctest::MaxAbsCoordinate(ref);

  // For integer inputs our scalars hold the value cast to the input type:
  // compare with a tolerance of 1 there.
  bool integral = image->GetPointData()->GetScalars()->GetDataType() != VTK_FLOAT &&
    image->GetPointData()->GetScalars()->GetDataType() != VTK_DOUBLE;
  pmctest::Comparison cmp =
    pmctest::CompareMeshes(ours, ref, tol, compareNormals, 2e-5, values.size() == 1 || !integral,
      integral ? 1.0 : 1e-6 * (1.0 + std::fabs(values[0])));
  ++Cases;
  if (!cmp.Ok || ref->GetNumberOfPolys() == 0)
  {
    std::cerr << "FAIL " << name << ": "
              << (cmp.Ok ? std::string("empty reference surface") : cmp.Message) << "\n";
    return false;
  }
  if (pmc->GetNumberOfRefinedTriangles() != static_cast<vtkTypeUInt64>(ours->GetNumberOfPolys()) ||
    pmc->GetNumberOfMCTriangles() != pmc->GetNumberOfRefinedTriangles() ||
    pmc->GetMaxLevelReached() != 0)
  {
    std::cerr << "FAIL " << name << ": inconsistent statistics\n";
    return false;
  }
  TotalPoints += cmp.Points;
  TotalTriangles += cmp.Triangles;
  std::cout << "ok " << name << ": " << cmp.Points << " points, " << cmp.Triangles
            << " triangles, max point distance " << cmp.MaxPointDistance
            << ", max normal difference " << cmp.MaxNormalDifference << "\n";
  return true;
}

} // anonymous namespace

int main(int, char*[])
{
  bool ok = true;

  // The wavelet: float scalars, extent [-10, 10]^3.
  {
    vtkNew<vtkRTAnalyticSource> wavelet;
    wavelet->SetWholeExtent(-10, 10, -10, 10, -10, 10);
    wavelet->Update();
    vtkImageData* image = wavelet->GetOutput();
    for (double v : { 80.0, 130.0, 160.0, 200.0, 250.0 })
    {
      ok &= RunCase("wavelet iso " + std::to_string(v), image, { v }, true);
    }
    ok &= RunCase("wavelet 3 values", image, { 100.0, 150.0, 220.0 }, true);

    // The same data with an origin and anisotropic spacing.
    vtkNew<vtkImageData> moved;
    moved->DeepCopy(image);
    moved->SetOrigin(1.5, -2.25, 3.0);
    moved->SetSpacing(0.5, 0.75, 1.25);
    ok &= RunCase("wavelet origin + anisotropic spacing", moved, { 150.0 }, true);
  }

  // A sampled sphere (double scalars), isotropic spacing.
  {
    vtkNew<vtkSphere> sphere;
    sphere->SetRadius(0.6);
    sphere->SetCenter(0.03, -0.05, 0.02);
    vtkNew<vtkSampleFunction> sample;
    sample->SetImplicitFunction(sphere);
    sample->SetModelBounds(-1, 1, -1, 1, -1, 1);
    sample->SetSampleDimensions(33, 33, 33);
    sample->ComputeNormalsOff();
    sample->Update();
    ok &= RunCase("sphere", sample->GetOutput(), { 0.0 }, true);
    ok &= RunCase("sphere 2 values", sample->GetOutput(), { -0.2, 0.1 }, true);
  }

  // Random volumes of every scalar type. Integer samples in [lo, hi) with
  // half-integer contour values, so that no sample equals a value.
  {
    struct TypeCase
    {
      int Type;
      double Lo, Hi, Iso;
    };
    const TypeCase types[] = {
      { VTK_CHAR, -60, 60, 0.5 },
      { VTK_SIGNED_CHAR, -100, 100, -10.5 },
      { VTK_UNSIGNED_CHAR, 0, 250, 100.5 },
      { VTK_SHORT, -3000, 3000, 100.5 },
      { VTK_UNSIGNED_SHORT, 0, 60000, 30000.5 },
      { VTK_INT, -100000, 100000, 0.5 },
      { VTK_UNSIGNED_INT, 0, 100000, 50000.5 },
      { VTK_LONG, -100000, 100000, 0.5 },
      { VTK_UNSIGNED_LONG, 0, 100000, 50000.5 },
      { VTK_LONG_LONG, -100000, 100000, 0.5 },
      { VTK_UNSIGNED_LONG_LONG, 0, 100000, 50000.5 },
      { VTK_ID_TYPE, -1000, 1000, 0.5 },
      { VTK_FLOAT, -1, 1, 0.1 },
      { VTK_DOUBLE, -1, 1, -0.1 },
    };
    const int dims[3] = { 17, 13, 11 };
    int seed = 1;
    for (const TypeCase& t : types)
    {
      auto image = pmctest::RandomVolume(t.Type, dims, t.Lo, t.Hi, seed++);
      std::string name = std::string("random ") + image->GetPointData()->GetScalars()->GetDataTypeAsString();
      ok &= RunCase(name, image, { t.Iso }, true);
    }

    // Extent not starting at 0, with an origin.
    auto image = pmctest::RandomVolume(VTK_FLOAT, dims, 0, 1, 99);
    image->SetExtent(5, 5 + dims[0] - 1, -7, -7 + dims[1] - 1, 100, 100 + dims[2] - 1);
    image->SetOrigin(0.25, 0.5, -3.0);
    ok &= RunCase("random float, extent (5,-7,100)", image, { 0.5 }, true);

    // Component 1 of a 3-component array, against vtkMarchingCubes on the
    // extracted component.
    auto multi = pmctest::RandomVolume(VTK_SHORT, dims, -500, 500, 7, 3);
    vtkNew<vtkImageExtractComponents> extract;
    extract->SetInputData(multi);
    extract->SetComponents(1);
    extract->Update();
    ok &= RunCase("random short, component 1 of 3", multi, { 20.5 }, true, 1, extract->GetOutput());
  }

  std::cout << Cases << " cases, " << TotalPoints << " points and " << TotalTriangles
            << " triangles equal to vtkMarchingCubes\n";
  return ok ? EXIT_SUCCESS : EXIT_FAILURE;
}
