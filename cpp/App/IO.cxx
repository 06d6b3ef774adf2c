// Reading volumes and writing surfaces for the precisemc tool. VTK readers
// report problems through the output window (captured by Common.h) and
// often still produce an empty image, so the result is checked as well.
#include "IO.h"

#include "Common.h"

#include "vtkAlgorithm.h"
#include "vtkDICOMImageReader.h"
#include "vtkDataArray.h"
#include "vtkImageData.h"
#include "vtkImageReader2.h"
#include "vtkMetaImageReader.h"
#include "vtkNIFTIImageReader.h"
#include "vtkNew.h"
#include "vtkNrrdReader.h"
#include "vtkOBJWriter.h"
#include "vtkPLYWriter.h"
#include "vtkPointData.h"
#include "vtkPolyData.h"
#include "vtkSTLWriter.h"
#include "vtkStructuredPointsReader.h"
#include "vtkXMLImageDataReader.h"
#include "vtkXMLPolyDataWriter.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <iostream>

#include <unistd.h>

namespace pmcapp
{
namespace
{

const char* const InputExtensions = ".vti, .vtk, .mha, .mhd, .nii, .nii.gz, .nrrd, .nhdr";
const char* const SurfaceExtensions = ".vtp, .ply, .stl, .obj";

bool IsSurfaceExtension(const std::string& ext)
{
  return ext == ".vtp" || ext == ".ply" || ext == ".stl" || ext == ".obj";
}

[[noreturn]] void Unreadable(const std::string& path, const std::string& why)
{
  throw Error("cannot read '" + path + "': " + why);
}

// Redirects file descriptor 2 into a temporary file while alive: some
// libraries under VTK's readers (MetaIO) print their complaints straight
// to std::cerr, which would break the one-line error report.
class StderrCapture
{
public:
  StderrCapture()
  {
    std::fflush(stderr);
    std::cerr.flush();
    this->File = std::tmpfile();
    this->Saved = this->File ? dup(STDERR_FILENO) : -1;
    if (this->Saved >= 0)
    {
      dup2(fileno(this->File), STDERR_FILENO);
    }
  }
  ~StderrCapture()
  {
    this->Restore();
    if (this->File)
    {
      std::fclose(this->File);
    }
  }
  // What was written, first line only, trimmed; restores stderr.
  std::string Text()
  {
    this->Restore();
    std::string text;
    if (this->File)
    {
      std::rewind(this->File);
      int c;
      while ((c = std::fgetc(this->File)) != EOF && text.size() < 4096)
      {
        text += static_cast<char>(c);
      }
    }
    size_t b = text.find_first_not_of(" \t\r\n");
    if (b == std::string::npos)
    {
      return std::string();
    }
    size_t e = text.find('\n', b);
    text = text.substr(b, e == std::string::npos ? std::string::npos : e - b);
    while (!text.empty() && (text.back() == ' ' || text.back() == '\r'))
    {
      text.pop_back();
    }
    return text;
  }

private:
  void Restore()
  {
    if (this->Saved >= 0)
    {
      std::fflush(stderr);
      std::cerr.flush();
      dup2(this->Saved, STDERR_FILENO);
      close(this->Saved);
      this->Saved = -1;
    }
  }
  std::FILE* File = nullptr;
  int Saved = -1;
};

// Runs the reader and turns captured VTK errors into an Error.
vtkImageData* RunReader(vtkAlgorithm* reader, const std::string& path)
{
  TakeVTKErrors();
  TakeVTKWarnings();
  std::string stray;
  {
    StderrCapture capture;
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
    auto reader = vtkSmartPointer<vtkXMLImageDataReader>::New();
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

}

vtkSmartPointer<vtkImageData> ReadVolume(const std::string& path)
{
  vtkSmartPointer<vtkAlgorithm> reader;
  if (IsDirectory(path))
  {
    auto dicom = vtkSmartPointer<vtkDICOMImageReader>::New();
    dicom->SetDirectoryName(path.c_str());
    reader = dicom;
  }
  else if (IsRegularFile(path))
  {
    reader = ReaderFor(path, Extension(path));
  }
  else
  {
    Unreadable(path, "no such file or directory");
  }

  vtkImageData* image = nullptr;
  if (IsDirectory(path))
  {
    // vtkDICOMImageReader complains about slice order for series it still
    // reads: only an empty result is a failure.
    TakeVTKErrors();
    reader->Update();
    TakeVTKErrors();
    image = vtkImageData::SafeDownCast(reader->GetOutputDataObject(0));
    if (!image || image->GetNumberOfPoints() == 0)
    {
      Unreadable(path, "no DICOM series found in the directory");
    }
  }
  else
  {
    image = RunReader(reader, path);
    if (!image || image->GetNumberOfPoints() == 0)
    {
      Unreadable(path, "the file holds no image data");
    }
  }
  int dims[3];
  image->GetDimensions(dims);
  if (dims[0] < 2 || dims[1] < 2 || dims[2] < 2)
  {
    Unreadable(path, "not a 3D volume (dimensions " + std::to_string(dims[0]) + "x" +
        std::to_string(dims[1]) + "x" + std::to_string(dims[2]) + ")");
  }
  vtkPointData* pd = image->GetPointData();
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
  if (!scalars || scalars->GetNumberOfTuples() != image->GetNumberOfPoints())
  {
    Unreadable(path, "the volume has no point scalars");
  }
  double range[2];
  scalars->GetRange(range, 0);
  if (!std::isfinite(range[0]) || !std::isfinite(range[1]) || range[0] > range[1])
  {
    Unreadable(path, "the scalars have no finite values");
  }

  auto volume = vtkSmartPointer<vtkImageData>::New();
  volume->ShallowCopy(image);
  return volume;
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
  }
  return text;
}

void CheckSurfaceFormat(const std::string& path)
{
  if (!IsSurfaceExtension(Extension(path)))
  {
    throw Error("unknown output format '" + path + "' (known: " + SurfaceExtensions + ")", 2);
  }
}

void WriteSurface(vtkPolyData* surface, const std::string& path, const std::string& file)
{
  std::string ext = Extension(path);
  vtkSmartPointer<vtkAlgorithm> writer;
  if (ext == ".vtp")
  {
    auto w = vtkSmartPointer<vtkXMLPolyDataWriter>::New();
    w->SetFileName(file.c_str());
    w->SetDataModeToAppended();
    w->SetCompressorTypeToZLib();
    writer = w;
  }
  else if (ext == ".ply")
  {
    auto w = vtkSmartPointer<vtkPLYWriter>::New();
    w->SetFileName(file.c_str());
    w->SetFileTypeToBinary();
    writer = w;
  }
  else if (ext == ".stl")
  {
    auto w = vtkSmartPointer<vtkSTLWriter>::New();
    w->SetFileName(file.c_str());
    w->SetFileTypeToBinary();
    writer = w;
  }
  else if (ext == ".obj")
  {
    auto w = vtkSmartPointer<vtkOBJWriter>::New();
    w->SetFileName(file.c_str());
    writer = w;
  }
  else
  {
    throw Error("unknown output format '" + path + "' (known: " + SurfaceExtensions + ")", 2);
  }
  writer->SetInputDataObject(0, surface);

  TakeVTKErrors();
  writer->Update();
  std::vector<std::string> errors = TakeVTKErrors();
  if (!errors.empty() || writer->GetErrorCode() != 0 || !IsRegularFile(file))
  {
    RemoveFile(file);
    throw Error("cannot write '" + path + "'" +
      (errors.empty() ? std::string() : ": " + errors.front()));
  }
}

}
