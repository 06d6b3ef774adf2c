// Off-screen pictures: vtkMarchingCubes beside PreciseMC (--compare) and
// the MC surface coloured by its distance to the refined one (--distance).
#include "Render.h"

#include "Common.h"

#include "vtkActor.h"
#include "vtkCamera.h"
#include "vtkCellArray.h"
#include "vtkCellData.h"
#include "vtkColorTransferFunction.h"
#include "vtkDataArray.h"
#include "vtkDistancePolyDataFilter.h"
#include "vtkDoubleArray.h"
#include "vtkImageData.h"
#include "vtkImageExtractComponents.h"
#include "vtkLightKit.h"
#include "vtkMarchingCubes.h"
#include "vtkMatrix3x3.h"
#include "vtkMatrix4x4.h"
#include "vtkNew.h"
#include "vtkPNGWriter.h"
#include "vtkPointData.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkPolyDataMapper.h"
#include "vtkProperty.h"
#include "vtkRenderWindow.h"
#include "vtkRenderer.h"
#include "vtkScalarBarActor.h"
#include "vtkTextActor.h"
#include "vtkTextProperty.h"
#include "vtkTransform.h"
#include "vtkTransformPolyDataFilter.h"
#include "vtkWindowToImageFilter.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace pmcapp
{
namespace
{

const double SurfaceColor[3] = { 0.90, 0.82, 0.66 };
const double EdgeColor[3] = { 0.22, 0.20, 0.26 };
const double TextColor[3] = { 0.10, 0.10, 0.14 };
const double Background[3] = { 1.0, 1.0, 1.0 };
const double Background2[3] = { 0.80, 0.84, 0.90 };

vtkIdType CountTriangles(vtkPolyData* pd)
{
  return pd ? pd->GetNumberOfPolys() : 0;
}

// world -> index space of the volume (cell units).
vtkSmartPointer<vtkMatrix4x4> WorldToIndex(vtkImageData* image)
{
  auto m = vtkSmartPointer<vtkMatrix4x4>::New();
  double origin[3], spacing[3];
  image->GetOrigin(origin);
  image->GetSpacing(spacing);
  vtkMatrix3x3* d = image->GetDirectionMatrix();
  // index_i = sum_j D[j][i] (w_j - o_j) / s_i
  for (int i = 0; i < 3; ++i)
  {
    double t = 0.0;
    for (int j = 0; j < 3; ++j)
    {
      double a = d->GetElement(j, i) / spacing[i];
      m->SetElement(i, j, a);
      t -= a * origin[j];
    }
    m->SetElement(i, 3, t);
  }
  return m;
}

vtkSmartPointer<vtkPolyData> Transformed(vtkPolyData* input, vtkMatrix4x4* matrix)
{
  vtkNew<vtkTransform> transform;
  transform->SetMatrix(matrix);
  vtkNew<vtkTransformPolyDataFilter> filter;
  filter->SetInputData(input);
  filter->SetTransform(transform);
  filter->Update();
  auto out = vtkSmartPointer<vtkPolyData>::New();
  out->ShallowCopy(filter->GetOutput());
  return out;
}

void AddText(vtkRenderer* renderer, const std::string& text, double x, double y, int size,
  int hjust, bool top, bool bold = false)
{
  vtkNew<vtkTextActor> actor;
  actor->SetInput(text.c_str());
  actor->SetTextScaleModeToNone();
  actor->GetPositionCoordinate()->SetCoordinateSystemToNormalizedViewport();
  actor->SetPosition(x, y);
  vtkTextProperty* p = actor->GetTextProperty();
  p->SetFontSize(size);
  p->SetColor(TextColor[0], TextColor[1], TextColor[2]);
  p->SetBold(bold);
  p->SetFontFamilyToArial();
  if (hjust == 0)
  {
    p->SetJustificationToLeft();
  }
  else if (hjust == 1)
  {
    p->SetJustificationToCentered();
  }
  else
  {
    p->SetJustificationToRight();
  }
  if (top)
  {
    p->SetVerticalJustificationToTop();
  }
  else
  {
    p->SetVerticalJustificationToBottom();
  }
  renderer->AddActor2D(actor);
}

vtkSmartPointer<vtkRenderer> NewRenderer(double x0, double y0, double x1, double y1)
{
  auto renderer = vtkSmartPointer<vtkRenderer>::New();
  renderer->SetViewport(x0, y0, x1, y1);
  renderer->SetBackground(Background[0], Background[1], Background[2]);
  renderer->SetBackground2(Background2[0], Background2[1], Background2[2]);
  renderer->GradientBackgroundOn();
  renderer->UseFXAAOn();
  vtkNew<vtkLightKit> lights;
  lights->AddLightsToRenderer(renderer);
  return renderer;
}

vtkSmartPointer<vtkActor> SurfaceActor(vtkPolyData* pd, bool edges)
{
  vtkNew<vtkPolyDataMapper> mapper;
  mapper->SetInputData(pd);
  mapper->ScalarVisibilityOff();
  auto actor = vtkSmartPointer<vtkActor>::New();
  actor->SetMapper(mapper);
  vtkProperty* p = actor->GetProperty();
  p->SetColor(SurfaceColor[0], SurfaceColor[1], SurfaceColor[2]);
  p->SetInterpolationToFlat();
  p->SetAmbient(0.15);
  p->SetDiffuse(0.8);
  p->SetSpecular(0.15);
  p->SetSpecularPower(30.0);
  p->BackfaceCullingOff();
  if (edges)
  {
    p->EdgeVisibilityOn();
    p->SetEdgeColor(EdgeColor[0], EdgeColor[1], EdgeColor[2]);
    p->SetLineWidth(1.0);
  }
  return actor;
}

// A three-quarter view of the bounds of the data.
void FrameCamera(vtkRenderer* renderer, vtkPolyData* pd, vtkImageData* volume)
{
  double bounds[6];
  if (pd && pd->GetNumberOfPoints() > 0)
  {
    pd->GetBounds(bounds);
  }
  else
  {
    volume->GetBounds(bounds);
  }
  vtkCamera* camera = renderer->GetActiveCamera();
  double center[3] = { 0.5 * (bounds[0] + bounds[1]), 0.5 * (bounds[2] + bounds[3]),
    0.5 * (bounds[4] + bounds[5]) };
  camera->SetFocalPoint(center);
  camera->SetPosition(center[0], center[1] - 1.0, center[2]);
  camera->SetViewUp(0.0, 0.0, 1.0);
  camera->Azimuth(-35.0);
  camera->Elevation(35.0);
  camera->OrthogonalizeViewUp();
  // ResetCamera fits the bounding sphere: a little zoom fills the view
  // without cropping elongated shapes.
  renderer->ResetCamera(bounds);
  camera->Zoom(1.1);
}

// The window is rendered off screen and saved into file, the temporary
// of png.
void SavePNG(vtkRenderWindow* window, const std::string& png, const std::string& file)
{
  window->Render();
  vtkNew<vtkWindowToImageFilter> grab;
  grab->SetInput(window);
  grab->SetInputBufferTypeToRGB();
  grab->ReadFrontBufferOff();
  grab->Update();
  TakeVTKErrors();
  vtkNew<vtkPNGWriter> writer;
  writer->SetInputConnection(grab->GetOutputPort());
  writer->SetFileName(file.c_str());
  {
    // libpng reports a failed write on stderr as well as to VTK.
    StderrSilenced silenced;
    writer->Write();
  }
  std::vector<std::string> errors = TakeVTKErrors();
  if (writer->GetErrorCode() != 0 || !errors.empty() || !IsRegularFile(file))
  {
    RemoveFile(file);
    throw Error("cannot write picture '" + png + "'" +
      (errors.empty() ? std::string() : ": " + ForUser(errors.front(), file, png)));
  }
}

// Each triangle split into n x n triangles (points not shared between
// triangles: only the geometry is used).
vtkSmartPointer<vtkPolyData> Subdivided(vtkPolyData* input, int n)
{
  auto points = vtkSmartPointer<vtkPoints>::New();
  points->SetDataTypeToDouble();
  auto polys = vtkSmartPointer<vtkCellArray>::New();
  const vtkIdType perTriangle = static_cast<vtkIdType>(n + 1) * (n + 2) / 2;
  vtkCellArray* cells = input->GetPolys();
  points->Allocate(cells->GetNumberOfCells() * perTriangle);
  vtkIdType npts;
  const vtkIdType* ids;
  for (cells->InitTraversal(); cells->GetNextCell(npts, ids);)
  {
    if (npts != 3)
    {
      continue;
    }
    double p[3][3];
    for (int c = 0; c < 3; ++c)
    {
      input->GetPoint(ids[c], p[c]);
    }
    // Point (i, j) = p0 + i/n (p1 - p0) + j/n (p2 - p0), i + j <= n.
    std::vector<vtkIdType> grid;
    for (int j = 0; j <= n; ++j)
    {
      for (int i = 0; i + j <= n; ++i)
      {
        double a = static_cast<double>(i) / n, b = static_cast<double>(j) / n;
        double q[3];
        for (int c = 0; c < 3; ++c)
        {
          q[c] = p[0][c] + a * (p[1][c] - p[0][c]) + b * (p[2][c] - p[0][c]);
        }
        grid.push_back(points->InsertNextPoint(q));
      }
    }
    // Row j starts at offset(j) and holds n - j + 1 points.
    auto at = [n, &grid](int i, int j) {
      int offset = j * (n + 1) - j * (j - 1) / 2;
      return grid[offset + i];
    };
    for (int j = 0; j < n; ++j)
    {
      for (int i = 0; i + j < n; ++i)
      {
        vtkIdType t[3] = { at(i, j), at(i + 1, j), at(i, j + 1) };
        polys->InsertNextCell(3, t);
        if (i + j + 1 < n)
        {
          vtkIdType u[3] = { at(i + 1, j), at(i + 1, j + 1), at(i, j + 1) };
          polys->InsertNextCell(3, u);
        }
      }
    }
  }
  auto out = vtkSmartPointer<vtkPolyData>::New();
  out->SetPoints(points);
  out->SetPolys(polys);
  return out;
}

// Whether the cell holding world point `x` of the axis-aligned `volume`
// has a non-finite corner in component 0 of `values` (float or double, of
// `components` components).
template <class T>
bool CellHasNonFinite(vtkImageData* volume, const T* values, int components, const double x[3])
{
  int extent[6];
  volume->GetExtent(extent);
  const double* origin = volume->GetOrigin();
  const double* spacing = volume->GetSpacing();
  vtkIdType corner[3];
  vtkIdType dims[3];
  for (int a = 0; a < 3; ++a)
  {
    dims[a] = static_cast<vtkIdType>(extent[2 * a + 1]) - extent[2 * a] + 1;
    const double u = (x[a] - origin[a]) / spacing[a] - extent[2 * a];
    const double last = static_cast<double>(std::max<vtkIdType>(dims[a] - 2, 0));
    corner[a] = static_cast<vtkIdType>(std::min(std::max(std::floor(u), 0.0), last));
  }
  for (int c = 0; c < 8; ++c)
  {
    const vtkIdType i = std::min(corner[0] + (c & 1), dims[0] - 1);
    const vtkIdType j = std::min(corner[1] + ((c >> 1) & 1), dims[1] - 1);
    const vtkIdType k = std::min(corner[2] + ((c >> 2) & 1), dims[2] - 1);
    if (!std::isfinite(values[(i + dims[0] * (j + dims[1] * k)) * components]))
    {
      return true;
    }
  }
  return false;
}

// Whether component 0 of `count` tuples of `components` values holds a
// NaN or an infinity.
template <class T>
bool AnyNonFinite(const T* values, vtkIdType count, int components)
{
  for (vtkIdType t = 0; t < count; ++t)
  {
    if (!std::isfinite(values[t * components]))
    {
      return true;
    }
  }
  return false;
}

// vtkMarchingCubes contours cells with NaN or infinite samples too, which
// gives NaN points, or finite ones pulled to a corner (inf): its triangles
// in such cells, or using a non-finite point, are dropped (PreciseMC skips
// the cells with non-finite samples), so that the pictures and the
// measures see the same cells on both sides. Returns how many.
unsigned long long DropNonFiniteTriangles(vtkPolyData* pd, vtkImageData* volume)
{
  vtkPoints* points = pd->GetPoints();
  vtkCellArray* polys = pd->GetPolys();
  if (!points || !polys)
  {
    return 0;
  }
  const vtkIdType np = points->GetNumberOfPoints();
  std::vector<char> finite(static_cast<size_t>(np));
  bool all = true;
  for (vtkIdType p = 0; p < np; ++p)
  {
    double x[3];
    points->GetPoint(p, x);
    finite[p] = std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2]);
    all = all && finite[p];
  }
  // Only floating-point samples can be non-finite.
  vtkDataArray* scalars = volume->GetPointData()->GetScalars();
  const int type = scalars ? scalars->GetDataType() : VTK_VOID;
  const bool isFloat = type == VTK_FLOAT;
  const int components = scalars ? scalars->GetNumberOfComponents() : 1;
  const void* values =
    (isFloat || type == VTK_DOUBLE) ? scalars->GetVoidPointer(0) : nullptr;
  const vtkIdType count = values ? scalars->GetNumberOfTuples() : 0;
  const bool anyNonFinite = isFloat
    ? AnyNonFinite(static_cast<const float*>(values), count, components)
    : AnyNonFinite(static_cast<const double*>(values), count, components);
  if (all && !anyNonFinite)
  {
    return 0;
  }
  auto inBadCell = [&](vtkIdType n, const vtkIdType* ids) {
    if (!anyNonFinite)
    {
      return false;
    }
    // The centroid of a Marching Cubes triangle lies in its cell.
    double c[3] = { 0.0, 0.0, 0.0 };
    for (vtkIdType k = 0; k < n; ++k)
    {
      double x[3];
      points->GetPoint(ids[k], x);
      for (int a = 0; a < 3; ++a)
      {
        c[a] += x[a] / static_cast<double>(n);
      }
    }
    return isFloat
      ? CellHasNonFinite(volume, static_cast<const float*>(values), components, c)
      : CellHasNonFinite(volume, static_cast<const double*>(values), components, c);
  };
  // The kept points are renumbered in order, with their point data.
  vtkPointData* inPD = pd->GetPointData();
  vtkNew<vtkPointData> outPD;
  outPD->CopyAllocate(inPD);
  auto newPoints = vtkSmartPointer<vtkPoints>::New();
  newPoints->SetDataType(points->GetDataType());
  auto newPolys = vtkSmartPointer<vtkCellArray>::New();
  std::vector<vtkIdType> renumbered(static_cast<size_t>(np), -1);
  std::vector<vtkIdType> cell;
  unsigned long long dropped = 0;
  vtkIdType n;
  const vtkIdType* ids;
  for (polys->InitTraversal(); polys->GetNextCell(n, ids);)
  {
    bool keep = true;
    for (vtkIdType k = 0; k < n && keep; ++k)
    {
      keep = finite[ids[k]] != 0;
    }
    if (!keep || inBadCell(n, ids))
    {
      ++dropped;
      continue;
    }
    cell.resize(static_cast<size_t>(n));
    for (vtkIdType k = 0; k < n; ++k)
    {
      vtkIdType& id = renumbered[ids[k]];
      if (id < 0)
      {
        id = newPoints->InsertNextPoint(points->GetPoint(ids[k]));
        outPD->CopyData(inPD, ids[k], id);
      }
      cell[k] = id;
    }
    newPolys->InsertNextCell(n, cell.data());
  }
  pd->SetPoints(newPoints);
  pd->GetPointData()->ShallowCopy(outPD);
  pd->SetPolys(newPolys);
  return dropped;
}

