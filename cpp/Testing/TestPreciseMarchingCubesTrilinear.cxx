/*=========================================================================

  Program:   PreciseMC
  Module:    TestPreciseMarchingCubesTrilinear.cxx

  Trilinear topology, refinement off: the output equals vtkMarchingCubes
  where no cell is ambiguous (a sampled sphere), and on random volumes it
  differs only inside ambiguous cells: cells with an ambiguous face (the
  two diagonals of a face separated) or the body-diagonal case (two
  opposite corners alone on their side). Every triangle present in one
  output and not in the other must lie in such a cell.

=========================================================================*/
#include "vtkPreciseMarchingCubes.h"

#include "PreciseMCTestUtilities.h"

#include "vtkMarchingCubes.h"
#include "vtkSampleFunction.h"
#include "vtkSphere.h"

#include <cstdlib>
#include <iterator>
#include <set>

namespace
{

// Corner c of a cell at (i, j, k): VTK order (x fastest, then y, z) with
// corners 2 and 3 swapped as in vtkMarchingCubes is not needed here; use
// bit order: c = dx + 2 dy + 4 dz.
double Sample(vtkDataArray* s, const int dims[3], int i, int j, int k)
{
  return s->GetComponent(i + dims[0] * (j + static_cast<vtkIdType>(dims[1]) * k), 0);
}

// Whether the cell at (i, j, k) is ambiguous for `iso`.
bool AmbiguousCell(vtkDataArray* s, const int dims[3], int i, int j, int k, double iso)
{
  bool in[8];
  for (int c = 0; c < 8; ++c)
  {
    in[c] = Sample(s, dims, i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)) >= iso;
  }
  // Faces as corner quadruples in cyclic order.
  static const int faces[6][4] = { { 0, 1, 3, 2 }, { 4, 5, 7, 6 }, { 0, 1, 5, 4 },
    { 2, 3, 7, 6 }, { 0, 2, 6, 4 }, { 1, 3, 7, 5 } };
  for (const auto& f : faces)
  {
    if (in[f[0]] == in[f[2]] && in[f[1]] == in[f[3]] && in[f[0]] != in[f[1]])
    {
      return true;
    }
  }
  // Body diagonal: exactly two opposite corners on one side.
  int count = 0;
  for (bool b : in)
  {
    count += b ? 1 : 0;
  }
  if (count == 2 || count == 6)
  {
    bool minority = count == 2;
    for (int c = 0; c < 4; ++c)
    {
      if (in[c] == minority && in[7 - c] == minority)
      {
        return true;
      }
    }
  }
  return false;
}

using Tri = std::array<vtkIdType, 3>;

