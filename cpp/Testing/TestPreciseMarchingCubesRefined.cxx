/*=========================================================================

  Program:   PreciseMC
  Module:    TestPreciseMarchingCubesRefined.cxx

  Refinement on (default epsilon 0.01, max level 5, rule A1, trilinear
  topology): the surface stays within one cell of vtkMarchingCubes's
  (symmetric point-to-surface distance, vtkImplicitPolyDataDistance), and
  every output vertex, refined ones included, lies on the isosurface of
  the trilinear interpolant: |F(p) - iso| is tiny (own trilinear
  evaluation in index space). Refined vertices are the ones absent from
  the output of the same filter with Epsilon 0; the vertices Marching Cubes
  itself places inside ambiguous cells (trilinear topology) are counted and
  reported separately.

=========================================================================*/
#include "vtkPreciseMarchingCubes.h"

#include "PreciseMCTestUtilities.h"

#include "vtkImageData.h"
#include "vtkImplicitPolyDataDistance.h"
#include "vtkPointData.h"
#include "vtkMarchingCubes.h"
#include "vtkQuadric.h"
#include "vtkRTAnalyticSource.h"
#include "vtkSampleFunction.h"
#include "vtkUnsignedCharArray.h"
#include "vtkCellData.h"

#include <cstdlib>