bool ShowEdges(vtkIdType triangles, int width, int height)
{
  // Edges help while triangles are large on screen; on dense meshes they
  // only darken the surface (the shape is what the refined side shows).
  return triangles > 0 && triangles * 40 < static_cast<vtkIdType>(width) * height;
}

}

vtkSmartPointer<vtkPolyData> RunMarchingCubes(
  vtkImageData* volume, const std::vector<double>& values, unsigned long long* dropped)
{
  // Some VTK versions apply the direction matrix in vtkMarchingCubes (9.1
  // does), others not: contour an axis-aligned copy and apply the matrix
  // here, like the PreciseMC filter does, so that it is applied once.
  vtkNew<vtkImageData> aligned;
  aligned->ShallowCopy(volume);
  aligned->SetDirectionMatrix(1, 0, 0, 0, 1, 0, 0, 0, 1);
  vtkNew<vtkMarchingCubes> mc;
  // vtkMarchingCubes takes single-component scalars only: it is given
  // component 0, the one PreciseMC contours.
  vtkDataArray* scalars = volume->GetPointData()->GetScalars();
  vtkNew<vtkImageExtractComponents> component0;
  if (scalars && scalars->GetNumberOfComponents() > 1)
  {
    component0->SetInputData(aligned);
    component0->SetComponents(0);
    mc->SetInputConnection(component0->GetOutputPort());
  }
  else
  {
    mc->SetInputData(aligned);
  }
  for (size_t i = 0; i < values.size(); ++i)
  {
    mc->SetValue(static_cast<int>(i), values[i]);
  }
  mc->ComputeNormalsOn();
  mc->ComputeScalarsOff();
  mc->ComputeGradientsOff();
  TakeVTKErrors();
  mc->Update();
  std::vector<std::string> errors = TakeVTKErrors();
  if (!errors.empty())
  {
    throw Error("vtkMarchingCubes: " + errors.front());
  }
  auto out = vtkSmartPointer<vtkPolyData>::New();
  out->ShallowCopy(mc->GetOutput());
  unsigned long long removed = DropNonFiniteTriangles(out, aligned);
  if (dropped)
  {
    *dropped = removed;
  }

  // p' = origin + D (p - origin).
  vtkMatrix3x3* d = volume->GetDirectionMatrix();
  if (!d->IsIdentity())
  {
    double origin[3];
    volume->GetOrigin(origin);
    vtkNew<vtkMatrix4x4> m;
    for (int i = 0; i < 3; ++i)
    {
      double t = origin[i];
      for (int j = 0; j < 3; ++j)
      {
        m->SetElement(i, j, d->GetElement(i, j));
        t -= d->GetElement(i, j) * origin[j];
      }
      m->SetElement(i, 3, t);
    }
    out = Transformed(out, m);
  }
  return out;
}