// Triangles of `pd` as rotated triples (smallest first, winding kept) of
// point ids given by `ids` (identity when empty).
std::vector<Tri> Triangles(vtkPolyData* pd, const std::vector<vtkIdType>& ids)
{
  std::vector<Tri> out;
  vtkIdType npts;
  const vtkIdType* pts;
  vtkCellArray* polys = pd->GetPolys();
  for (polys->InitTraversal(); polys->GetNextCell(npts, pts);)
  {
    Tri t;
    for (int v = 0; v < 3; ++v)
    {
      t[v] = ids.empty() ? pts[v] : ids[pts[v]];
    }
    out.push_back(pmctest::Canonical(t[0], t[1], t[2]));
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Ids of the points of `ours` in `ref` (same position within `tol`), or
// fresh ids above ref's range for points ref does not have.
std::vector<vtkIdType> MatchPoints(vtkPolyData* ours, vtkPolyData* ref, double tol)
{
  std::vector<vtkIdType> ids(static_cast<size_t>(ours->GetNumberOfPoints()));
  vtkNew<vtkStaticPointLocator> locator;
  locator->SetDataSet(ref);
  locator->BuildLocator();
  vtkIdType next = ref->GetNumberOfPoints();
  for (vtkIdType i = 0; i < ours->GetNumberOfPoints(); ++i)
  {
    double x[3], y[3];
    ours->GetPoint(i, x);
    vtkIdType j = ref->GetNumberOfPoints() > 0 ? locator->FindClosestPoint(x) : -1;
    if (j >= 0)
    {
      ref->GetPoint(j, y);
    }
    ids[i] = (j >= 0 && vtkMath::Distance2BetweenPoints(x, y) <= tol * tol) ? j : next++;
  }
  return ids;
}

// Bounding box (index space) of a triangle given by ids in the combined
// numbering: ids below ref's point count are ref points, others ours.
void TriangleBox(const Tri& t, vtkPolyData* ref, const std::vector<double>& extra,
  double mn[3], double mx[3])
{
  for (int d = 0; d < 3; ++d)
  {
    mn[d] = 1e300;
    mx[d] = -1e300;
  }
  for (vtkIdType id : t)
  {
    double x[3];
    if (id < ref->GetNumberOfPoints())
    {
      ref->GetPoint(id, x);
    }
    else
    {
      const size_t e = static_cast<size_t>(id - ref->GetNumberOfPoints());
      x[0] = extra[3 * e];
      x[1] = extra[3 * e + 1];
      x[2] = extra[3 * e + 2];
    }
    for (int d = 0; d < 3; ++d)
    {
      mn[d] = std::min(mn[d], x[d]);
      mx[d] = std::max(mx[d], x[d]);
    }
  }
}

// Whether a triangle with bounding box [mn, mx] lies in a cell flagged
// ambiguous: some cell whose closed box holds the three vertices.
bool InAmbiguousCell(
  const double mn[3], const double mx[3], const std::vector<char>& ambiguous, const int dims[3])
{
  int lo[3], hi[3];
  for (int d = 0; d < 3; ++d)
  {
    // Cells c with c <= mn and mx <= c + 1.
    lo[d] = std::max(0, static_cast<int>(std::ceil(mx[d] - 1.0 - 1e-6)));
    hi[d] = std::min(dims[d] - 2, static_cast<int>(std::floor(mn[d] + 1e-6)));
  }
  for (int k = lo[2]; k <= hi[2]; ++k)
  {
    for (int j = lo[1]; j <= hi[1]; ++j)
    {
      for (int i = lo[0]; i <= hi[0]; ++i)
      {
        if (ambiguous[i + (dims[0] - 1) * (j + static_cast<size_t>(dims[1] - 1) * k)])
        {
          return true;
        }
      }
    }
  }
  return false;
}

} // anonymous namespace

int main(int, char*[])
{
  bool ok = true;

  // A sphere: no ambiguous cell, the output equals vtkMarchingCubes.
  {
    vtkNew<vtkSphere> sphere;
    sphere->SetRadius(0.55);
    vtkNew<vtkSampleFunction> sample;
    sample->SetImplicitFunction(sphere);
    sample->SetModelBounds(-1, 1, -1, 1, -1, 1);
    sample->SetSampleDimensions(31, 31, 31);
    sample->ComputeNormalsOff();
    sample->Update();
    vtkNew<vtkMarchingCubes> mc;
    mc->SetInputConnection(sample->GetOutputPort());
    mc->SetValue(0, 0.0);
    mc->Update();
    vtkNew<vtkPreciseMarchingCubes> pmc;
    pmc->SetInputConnection(sample->GetOutputPort());
    pmc->SetValue(0, 0.0);
    pmc->SetEpsilon(0.0);
    pmc->SetNormalModeToCentralDifference();
    pmc->SetOutputPointsPrecision(vtkAlgorithm::DOUBLE_PRECISION);
    pmc->Update();
    auto cmp = pmctest::CompareMeshes(pmc->GetOutput(), mc->GetOutput(),
      1e-6 * 2.0 / 30 + 1e-7, true, 2e-5, true, 1e-12);
    if (!cmp.Ok || pmc->GetNumberOfAmbiguousCells() != 0)
    {
      std::cerr << "FAIL sphere: " << cmp.Message << " (ambiguous cells "
                << pmc->GetNumberOfAmbiguousCells() << ")\n";
      ok = false;
    }
    else
    {
      std::cout << "ok sphere: " << cmp.Points << " points, " << cmp.Triangles
                << " triangles equal to vtkMarchingCubes, 0 ambiguous cells\n";
    }
  }

  // Random volumes: differences only inside ambiguous cells.
  const int dims[3] = { 24, 21, 19 };
  size_t totalDiff = 0, totalTris = 0, totalAmbiguous = 0;
  for (int seed = 1; seed <= 4; ++seed)
  {
    int type = seed % 2 ? VTK_FLOAT : VTK_UNSIGNED_CHAR;
    double iso = type == VTK_FLOAT ? 0.5 : 127.5;
    auto image = pmctest::RandomVolume(type, dims, 0, type == VTK_FLOAT ? 1 : 256, 100 + seed);
    vtkDataArray* s = image->GetPointData()->GetScalars();
    vtkNew<vtkMarchingCubes> mc;
    mc->SetInputData(image);
    mc->SetValue(0, iso);
    mc->ComputeNormalsOff();
    mc->Update();
    vtkNew<vtkPreciseMarchingCubes> pmc;
    pmc->SetInputData(image);
    pmc->SetValue(0, iso);
    pmc->SetEpsilon(0.0);
    pmc->ComputeNormalsOff();
    pmc->SetOutputPointsPrecision(vtkAlgorithm::DOUBLE_PRECISION);
    pmc->Update();

    std::vector<char> ambiguous(static_cast<size_t>(dims[0] - 1) * (dims[1] - 1) * (dims[2] - 1));
    size_t numAmbiguous = 0;
    for (int k = 0; k < dims[2] - 1; ++k)
    {
      for (int j = 0; j < dims[1] - 1; ++j)
      {
        for (int i = 0; i < dims[0] - 1; ++i)
        {
          bool a = AmbiguousCell(s, dims, i, j, k, iso);
          ambiguous[i + (dims[0] - 1) * (j + static_cast<size_t>(dims[1] - 1) * k)] = a;
          numAmbiguous += a ? 1 : 0;
        }
      }
    }

    vtkPolyData* refPd = mc->GetOutput();
    vtkPolyData* ourPd = pmc->GetOutput();
    std::vector<vtkIdType> ids = MatchPoints(ourPd, refPd, 1e-5);
    std::vector<double> extra;
    for (vtkIdType i = 0; i < ourPd->GetNumberOfPoints(); ++i)
    {
      if (ids[i] >= refPd->GetNumberOfPoints())
      {
        double x[3];
        ourPd->GetPoint(i, x);
        extra.insert(extra.end(), x, x + 3);
      }
    }
    auto ours = Triangles(ourPd, ids);
    auto ref = Triangles(refPd, std::vector<vtkIdType>());
    std::vector<Tri> onlyOurs, onlyRef;
    std::set_difference(
      ours.begin(), ours.end(), ref.begin(), ref.end(), std::back_inserter(onlyOurs));
    std::set_difference(
      ref.begin(), ref.end(), ours.begin(), ours.end(), std::back_inserter(onlyRef));
    size_t outside = 0;
    for (const auto* list : { &onlyOurs, &onlyRef })
    {
      for (const Tri& t : *list)
      {
        double mn[3], mx[3];
        TriangleBox(t, refPd, extra, mn, mx);
        if (!InAmbiguousCell(mn, mx, ambiguous, dims))
        {
          if (outside < 5)
          {
            std::cerr << "  differing triangle outside ambiguous cells: box (" << mn[0] << ", "
                      << mn[1] << ", " << mn[2] << ") - (" << mx[0] << ", " << mx[1] << ", "
                      << mx[2] << ")" << (list == &onlyOurs ? " [ours]" : " [vtk]") << "\n";
          }
          ++outside;
        }
      }
    }
    const size_t diff = onlyOurs.size() + onlyRef.size();
    std::cout << (outside == 0 && diff > 0 ? "ok" : "FAIL") << " random "
              << s->GetDataTypeAsString() << " seed " << seed << ": " << ours.size()
              << " triangles (vtkMarchingCubes " << ref.size() << "), " << onlyOurs.size()
              << " only ours + " << onlyRef.size() << " only vtkMarchingCubes, " << outside
              << " of them outside the " << numAmbiguous << " ambiguous cells"
              << " (filter reports " << pmc->GetNumberOfAmbiguousCells() << ")\n";
    if (outside != 0 || diff == 0 || pmc->GetNumberOfAmbiguousCells() == 0 ||
      pmc->GetNumberOfAmbiguousCells() > numAmbiguous)
    {
      ok = false;
    }
    totalDiff += diff;
    totalTris += ours.size();
    totalAmbiguous += numAmbiguous;
  }
  std::cout << totalTris << " triangles checked, " << totalDiff
            << " differing triangles, all inside the " << totalAmbiguous
            << " ambiguous cells\n";
  return ok ? EXIT_SUCCESS : EXIT_FAILURE;
}