namespace
{

vtkIdType RefinedVertices = 0;

// Trilinear interpolant of the image's scalars and its gradient (index
// space) at a point given in world coordinates (identity direction).
double Trilinear(vtkImageData* image, const double x[3], double grad[3])
{
  vtkDataArray* s = image->GetPointData()->GetScalars();
  int dims[3], ext[6];
  image->GetDimensions(dims);
  image->GetExtent(ext);
  const double* o = image->GetOrigin();
  const double* h = image->GetSpacing();
  int c[3];
  double r[3];
  for (int d = 0; d < 3; ++d)
  {
    double local = (x[d] - o[d]) / h[d] - ext[2 * d];
    c[d] = std::max(0, std::min(dims[d] - 2, static_cast<int>(std::floor(local))));
    r[d] = local - c[d];
  }
  double v[8];
  for (int k = 0; k < 8; ++k)
  {
    int i = c[0] + (k & 1), j = c[1] + ((k >> 1) & 1), l = c[2] + ((k >> 2) & 1);
    v[k] = s->GetComponent(i + dims[0] * (j + static_cast<vtkIdType>(dims[1]) * l), 0);
  }
  double f = 0.0;
  grad[0] = grad[1] = grad[2] = 0.0;
  for (int k = 0; k < 8; ++k)
  {
    double w[3], dw[3];
    for (int d = 0; d < 3; ++d)
    {
      bool hi = (k >> d) & 1;
      w[d] = hi ? r[d] : 1.0 - r[d];
      dw[d] = hi ? 1.0 : -1.0;
    }
    f += v[k] * w[0] * w[1] * w[2];
    grad[0] += v[k] * dw[0] * w[1] * w[2];
    grad[1] += v[k] * w[0] * dw[1] * w[2];
    grad[2] += v[k] * w[0] * w[1] * dw[2];
  }
  return f;
}

// Largest |distance| from the points of `a` to the surface `b`.
double MaxDistance(vtkPolyData* a, vtkPolyData* b)
{
  vtkNew<vtkImplicitPolyDataDistance> distance;
  distance->SetInput(b);
  double m = 0.0;
  for (vtkIdType i = 0; i < a->GetNumberOfPoints(); ++i)
  {
    double x[3];
    a->GetPoint(i, x);
    m = std::max(m, std::fabs(distance->EvaluateFunction(x)));
  }
  return m;
}

bool RunCase(const std::string& name, vtkImageData* image, double iso, int topology)
{
  vtkNew<vtkMarchingCubes> mc;
  mc->SetInputData(image);
  mc->SetValue(0, iso);
  mc->ComputeNormalsOff();
  mc->Update();
  vtkNew<vtkPreciseMarchingCubes> pmc;
  pmc->SetInputData(image);
  pmc->SetValue(0, iso);
  pmc->SetTopology(topology);
  pmc->ComputeLevelsOn();
  pmc->SetOutputPointsPrecision(vtkAlgorithm::DOUBLE_PRECISION);
  pmc->Update();
  vtkPolyData* ours = pmc->GetOutput();
  vtkPolyData* ref = mc->GetOutput();

  const double* h = image->GetSpacing();
  const double cell = std::max(h[0], std::max(h[1], h[2]));
  const double d1 = MaxDistance(ours, ref) / cell;
  const double d2 = MaxDistance(ref, ours) / cell;

  // The same filter without refinement gives the Marching Cubes vertices.
  vtkNew<vtkPreciseMarchingCubes> plain;
  plain->SetInputData(image);
  plain->SetValue(0, iso);
  plain->SetTopology(topology);
  plain->SetEpsilon(0.0);
  plain->ComputeNormalsOff();
  plain->SetOutputPointsPrecision(vtkAlgorithm::DOUBLE_PRECISION);
  plain->Update();
  vtkNew<vtkStaticPointLocator> mcPoints;
  mcPoints->SetDataSet(plain->GetOutput());
  mcPoints->BuildLocator();

  // Every refined vertex on the trilinear isosurface.
  double range[2];
  image->GetPointData()->GetScalars()->GetRange(range);
  const double scale = std::max(1.0, std::max(std::fabs(range[0]), std::fabs(range[1])));
  double worstRefined = 0.0, worstMC = 0.0;
  vtkIdType refined = 0, mcOff = 0;
  for (vtkIdType i = 0; i < ours->GetNumberOfPoints(); ++i)
  {
    double x[3], g[3], y[3];
    ours->GetPoint(i, x);
    const double err = std::fabs(Trilinear(image, x, g) - iso) / scale;
    vtkIdType j = mcPoints->FindClosestPoint(x);
    plain->GetOutput()->GetPoint(j, y);
    if (vtkMath::Distance2BetweenPoints(x, y) > 1e-20)
    {
      ++refined;
      worstRefined = std::max(worstRefined, err);
    }
    else
    {
      worstMC = std::max(worstMC, err);
      mcOff += err > 1e-9 ? 1 : 0;
    }
  }
  RefinedVertices += refined;
  vtkUnsignedCharArray* levels =
    vtkUnsignedCharArray::SafeDownCast(ours->GetCellData()->GetArray("RefinementLevel"));
  bool levelsOk = levels && levels->GetNumberOfTuples() == ours->GetNumberOfPolys();
  int maxLevel = 0;
  if (levelsOk)
  {
    for (vtkIdType i = 0; i < levels->GetNumberOfTuples(); ++i)
    {
      maxLevel = std::max(maxLevel, static_cast<int>(levels->GetValue(i)));
    }
  }

  // The distance bound: one cell (the diagonal of a cell in ambiguous
  // random data, where the topologies differ).
  const double bound = 1.0;
  const bool ok = d1 <= bound && d2 <= bound && worstRefined < 1e-9 && levelsOk &&
    maxLevel == pmc->GetMaxLevelReached() && (maxLevel > 0) == (refined > 0) &&
    (topology == vtkPreciseMarchingCubes::TOPOLOGY_TRILINEAR || mcOff == 0) &&
    ours->GetNumberOfPolys() == static_cast<vtkIdType>(pmc->GetNumberOfRefinedTriangles());
  std::cout << (ok ? "ok " : "FAIL ") << name << ": " << pmc->GetNumberOfMCTriangles()
            << " MC -> " << pmc->GetNumberOfRefinedTriangles() << " triangles, "
            << ours->GetNumberOfPoints() << " points (" << refined << " refined), "
            << "max level " << pmc->GetMaxLevelReached() << ", mean level "
            << pmc->GetMeanLevel() << ", projection failures "
            << pmc->GetNumberOfProjectionFailures() << "; distance to vtkMarchingCubes "
            << d1 << " / " << d2 << " cells; max |F - iso| / range: refined vertices "
            << worstRefined << ", Marching Cubes vertices " << worstMC << " (" << mcOff
            << " interior vertices of ambiguous cells off the surface)\n";
  return ok;
}

} // anonymous namespace

