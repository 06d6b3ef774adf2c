// Reading volumes for the precisemc tool: the reader for the file's
// format, that format's checks before it runs (Read*.cxx), and the checks
// of the volume it gives. VTK readers report problems through the output
// window (captured by Common.h) and often still produce an empty image, so
// the result is checked as well.
#include "IO.h"

#include "Common.h"
#include "ReadChecks.h"
#include "ReadDicom.h"
#include "ReadLegacy.h"
#include "ReadMetaImage.h"
#include "ReadNifti.h"
#include "ReadNrrd.h"
#include "ReadVtkXml.h"

#include "vtkAlgorithm.h"
#include "vtkArrayDispatch.h"
#include "vtkDataArray.h"
#include "vtkDataArrayRange.h"
#include "vtkImageData.h"
#include "vtkImageReader2.h"
#include "vtkInformation.h"
#include "vtkMath.h"
#include "vtkMatrix3x3.h"
#include "vtkMetaImageReader.h"
#include "vtkNIFTIImageReader.h"
#include "vtkNrrdReader.h"
#include "vtkPointData.h"
#include "vtkPreciseMarchingCubes.h"
#include "vtkStreamingDemandDrivenPipeline.h"
#include "vtkStructuredPointsReader.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include <sys/stat.h>
#include <unistd.h>

namespace pmcapp
{
namespace
{

const char* const InputExtensions = ".vti, .vtk, .mha, .mhd, .nii, .nii.gz, .nrrd, .nhdr";

// Throws when the volume a reader's header declares (after
// UpdateInformation) needs more bytes than the machine has memory.
void CheckDeclaredSize(vtkAlgorithm* reader, const std::string& path)
{
  vtkInformation* info = reader->GetOutputInformation(0);
  if (!info || !info->Has(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT()))
  {
    return;
  }
  int ext[6];
  info->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), ext);
  double samples = 1.0;
  std::string dims;
  for (int a = 0; a < 3; ++a)
  {
    double n = static_cast<double>(ext[2 * a + 1]) - ext[2 * a] + 1.0;
    if (n < 1.0)
    {
      Unreadable(path, "the header declares an extent with no samples along axis " +
          std::to_string(a) + " (" + std::to_string(ext[2 * a]) + ".." +
          std::to_string(ext[2 * a + 1]) + ")");
    }
    samples *= n;
    dims += (a ? "x" : "") + std::to_string(static_cast<long long>(n));
  }
  int type = vtkImageData::GetScalarType(info);
  int components = std::max(1, vtkImageData::GetNumberOfScalarComponents(info));
  double bytes = samples * components * std::max(1, vtkDataArray::GetDataTypeSize(type));
  long pages = sysconf(_SC_PHYS_PAGES);
  long pageSize = sysconf(_SC_PAGESIZE);
  if (pages <= 0 || pageSize <= 0)
  {
    return;
  }
  double memory = static_cast<double>(pages) * static_cast<double>(pageSize);
  if (bytes > memory)
  {
    const double gib = 1024.0 * 1024.0 * 1024.0;
    char text[160];
    std::snprintf(text, sizeof(text), "%.1f GiB, more than this machine's memory (%.1f GiB)",
      bytes / gib, memory / gib);
    Unreadable(path, "the header declares " + dims + " samples (" + text + ")");
  }
}

