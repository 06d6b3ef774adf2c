// Contours VTK's analytic source with the filter found through the
// package; exits 0 when the surface is closed and refined.
#include <vtkPreciseMarchingCubes.h>
#include <vtkPolyData.h>
#include <vtkRTAnalyticSource.h>
#include <vtkSmartPointer.h>

#include <cstdio>

int main()
{
  auto source = vtkSmartPointer<vtkRTAnalyticSource>::New();
  source->SetWholeExtent(-12, 12, -12, 12, -12, 12);
  auto filter = vtkSmartPointer<vtkPreciseMarchingCubes>::New();
  filter->SetInputConnection(source->GetOutputPort());
  filter->SetValue(0, 200.0);
  filter->Update();
  vtkPolyData* out = filter->GetOutput();
  std::printf("%lld triangles (%llu from Marching Cubes)\n",
    static_cast<long long>(out->GetNumberOfPolys()),
    static_cast<unsigned long long>(filter->GetNumberOfMCTriangles()));
  return out->GetNumberOfPolys() > static_cast<vtkIdType>(filter->GetNumberOfMCTriangles()) &&
      filter->GetNumberOfMCTriangles() > 0
    ? 0
    : 1;
}