int main(int, char*[])
{
  bool ok = true;
  {
    vtkNew<vtkRTAnalyticSource> wavelet;
    wavelet->SetWholeExtent(-12, 12, -12, 12, -12, 12);
    wavelet->Update();
    for (double iso : { 100.0, 160.0, 220.0 })
    {
      ok &= RunCase("wavelet iso " + std::to_string(iso), wavelet->GetOutput(), iso,
        vtkPreciseMarchingCubes::TOPOLOGY_TRILINEAR);
    }
    ok &= RunCase("wavelet iso 160 classic", wavelet->GetOutput(), 160.0,
      vtkPreciseMarchingCubes::TOPOLOGY_CLASSIC);
  }
  {
    // A tilted ellipsoid: the cross terms make the trilinear isosurface
    // curved inside the cells (a sampled sphere x^2 + y^2 + z^2 would be
    // planar in every cell and need no refinement).
    vtkNew<vtkQuadric> quadric;
    quadric->SetCoefficients(1.0, 2.0, 1.5, 0.9, 0.4, -0.3, 0.1, 0.0, -0.1, -0.45);
    vtkNew<vtkSampleFunction> sample;
    sample->SetImplicitFunction(quadric);
    sample->SetModelBounds(-1, 1, -1, 1, -1, 1);
    sample->SetSampleDimensions(9, 9, 9);
    sample->ComputeNormalsOff();
    sample->Update();
    ok &= RunCase("coarse tilted ellipsoid", sample->GetOutput(), 0.0,
      vtkPreciseMarchingCubes::TOPOLOGY_TRILINEAR);
  }
  {
    const int dims[3] = { 16, 14, 12 };
    auto image = pmctest::RandomVolume(VTK_FLOAT, dims, 0, 1, 5);
    ok &= RunCase("random float", image, 0.5, vtkPreciseMarchingCubes::TOPOLOGY_TRILINEAR);
    auto bytes = pmctest::RandomVolume(VTK_UNSIGNED_CHAR, dims, 0, 256, 6);
    ok &= RunCase("random unsigned char", bytes, 127.5, vtkPreciseMarchingCubes::TOPOLOGY_TRILINEAR);
  }
  {
    // A cell of a real scan (values less the isovalue, x fastest) where
    // the isosurface folds through a neck at a face's saddle: refinement
    // stalls there and the cell is meshed again on sub-cells, which the
    // statistics report; with refinement off nothing is.
    const double values[8] = { -7.102, 20.898, -106.102, -87.102, 33.898, -77.102, -49.102,
      161.898 };
    vtkNew<vtkImageData> cell;
    cell->SetDimensions(2, 2, 2);
    cell->AllocateScalars(VTK_DOUBLE, 1);
    for (int i = 0; i < 8; ++i)
    {
      cell->GetPointData()->GetScalars()->SetComponent(i, 0, values[i]);
    }
    vtkNew<vtkPreciseMarchingCubes> filter;
    filter->SetInputData(cell);
    filter->SetValue(0, 0.0);
    filter->SetEpsilon(0.01);
    filter->SetMaxLevel(5);
    filter->SetOutputPointsPrecision(vtkAlgorithm::DOUBLE_PRECISION);
    filter->Update();
    vtkPolyData* out = filter->GetOutput();
    double worst = 0.0;
    for (vtkIdType i = 0; i < out->GetNumberOfPoints(); ++i)
    {
      double x[3], g[3];
      out->GetPoint(i, x);
      const double f = Trilinear(cell, x, g);
      worst = std::max(worst, std::fabs(f) / std::sqrt(vtkMath::Dot(g, g)));
    }
    std::cout << "fold cell: " << filter->GetNumberOfCellsOnSubcells() << " cell on sub-cells, "
              << out->GetNumberOfCells() << " triangles, max |F - iso| / |grad F| " << worst << "\n";
    if (filter->GetNumberOfCellsOnSubcells() != 1 || out->GetNumberOfCells() == 0 || worst > 1e-9)
    {
      std::cerr << "FAIL: the fold cell should be meshed again on sub-cells, on the surface\n";
      ok = false;
    }
    filter->SetEpsilon(0.0);
    filter->Update();
    if (filter->GetNumberOfCellsOnSubcells() != 0)
    {
      std::cerr << "FAIL: cells on sub-cells with refinement off\n";
      ok = false;
    }
  }
  std::cout << RefinedVertices << " refined vertices checked on the trilinear isosurface\n";
  if (RefinedVertices == 0)
  {
    std::cerr << "FAIL: nothing was refined\n";
    ok = false;
  }
  return ok ? EXIT_SUCCESS : EXIT_FAILURE;
}