// Runs the reader and turns captured VTK errors into an Error.
vtkImageData* RunReader(vtkAlgorithm* reader, const std::string& path)
{
  TakeVTKErrors();
  TakeVTKWarnings();
  std::string stray;
  {
    StderrCapture capture;
    // The header first: a size beyond the machine's memory is refused
    // before any allocation (some readers crash when it fails). A header
    // the reader rejected stops the read: asked for the data anyway,
    // VTK's MetaImage reader read a 4D file's samples past the end of
    // the empty image it had allocated (heap overflow).
    reader->UpdateInformation();
    std::vector<std::string> rejected = TakeVTKErrors();
    if (!rejected.empty())
    {
      std::string why = BestError(rejected);
      Unreadable(path, why.empty() ? "the reader rejected its header" : why);
    }
    CheckDeclaredSize(reader, path);
    reader->Update();
    stray = capture.Text();
  }
  std::vector<std::string> errors = TakeVTKErrors();
  // MetaIO reports truncated data on std::cerr only.
  if (!stray.empty())
  {
    errors.push_back(stray);
  }
  // The legacy reader reports truncated data only as a warning ("Error
  // reading binary data!"): a warning that speaks of an error is one.
  for (const std::string& warning : TakeVTKWarnings())
  {
    std::string lower = warning;
    std::transform(lower.begin(), lower.end(), lower.begin(),
      [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (lower.find("error") != std::string::npos || lower.find("failed") != std::string::npos)
    {
      errors.push_back(warning);
    }
  }
  if (!errors.empty())
  {
    // The legacy reader reads ASCII values with a stream, which stops at
    // "nan" or "inf" (as VTK's own writer writes NaN and infinities) and
    // takes the word for the next section's keyword: say so.
    std::string lower = errors.front();
    std::transform(lower.begin(), lower.end(), lower.begin(),
      [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    const size_t at = lower.find("attribute type: ");
    if (at != std::string::npos)
    {
      std::string word = lower.substr(at + 16, lower.find(' ', at + 16) - at - 16);
      if (!word.empty() && (word[0] == '-' || word[0] == '+'))
      {
        word.erase(0, 1);
      }
      if (word == "nan" || word == "inf" || word == "infinity")
      {
        Unreadable(path, "its ASCII data holds a non-finite value ('" + word +
            "'), which VTK's legacy reader cannot read (write the file in binary, or as .vti)");
      }
    }
    Unreadable(path, errors.front());
  }
  if (reader->GetErrorCode() != 0)
  {
    Unreadable(path, "the reader failed (is the file complete?)");
  }
  return vtkImageData::SafeDownCast(reader->GetOutputDataObject(0));
}

// The reader for a file, after a cheap look at its header when the reader
// offers one, so that a file of another format is reported as such.
vtkSmartPointer<vtkAlgorithm> ReaderFor(const std::string& path, const std::string& ext)
{
  if (ext == ".vti")
  {
    auto reader = vtkSmartPointer<vtkPieceCheckingImageDataReader>::New();
    if (!reader->CanReadFile(path.c_str()))
    {
      Unreadable(path, "not a VTK XML image data file");
    }
    reader->SetFileName(path.c_str());
    return reader;
  }
  if (ext == ".vtk")
  {
    auto reader = vtkSmartPointer<vtkStructuredPointsReader>::New();
    reader->SetFileName(path.c_str());
    TakeVTKErrors();
    if (!reader->IsFileStructuredPoints())
    {
      Unreadable(path, "not a legacy VTK structured points file");
    }
    return reader;
  }
  vtkSmartPointer<vtkImageReader2> reader;
  const char* format = nullptr;
  if (ext == ".mha" || ext == ".mhd")
  {
    reader = vtkSmartPointer<vtkMetaImageReader>::New();
    format = "MetaImage";
  }
  else if (ext == ".nii" || ext == ".nii.gz")
  {
    reader = vtkSmartPointer<vtkNIFTIImageReader>::New();
    format = "NIfTI";
  }
  else if (ext == ".nrrd" || ext == ".nhdr")
  {
    reader = vtkSmartPointer<vtkNrrdReader>::New();
    format = "NRRD";
  }
  else
  {
    throw Error("unknown input format '" + (ext.empty() ? path : ext) + "' (known: " +
      InputExtensions + ", or a DICOM directory)");
  }
  TakeVTKErrors();
  if (!reader->CanReadFile(path.c_str()))
  {
    Unreadable(path, std::string("not a readable ") + format + " file");
  }
  reader->SetFileName(path.c_str());
  return reader;
}

bool IsNrrd(const std::string& path)
{
  const std::string ext = Extension(path);
  return ext == ".nrrd" || ext == ".nhdr";
}

}

namespace
{
// What the filter refuses in a volume's frame once the extraction runs
// (after the default isovalue's line went to stdout), tested here as it
// does: a direction matrix with a non-finite entry or a singular D *
// sign(spacing) (a .vti's Direction is read as written; the other formats'
// matrices went through SetFrame), and world coordinates that overflow at
// a corner of the extent (origin + column 0 * i + column 1 * j + column 2
// * k, each partial sum; the library's own test for an axis-aligned grid).
void CheckWorldFrame(vtkImageData* volume, const std::string& path)
{
  const double* origin = volume->GetOrigin();
  const double* spacing = volume->GetSpacing();
  vtkMatrix3x3* direction = volume->GetDirectionMatrix();
  const bool axisAligned = direction->IsIdentity() && spacing[0] > 0.0 && spacing[1] > 0.0 &&
    spacing[2] > 0.0;
  double indexToWorld[3][3];
  double scaled[3][3];
  std::string entries;
  bool finite = true;
  for (int r = 0; r < 3; ++r)
  {
    for (int c = 0; c < 3; ++c)
    {
      const double e = direction->GetElement(r, c);
      entries += (entries.empty() ? "" : " ") + General(e);
      finite = finite && std::isfinite(e);
      indexToWorld[r][c] = axisAligned ? (r == c ? spacing[c] : 0.0) : e * spacing[c];
      scaled[r][c] = e * (spacing[c] < 0.0 ? -1.0 : 1.0);
    }
  }
  const double det = vtkMath::Determinant3x3(scaled);
  if (!axisAligned && (!finite || det == 0.0 || !std::isfinite(det)))
  {
    Unreadable(path, "its direction matrix (" + entries + ") is " +
        (finite ? "singular" : "not all finite numbers"));
  }
  int extent[6];
  volume->GetExtent(extent);
  double largest[3] = { 0.0, 0.0, 0.0 }; // each world coordinate's, in magnitude
  for (int corner = 0; corner < 8; ++corner)
  {
    const double ijk[3] = { static_cast<double>(extent[corner & 1 ? 1 : 0]),
      static_cast<double>(extent[corner & 2 ? 3 : 2]),
      static_cast<double>(extent[corner & 4 ? 5 : 4]) };
    for (int r = 0; r < 3; ++r)
    {
      double x = origin[r];
      for (int c = 0; c < 3; ++c)
      {
        x += indexToWorld[r][c] * ijk[c];
        if (!std::isfinite(x))
        {
          const double* s = spacing;
          Unreadable(path, "its world coordinates overflow (not finite at sample (" +
              General(ijk[0]) + ", " + General(ijk[1]) + ", " + General(ijk[2]) +
              ") with origin (" + General(origin[0]) + ", " + General(origin[1]) + ", " +
              General(origin[2]) + "), spacing (" + General(s[0]) + ", " + General(s[1]) +
              ", " + General(s[2]) + ")" + (axisAligned ? "" : " and its direction matrix") +
              ")");
        }
      }
      largest[r] = std::max(largest[r], std::fabs(x));
    }
  }
  // Coordinates too large for the spacing: a double holds a coordinate x
  // to half an ulp, |x| * 2^-53, which moves a point along index axis c
  // by sum over r of |D^-1[c][r]| |x_r| 2^-53 / |spacing c| cells. Up to
  // 2^-13 (1.2e-4) of a cell, a hundredth of the default epsilon, is
  // allowed: a spacing of at least 2^-40 times the coordinates (per axis
  // for an axis-aligned grid). Beyond it (origin 1e17 at spacing 1: an
  // ulp of 16 cells) the surface's points collapsed onto each other, exit
  // status 0.
  double inverse[3][3] = { { 1, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 } };
  if (!axisAligned)
  {
    double d[3][3];
    for (int r = 0; r < 3; ++r)
    {
      for (int c = 0; c < 3; ++c)
      {
        d[r][c] = direction->GetElement(r, c);
      }
    }
    vtkMath::Invert3x3(d, inverse);
  }
  for (int c = 0; c < 3; ++c)
  {
    double reach = 0.0; // sum over r of |D^-1[c][r]| |x_r|
    for (int r = 0; r < 3; ++r)
    {
      reach += std::fabs(inverse[c][r]) * largest[r];
    }
    if (!(std::fabs(spacing[c]) >= std::ldexp(reach, -40)))
    {
      const auto triple = [](const double* v) {
        return "(" + General(v[0]) + ", " + General(v[1]) + ", " + General(v[2]) + ")";
      };
      Unreadable(path, "its world coordinates (up to " + triple(largest) + " in magnitude, "
          "origin " + triple(origin) + ") are too large for its spacing " + triple(spacing) +
          ": in double precision they round by more than 1e-4 of a cell along axis " +
          std::to_string(c) + " (a spacing of at least 2^-40 times the coordinates is needed; "
          "move the origin nearer 0)");
    }
  }
}

vtkSmartPointer<vtkImageData> ReadVolumeUnchecked(const std::string& path,
  const std::string& array, std::vector<std::string>& warnings, double range[2]);
}

// A failure inside a reader (an allocation of a size the header made up, a
// C++ exception from VTK) is reported as a failure to read that file, with
// its name, not as a bare "out of memory" or library message.
vtkSmartPointer<vtkImageData> ReadVolume(const std::string& path, const std::string& array,
  std::vector<std::string>& warnings, double range[2])
{
  try
  {
    return ReadVolumeUnchecked(path, array, warnings, range);
  }
  catch (const Error&)
  {
    throw;
  }
  catch (const std::bad_alloc&)
  {
    Unreadable(path, "out of memory while reading it (does its header declare a larger volume "
                     "than the file holds?)");
  }
  catch (const std::exception& e)
  {
    Unreadable(path, std::string("the reader failed (") + e.what() + ")");
  }
}

namespace
{
vtkSmartPointer<vtkImageData> ReadVolumeUnchecked(const std::string& path,
  const std::string& array, std::vector<std::string>& warnings, double range[2])
{
  vtkSmartPointer<vtkAlgorithm> reader;
  NrrdHeader nrrd;
  if (IsDirectory(path))
  {
    CheckDirectoryEntries(path);
    auto dicom = vtkSmartPointer<vtkSliceListingDICOMReader>::New();
    dicom->SetDirectoryName(path.c_str());
    reader = dicom;
  }
  else if (IsRegularFile(path))
  {
    // What keeps the file from being read at all, named as such (a reader
    // would blame its format).
    std::FILE* probe = std::fopen(path.c_str(), "rb");
    if (!probe)
    {
      Unreadable(path, std::strerror(errno));
    }
    const bool empty = std::fgetc(probe) == EOF;
    std::fclose(probe);
    if (empty)
    {
      Unreadable(path, "the file is empty");
    }
    if (IsNrrd(path))
    {
      nrrd = CheckNrrdHeader(path);
    }
    reader = ReaderFor(path, Extension(path));
    if (Extension(path) == ".mha" || Extension(path) == ".mhd")
    {
      CheckMetaImageHeaderLines(path);
      CheckMetaImageDataFiles(path);
      CheckMetaImageCompressedSize(path);
    }
    if (Extension(path) == ".vtk")
    {
      CheckLegacySize(path);
    }
    if (Extension(path) == ".nii" || Extension(path) == ".nii.gz")
    {
      CheckNiftiHeader(path);
    }
    if (Extension(path) == ".vti")
    {
      CheckVtiGeometry(path);
      CheckAppendedData(path);
      CheckInlineBinaryData(path);
      CheckCompressedBlockHeaders(path);
    }
  }
  else
  {
    // A FIFO or a device exists: it is no volume file (reading a FIFO
    // would wait for a writer).
    struct stat st;
    if (stat(path.c_str(), &st) == 0)
    {
      Unreadable(path, "not a regular file (nor a directory of DICOM files)");
    }
    Unreadable(path, errno == ENOENT ? std::string("no such file or directory")
                                     : std::string(std::strerror(errno)));
  }

  vtkImageData* image = nullptr;
  if (IsDirectory(path))
  {
    // vtkDICOMImageReader complains about slice order for series it still
    // reads: only an empty result is a failure. It lists the series' files
    // with the header; their pixel data is checked before it reads them.
    auto* dicom = vtkSliceListingDICOMReader::SafeDownCast(reader);
    TakeVTKErrors();
    reader->UpdateInformation();
    const std::vector<std::string> taken = dicom->TakenFiles();
    std::vector<SliceLayout> layouts(taken.size());
    for (size_t i = 0; i < taken.size(); ++i)
    {
      const std::string why = PixelDataProblem(path + "/" + taken[i], layouts[i]);
      if (!why.empty())
      {
        Unreadable(path, "its file '" + taken[i] + "' " + why);
      }
    }
    // Every slice laid out as the others: the layout most slices share
    // (the first slice's on a tie) is the series', so the odd one out is
    // named, whichever the reader sorted first.
    size_t common = 0;
    size_t commonCount = 0;
    for (size_t i = 0; i < layouts.size(); ++i)
    {
      const size_t count = static_cast<size_t>(std::count_if(layouts.begin(), layouts.end(),
        [&](const SliceLayout& l) { return l.Differs(layouts[i]) < 0; }));
      if (count > commonCount)
      {
        common = i;
        commonCount = count;
      }
    }
    for (size_t i = 0; i < layouts.size(); ++i)
    {
      const int field = layouts[common].Differs(layouts[i]);
      if (field >= 0)
      {
        Unreadable(path, "its file '" + taken[i] + "' has " + SliceLayout::Name(field) + " " +
            std::to_string(layouts[i].Values()[field]) + " where the series' other slices (as '" +
            taken[common] + "') have " + std::to_string(layouts[common].Values()[field]) +
            ": VTK's reader would read it into the volume as garbage (a slice of another "
            "series, as a localizer, mixed in?)");
      }
    }
    // The reader lays the volume out by the last file it parsed, of any
    // series in the directory: a 3-slice 4x4 localizer it took as the
    // series was read into 16x16 slices sized by another series' file.
    vtkInformation* info = reader->GetOutputInformation(0);
    if (!layouts.empty() && info &&
      info->Has(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT()))
    {
      int ext[6];
      info->Get(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), ext);
      SliceLayout volume = layouts[common];
      volume.Columns = ext[1] - ext[0] + 1;
      volume.Rows = ext[3] - ext[2] + 1;
      volume.BitsAllocated = 8 * vtkDataArray::GetDataTypeSize(vtkImageData::GetScalarType(info));
      volume.Samples = vtkImageData::GetNumberOfScalarComponents(info);
      const int field = volume.Differs(layouts[common]);
      if (field >= 0)
      {
        Unreadable(path, "its series' slices (as '" + taken[common] + "') have " +
            SliceLayout::Name(field) + " " + std::to_string(layouts[common].Values()[field]) +
            " where VTK's reader lays the volume out with " +
            std::to_string(volume.Values()[field]) + ", from another file "
            "in the directory: it would read them as garbage (several series of different "
            "sizes in one directory?)");
      }
    }
    // One series a directory: the reader reads the first and leaves the
    // others out (checked after the layouts, whose messages say more of
    // series that differ in size).
    const std::string several = SeveralSeries(dicom);
    if (!several.empty())
    {
      Unreadable(path, several);
    }
    reader->Update();
    TakeVTKErrors();
    image = vtkImageData::SafeDownCast(reader->GetOutputDataObject(0));
    if (!image || image->GetNumberOfPoints() == 0)
    {
      Unreadable(path, "no DICOM series found in the directory");
    }
    const std::string skipped = UnreadableSlice(path, dicom->TakenFiles());
    if (!skipped.empty())
    {
      Unreadable(path, "its file '" + skipped +
          "' is not a readable DICOM slice (empty, cut short or not DICOM): the series would "
          "be read without it");
    }
    // A slice file missing from the directory: the reader closes the gap
    // up (the slices beyond it move by a slice). Seen in the positions:
    // one step well beyond the others.
    const auto positions = dicom->SlicePositions();
    if (positions.size() >= 3)
    {
      std::vector<double> steps;
      for (size_t i = 1; i < positions.size(); ++i)
      {
        steps.push_back(static_cast<double>(positions[i].first) - positions[i - 1].first);
      }
      std::vector<double> sorted = steps;
      std::sort(sorted.begin(), sorted.end());
      const double typical = sorted[sorted.size() / 2];
      // Six digits: the positions went through float.
      const auto text = [](double x) {
        char buf[32];
        std::snprintf(buf, sizeof(buf), "%.6g", x);
        return std::string(buf);
      };
      for (size_t i = 0; typical > 0.0 && i < steps.size(); ++i)
      {
        // Two slices at one position (a copy of a slice file, or a link to
        // one): the reader took both, and the volume grew by a slice, every
        // later one shifted.
        if (steps[i] < 0.5 * typical)
        {
          Unreadable(path, "its slices '" + positions[i].second + "' and '" +
              positions[i + 1].second + "' lie " + text(steps[i]) + " apart, where the other "
              "slices are " + text(typical) + " apart: a slice is there twice (the series "
              "would be read with both, a slice taller)");
        }
        if (steps[i] > 1.5 * typical)
        {
          Unreadable(path, "its slice positions jump by " + text(steps[i]) + " between '" +
              positions[i].second + "' and '" + positions[i + 1].second + "', where the other "
              "slices are " + text(typical) + " apart: a slice is missing (the series would "
              "be read with the slices around the gap closed up)");
        }
      }
    }
  }
  else
  {
    image = RunReader(reader, path);
    if (!image || image->GetNumberOfPoints() == 0)
    {
      Unreadable(path, "the file holds no image data");
    }
    if (auto* xml = vtkPieceCheckingImageDataReader::SafeDownCast(reader))
    {
      std::string uncovered = xml->UncoveredSamples();
      if (!uncovered.empty())
      {
        Unreadable(path, uncovered);
      }
    }
  }
  int dims[3];
  image->GetDimensions(dims);
  const std::vector<long long>& nrrdSizes = nrrd.sizes;
  if (!nrrdSizes.empty())
  {
    // Dimension 3: the sizes are the samples, one component. VTK 9.1's
    // reader takes a short first axis (9 samples or fewer, even with
    // kinds "domain") or one without a space direction for vector
    // components. Dimension 4: the first size is the components.
    const int components = image->GetNumberOfScalarComponents();
    const size_t first = nrrdSizes.size() - 3;
    const long long expectedComponents = first == 0 ? 1 : nrrdSizes[0];
    if (dims[0] != nrrdSizes[first] || dims[1] != nrrdSizes[first + 1] ||
      dims[2] != nrrdSizes[first + 2] || components != expectedComponents)
    {
      std::string declared;
      for (long long n : nrrdSizes)
      {
        declared += (declared.empty() ? "" : " ") + std::to_string(n);
      }
      Unreadable(path, "VTK's NRRD reader reads the sizes " + declared + " as " +
          std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" +
          std::to_string(dims[2]) + " samples of " + std::to_string(components) +
          " components (it took the first axis for components): write the volume as .mha, "
          ".nii or .vti");
    }
  }
  if (dims[0] < 2 || dims[1] < 2 || dims[2] < 2)
  {
    Unreadable(path, "not a 3D volume (dimensions " + std::to_string(dims[0]) + "x" +
        std::to_string(dims[1]) + "x" + std::to_string(dims[2]) + ")");
  }
  vtkPointData* pd = image->GetPointData();
  if (!array.empty())
  {
    if (!pd->GetArray(array.c_str()))
    {
      std::string names;
      for (int i = 0; i < pd->GetNumberOfArrays(); ++i)
      {
        const char* n = pd->GetArrayName(i);
        names += std::string(names.empty() ? "" : ", ") + "'" + (n ? n : "") + "'";
      }
      Unreadable(path, "it has no point array of numbers named '" + array + "' (its point "
          "arrays: " + (names.empty() ? "none" : names) + ")");
    }
    pd->SetActiveScalars(array.c_str());
  }
  if (!pd->GetScalars())
  {
    // Some writers do not flag the scalars: take the first point array.
    for (int i = 0; i < pd->GetNumberOfArrays(); ++i)
    {
      if (pd->GetArray(i))
      {
        pd->SetActiveScalars(pd->GetArray(i)->GetName());
        break;
      }
    }
  }
  vtkDataArray* scalars = pd->GetScalars();
  if (!scalars && pd->GetNumberOfArrays() > 0)
  {
    // Only arrays of another kind (String): nothing the tool can contour.
    vtkAbstractArray* first = pd->GetAbstractArray(0);
    Unreadable(path, std::string("its point data holds no numbers (its array '") +
        (first->GetName() ? first->GetName() : "") + "' is of type " +
        first->GetDataTypeAsString() + ")");
  }
  if (!scalars || scalars->GetNumberOfTuples() != image->GetNumberOfPoints())
  {
    Unreadable(path, "the volume has no point scalars");
  }
  // Refused here, with the other checks, rather than by the filter once
  // the isovalue line is out (a legacy file's "bit" array).
  if (vtkPreciseMarchingCubes::LibraryScalarType(scalars->GetDataType()) < 0)
  {
    Unreadable(path, std::string("its scalars '") + (scalars->GetName() ? scalars->GetName() : "") +
        "' are of type " + scalars->GetDataTypeAsString() +
        ", which PreciseMC does not contour (integer and floating point arrays)");
  }
  auto volume = vtkSmartPointer<vtkImageData>::New();
  volume->ShallowCopy(image);
  if (auto* nifti = vtkNIFTIImageReader::SafeDownCast(reader))
  {
    if (nifti->GetTimeDimension() > 1)
    {
      // The reader gives the first time point only (with TimeAsVector
      // off), without a word.
      Unreadable(path, "it holds " + std::to_string(nifti->GetTimeDimension()) +
          " time points (a 4D series) and VTK's NIfTI reader gives the first only (write one "
          "file per 3D volume)");
    }
    ApplyNiftiScaling(nifti, volume);
    ApplyNiftiFrame(volume, path, nifti);
  }
  // Infinite samples are skipped like NaN ones (the cells touching them
  // have no surface): only finite values count. Once the values are final
  // (a NIfTI's scaling may take them beyond float's range).
  FiniteRange(volume->GetPointData()->GetScalars(), range);
  if (!std::isfinite(range[0]) || !std::isfinite(range[1]) || range[0] > range[1])
  {
    Unreadable(path, "the scalars have no finite values");
  }
  if (!nrrdSizes.empty())
  {
    ApplyNrrdFrame(volume, path, nrrd);
  }
  if (vtkMetaImageReader::SafeDownCast(reader))
  {
    ApplyMetaImageFrame(volume, path);
  }
  if (IsDirectory(path))
  {
    warnings.push_back("the series' patient position and orientation are not applied (VTK's "
                       "DICOM reader does not give them): the surface is in the image's own "
                       "frame, at its pixel and slice spacing");
  }
  // A spacing of 0 (a legacy file's SPACING 0 1 1) or not finite, from
  // any format: the filter refused it only once the extraction ran, after
  // the checks before the work; said here, as the file's fault.
  const double* spacing = volume->GetSpacing();
  const double* origin = volume->GetOrigin();
  const auto triple = [](const double* v) {
    return "(" + General(v[0]) + ", " + General(v[1]) + ", " + General(v[2]) + ")";
  };
  for (int i = 0; i < 3; ++i)
  {
    if (!(spacing[i] != 0.0) || !std::isfinite(spacing[i]))
    {
      Unreadable(path, "its spacing " + triple(spacing) +
          " is not all finite and non-zero (a spacing of 0 puts an axis's samples at one place)");
    }
    if (!std::isfinite(origin[i]))
    {
      Unreadable(path, "its origin " + triple(origin) + " is not all finite numbers");
    }
  }
  CheckWorldFrame(volume, path);
  return volume;
}
}

namespace
{
// FiniteRange() over any array type (vtkArrayDispatch's typed arrays, or
// vtkDataArray's API for the others).
struct FiniteRangeWorker
{
  double Min = std::numeric_limits<double>::infinity();
  double Max = -std::numeric_limits<double>::infinity();

  template <typename ArrayT>
  void operator()(ArrayT* array)
  {
    for (const auto tuple : vtk::DataArrayTupleRange(array))
    {
      const double v = static_cast<double>(tuple[0]);
      if (std::isfinite(v))
      {
        this->Min = std::min(this->Min, v);
        this->Max = std::max(this->Max, v);
      }
    }
  }
};
}

void FiniteRange(vtkDataArray* scalars, double range[2])
{
  FiniteRangeWorker worker;
  if (scalars->GetNumberOfComponents() > 0 && !vtkArrayDispatch::Dispatch::Execute(scalars, worker))
  {
    worker(scalars);
  }
  range[0] = worker.Min;
  range[1] = worker.Max;
}

std::string DescribeVolume(vtkImageData* volume)
{
  int dims[3];
  volume->GetDimensions(dims);
  vtkDataArray* scalars = volume->GetPointData()->GetScalars();
  std::string text = std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" +
    std::to_string(dims[2]);
  if (scalars)
  {
    text += std::string(", ") + scalars->GetDataTypeAsString();
    if (scalars->GetNumberOfComponents() > 1)
    {
      text += " (component 0 of " + std::to_string(scalars->GetNumberOfComponents()) + ")";
    }
    if (volume->GetPointData()->GetNumberOfArrays() > 1 && scalars->GetName())
    {
      // Which one of several (--array chooses).
      text += std::string(", array '") + scalars->GetName() + "'";
    }
  }
  return text;
}


}