void ComputeDistance(Panel& panel)
{
  // The MC vertices lie on cell edges, where the linear interpolation of
  // Marching Cubes is exact: they are on the refined surface too. The
  // error of MC is inside its triangles, so they are measured there.
  auto result = Subdivided(panel.MC, 3);
  vtkIdType n = result->GetNumberOfPoints();
  vtkNew<vtkDoubleArray> distance;
  distance->SetName("DistanceToRefined");
  distance->SetNumberOfTuples(n);
  distance->Fill(0.0);
  panel.MaxDistance = 0.0;
  panel.MeanDistance = 0.0;
  panel.Unmeasured = 0;
  if (n > 0 && CountTriangles(panel.Refined) > 0)
  {
    auto toIndex = WorldToIndex(panel.Volume);
    auto mcIndex = Transformed(result, toIndex);
    auto refinedIndex = Transformed(panel.Refined, toIndex);
    // Only the geometry matters.
    mcIndex->GetPointData()->Initialize();
    refinedIndex->GetPointData()->Initialize();
    refinedIndex->GetCellData()->Initialize();
    vtkNew<vtkDistancePolyDataFilter> filter;
    filter->SetInputData(0, mcIndex);
    filter->SetInputData(1, refinedIndex);
    filter->SignedDistanceOff();
    filter->ComputeSecondDistanceOff();
    filter->NegateDistanceOff();
    filter->Update();
    vtkDataArray* d = filter->GetOutput()->GetPointData()->GetArray("Distance");
    if (d && d->GetNumberOfTuples() == n)
    {
      // A distance the filter could not compute (NaN, on degenerate
      // triangles) is counted apart, not averaged: one made the mean NaN.
      double sum = 0.0;
      vtkIdType measured = 0;
      for (vtkIdType i = 0; i < n; ++i)
      {
        double v = std::fabs(d->GetTuple1(i));
        distance->SetValue(i, v);
        if (!std::isfinite(v))
        {
          ++panel.Unmeasured;
          continue;
        }
        sum += v;
        ++measured;
        panel.MaxDistance = std::max(panel.MaxDistance, v);
      }
      panel.MeanDistance = measured > 0 ? sum / static_cast<double>(measured) : 0.0;
    }
  }
  result->GetPointData()->AddArray(distance);
  result->GetPointData()->SetActiveScalars("DistanceToRefined");
  panel.Distance = result;
}

