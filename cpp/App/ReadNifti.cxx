// The checks of a NIfTI header (.nii, .nii.gz) before VTK's reader sees
// it, and its scaling and world frame applied after the read.
#include "ReadNifti.h"

#include "ReadChecks.h"

#include "vtkDataArray.h"
#include "vtkDoubleArray.h"
#include "vtkFloatArray.h"
#include "vtkImageData.h"
#include "vtkMatrix4x4.h"
#include "vtkNIFTIImageHeader.h"
#include "vtkNIFTIImageReader.h"
#include "vtkPointData.h"
#include "vtkSmartPointer.h"
#include "vtk_zlib.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>

namespace pmcapp
{
namespace
{

template <class In, class Out>
void ScaleValues(const In* in, Out* out, vtkIdType n, double slope, double intercept)
{
  for (vtkIdType i = 0; i < n; ++i)
  {
    out[i] = static_cast<Out>(static_cast<double>(in[i]) * slope + intercept);
  }
}

}

// NIfTI: the sform (or else the qform) maps VTK's data coordinates
// (origin + spacing * index, as the reader laid the samples out) to the
// world; the reader leaves it out of the image.
void ApplyNiftiFrame(vtkImageData* volume, const std::string& path, vtkNIFTIImageReader* reader)
{
  vtkNIFTIImageHeader* header = reader->GetNIFTIHeader();
  vtkMatrix4x4* m = nullptr;
  if (header && header->GetSFormCode() > 0)
  {
    m = reader->GetSFormMatrix();
  }
  else if (header && header->GetQFormCode() > 0)
  {
    m = reader->GetQFormMatrix();
  }
  if (!m)
  {
    return;
  }
  double direction[9];
  double spacing[3];
  double local[3];
  double origin[3];
  volume->GetSpacing(spacing);
  volume->GetOrigin(local);
  for (int r = 0; r < 3; ++r)
  {
    origin[r] = m->GetElement(r, 3);
    for (int c = 0; c < 3; ++c)
    {
      direction[3 * r + c] = m->GetElement(r, c);
      origin[r] += m->GetElement(r, c) * local[c];
    }
  }
  SetFrame(volume, path, direction, spacing, origin);
}

// The scalars times NIfTI's scl_slope plus scl_inter, as its standard
// asks (0 or 1 and 0: stored values as they are), in float (double for
// double and for integers wider than 16 bits, which float would round,
// and for values beyond float's range).
void ApplyNiftiScaling(vtkNIFTIImageReader* reader, vtkImageData* volume)
{
  double slope = reader->GetRescaleSlope();
  double intercept = reader->GetRescaleIntercept();
  if (!std::isfinite(slope) || !std::isfinite(intercept) || slope == 0.0 ||
    (slope == 1.0 && intercept == 0.0))
  {
    return;
  }
  vtkDataArray* stored = volume->GetPointData()->GetScalars();
  int type = stored->GetDataType();
  double range[2];
  stored->GetFiniteRange(range, -1);
  double largest = std::max(std::abs(range[0]), std::abs(range[1])) * std::abs(slope) +
    std::abs(intercept);
  bool wide = type == VTK_DOUBLE || vtkDataArray::GetDataTypeSize(type) > 2 || !(largest < 1e37);
  vtkSmartPointer<vtkDataArray> scaled;
  if (wide)
  {
    scaled = vtkSmartPointer<vtkDoubleArray>::New();
  }
  else
  {
    scaled = vtkSmartPointer<vtkFloatArray>::New();
  }
  scaled->SetName(stored->GetName() ? stored->GetName() : "scalars");
  scaled->SetNumberOfComponents(stored->GetNumberOfComponents());
  scaled->SetNumberOfTuples(stored->GetNumberOfTuples());
  const vtkIdType n = stored->GetNumberOfValues();
  void* in = stored->GetVoidPointer(0);
  void* out = scaled->GetVoidPointer(0);
  switch (type)
  {
    vtkTemplateMacro(wide
        ? ScaleValues(static_cast<const VTK_TT*>(in), static_cast<double*>(out), n, slope, intercept)
        : ScaleValues(static_cast<const VTK_TT*>(in), static_cast<float*>(out), n, slope, intercept));
    default:
      Unreadable(reader->GetFileName() ? reader->GetFileName() : "NIfTI file",
        "scalars of an unsupported type cannot take the header's scaling");
  }
  volume->GetPointData()->SetScalars(scaled);
}

// What VTK 9.1's NIfTI reader crashes on or misreads in a NIfTI header,
// refused before it runs. NIfTI-1 (348-byte header) and NIfTI-2 (540),
// either byte order, read through zlib so .nii.gz too; any other header is
// left to the reader.
// - A datatype code that is none that VTK's reader reads: it went on with
//   an unknown code (5, 4096, 12345) and crashed reading the data, or sized
//   it from garbage. The codes are NIfTI-1's that the reader maps to a VTK
//   type (the types of a VTK array: not binary, float128 or complex256).
// - A dimension count outside 1..7 or a used dimension below 1: 0 vector
//   components made the reader divide by zero (SIGFPE).
// - A dimension 6 or 7 (within the count) above 1: the reader ignores
//   them and gave the first of the 3D volumes the header declares.
// - In a single-file .nii, data that starts inside the header (vox_offset
//   below 352, 544 for NIfTI-2): the header's own bytes were read as the
//   first samples.
void CheckNiftiHeader(const std::string& path)
{
  unsigned char head[544] = {};
  gzFile gz = gzopen(path.c_str(), "rb");
  if (!gz)
  {
    return;
  }
  const int got = gzread(gz, head, sizeof(head));
  gzclose(gz);
  const auto number = [&head](int at, int bytes, bool swap) {
    unsigned long long v = 0;
    for (int b = 0; b < bytes; ++b)
    {
      v |= static_cast<unsigned long long>(head[at + (swap ? bytes - 1 - b : b)]) << (8 * b);
    }
    return v;
  };
  int version = 0;
  bool swap = false;
  for (bool s : { false, true })
  {
    const unsigned long long size = number(0, 4, s);
    if (size == 348 || size == 540)
    {
      version = size == 348 ? 1 : 2;
      swap = s;
    }
  }
  if (version == 0 || got < (version == 1 ? 348 : 540))
  {
    return; // the reader speaks of a short or foreign header
  }
  const int code = static_cast<int>(number(version == 1 ? 70 : 12, 2, swap));
  static const std::pair<int, const char*> readable[] = { { 2, "uint8" }, { 4, "int16" },
    { 8, "int32" }, { 16, "float32" }, { 32, "complex64" }, { 64, "float64" }, { 128, "rgb24" },
    { 256, "int8" }, { 512, "uint16" }, { 768, "uint32" }, { 1024, "int64" },
    { 1280, "uint64" }, { 1792, "complex128" }, { 2304, "rgba32" } };
  std::string known;
  bool readableCode = false;
  for (const auto& r : readable)
  {
    readableCode = readableCode || r.first == code;
    known += (known.empty() ? "" : ", ") + std::to_string(r.first) + " " + r.second;
  }
  if (!readableCode)
  {
    Unreadable(path, "its header's datatype code " + std::to_string(code) +
        " is none that VTK's NIfTI reader reads (" + known + ")");
  }
  // dim[0..7]: int16 from byte 40 (NIfTI-1), int64 from byte 16 (NIfTI-2).
  const auto dim = [&](int i) {
    return version == 1 ? static_cast<long long>(static_cast<int16_t>(number(40 + 2 * i, 2, swap)))
                        : static_cast<long long>(number(16 + 8 * i, 8, swap));
  };
  const long long count = dim(0);
  if (count < 1 || count > 7)
  {
    Unreadable(path, "its header gives " + std::to_string(count) +
        " dimensions (dim[0]), not 1 to 7");
  }
  static const char* const names[] = { "", "x", "y", "z", "time points", "vector components",
    "dimension 6", "dimension 7" };
  for (int i = 1; i <= count; ++i)
  {
    if (dim(i) < 1)
    {
      Unreadable(path, "its header gives " + std::to_string(dim(i)) + " " + names[i] +
          " (dim[" + std::to_string(i) + "]): every dimension used holds at least 1");
    }
  }
  // Dimensions 6 and 7 above 1: VTK's reader ignores them and gave the
  // first 3D volume of the many the header declares, exit status 0.
  // (Dimension 5 is read as the samples' vector components, component 0
  // contoured; more than one time point is refused after the read.)
  for (int i = 6; i <= count; ++i)
  {
    if (dim(i) > 1)
    {
      Unreadable(path, "its header declares " + std::to_string(dim(i)) + " along " + names[i] +
          " (dim[" + std::to_string(i) + "]): more than one 3D volume, and VTK's NIfTI reader "
          "ignores dimensions 6 and 7 and would give the first only (write one file per 3D "
          "volume)");
    }
  }
  // The spacing of each spatial axis: pixdim[1..3], float32 from byte 80
  // (NIfTI-1), double from byte 112 (NIfTI-2). VTK's reader takes 0 for 1
  // without a word, where a spacing of 0 is refused in every other format.
  for (int i = 1; i <= std::min<long long>(count, 3); ++i)
  {
    double spacing;
    if (version == 1)
    {
      const uint32_t bits = static_cast<uint32_t>(number(76 + 4 * i, 4, swap));
      float f;
      std::memcpy(&f, &bits, sizeof(f));
      spacing = f;
    }
    else
    {
      const uint64_t bits = number(104 + 8 * i, 8, swap);
      std::memcpy(&spacing, &bits, sizeof(spacing));
    }
    if (spacing == 0.0)
    {
      Unreadable(path, "its header gives a spacing of 0 along axis " + std::to_string(i - 1) +
          " (pixdim[" + std::to_string(i) + "])");
    }
  }
  // A single file ("n+1" or "n+2" magic) holds its data after the header
  // and its 4 extension bytes.
  const bool single = version == 1 ? std::memcmp(head + 344, "n+1", 4) == 0
                                   : std::memcmp(head + 4, "n+2", 4) == 0;
  if (single)
  {
    double offset;
    if (version == 1)
    {
      const uint32_t bits = static_cast<uint32_t>(number(108, 4, swap));
      float f;
      std::memcpy(&f, &bits, sizeof(f));
      offset = f;
    }
    else
    {
      offset = static_cast<double>(static_cast<long long>(number(168, 8, swap)));
    }
    const int least = version == 1 ? 352 : 544;
    if (!(offset >= least))
    {
      char at[32];
      std::snprintf(at, sizeof(at), "%g", offset);
      Unreadable(path, std::string("its header puts the data at byte ") + at +
          " (vox_offset), inside the header, which ends at byte " + std::to_string(least) +
          " in a single .nii file");
    }
  }
}

}