void RenderCompare(
  const std::vector<Panel>& panels, const std::string& png, const std::string& file)
{
  const int rows = static_cast<int>(panels.size());
  const int width = 1600;
  const int rowHeight = rows == 1 ? 800 : 560;
  const int height = rowHeight * rows;
  vtkNew<vtkRenderWindow> window;
  window->SetOffScreenRendering(1);
  window->SetSize(width, height);
  window->SetMultiSamples(0);
  window->SetWindowName("precisemc --compare");

  for (int r = 0; r < rows; ++r)
  {
    const Panel& panel = panels[r];
    double y0 = 1.0 - static_cast<double>(r + 1) / rows;
    double y1 = 1.0 - static_cast<double>(r) / rows;
    auto left = NewRenderer(0.0, y0, 0.5, y1);
    auto right = NewRenderer(0.5, y0, 1.0, y1);
    vtkIdType mcTriangles = CountTriangles(panel.MC);
    vtkIdType refinedTriangles = CountTriangles(panel.Refined);
    int pixels = width / 2;
    left->AddActor(SurfaceActor(panel.MC, ShowEdges(mcTriangles, pixels, rowHeight)));
    right->AddActor(SurfaceActor(panel.Refined, ShowEdges(refinedTriangles, pixels, rowHeight)));
    FrameCamera(right, panel.Refined, panel.Volume);
    left->SetActiveCamera(right->GetActiveCamera());

    int titleSize = rows == 1 ? 24 : 20;
    AddText(left, "vtkMarchingCubes: " + Grouped(mcTriangles) + " triangles", 0.5, 0.975,
      titleSize, 1, true, true);
    AddText(right, panel.RefinedLabel + ": " + Grouped(refinedTriangles) + " triangles", 0.5,
      0.975, titleSize, 1, true, true);
    AddText(left, panel.Name, 0.02, 0.02, titleSize - 2, 0, false);
    window->AddRenderer(left);
    window->AddRenderer(right);
  }
  SavePNG(window, png, file);
}

void RenderDistance(
  const std::vector<Panel>& panels, const std::string& png, const std::string& file)
{
  const int cols = static_cast<int>(panels.size());
  const int width = cols == 1 ? 1000 : 1800;
  const int height = cols == 1 ? 860 : 760;
  vtkNew<vtkRenderWindow> window;
  window->SetOffScreenRendering(1);
  window->SetSize(width, height);
  window->SetMultiSamples(0);
  window->SetWindowName("precisemc --distance");

  for (int c = 0; c < cols; ++c)
  {
    const Panel& panel = panels[c];
    auto renderer = NewRenderer(static_cast<double>(c) / cols, 0.0,
      static_cast<double>(c + 1) / cols, 1.0);
    double top = panel.MaxDistance > 0.0 ? panel.MaxDistance : 1e-3;

    // Dark blue (on the refined surface) to yellow (farthest), perceptually
    // ordered like viridis/plasma.
    vtkNew<vtkColorTransferFunction> colors;
    colors->SetColorSpaceToLab();
    colors->AddRGBPoint(0.0 * top, 0.050, 0.030, 0.530);
    colors->AddRGBPoint(0.25 * top, 0.420, 0.000, 0.660);
    colors->AddRGBPoint(0.50 * top, 0.720, 0.200, 0.470);
    colors->AddRGBPoint(0.75 * top, 0.930, 0.470, 0.240);
    colors->AddRGBPoint(1.0 * top, 0.940, 0.970, 0.130);

    vtkNew<vtkPolyDataMapper> mapper;
    mapper->SetInputData(panel.Distance);
    mapper->SetLookupTable(colors);
    mapper->SetScalarModeToUsePointFieldData();
    mapper->SelectColorArray("DistanceToRefined");
    mapper->SetScalarRange(0.0, top);
    mapper->ScalarVisibilityOn();
    mapper->InterpolateScalarsBeforeMappingOn();
    vtkNew<vtkActor> actor;
    actor->SetMapper(mapper);
    actor->GetProperty()->SetAmbient(0.2);
    actor->GetProperty()->SetDiffuse(0.8);
    actor->GetProperty()->SetSpecular(0.1);
    renderer->AddActor(actor);
    FrameCamera(renderer, panel.Distance, panel.Volume);
    renderer->GetActiveCamera()->Zoom(0.85);

    vtkNew<vtkScalarBarActor> bar;
    bar->SetLookupTable(colors);
    bar->SetOrientationToHorizontal();
    bar->SetTitle("distance to refined surface (cells)");
    bar->SetNumberOfLabels(5);
    bar->SetLabelFormat(top < 0.1 ? "%.3f" : "%.2f");
    bar->GetPositionCoordinate()->SetCoordinateSystemToNormalizedViewport();
    bar->SetPosition(0.12, 0.02);
    bar->SetWidth(0.76);
    bar->SetHeight(0.13);
    bar->SetBarRatio(0.3);
    bar->UnconstrainedFontSizeOn();
    for (vtkTextProperty* p : { bar->GetTitleTextProperty(), bar->GetLabelTextProperty() })
    {
      p->SetColor(TextColor[0], TextColor[1], TextColor[2]);
      p->SetFontFamilyToArial();
      p->ShadowOff();
      p->ItalicOff();
      p->SetFontSize(16);
    }
    bar->GetTitleTextProperty()->BoldOn();
    renderer->AddActor2D(bar);

    // Short lines: with three panels side by side long titles overlap.
    AddText(renderer, panel.Name, 0.5, 0.975, 20, 1, true, true);
    AddText(renderer,
      "vtkMarchingCubes to " + panel.RefinedLabel + ":\nmax " + Fixed(panel.MaxDistance, 3) +
        ", mean " + Fixed(panel.MeanDistance, 3) + " cells",
      0.5, 0.93, 16, 1, true);
    window->AddRenderer(renderer);
  }
  SavePNG(window, png, file);
}

}
