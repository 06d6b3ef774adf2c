// Writing the surface for the precisemc tool (IO.h): the format by the
// output's extension, and a check that the writer wrote it all.
#include "IO.h"

#include "Common.h"

#include "vtkAlgorithm.h"
#include "vtkCellArray.h"
#include "vtkErrorCode.h"
#include "vtkOBJWriter.h"
#include "vtkPLYWriter.h"
#include "vtkPointData.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkSTLWriter.h"
#include "vtkXMLPolyDataWriter.h"

#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <sstream>

#include <sys/stat.h>

namespace pmcapp
{
namespace
{

const char* const SurfaceExtensions = ".vtp, .ply, .stl, .obj";

bool IsSurfaceExtension(const std::string& ext)
{
  return ext == ".vtp" || ext == ".ply" || ext == ".stl" || ext == ".obj";
}

// Whether the binary PLY file vtkPLYWriter wrote holds every point and
// polygon of surface: its size must be what its header declares for them.
bool CompletePly(const std::string& file, vtkPolyData* surface)
{
  std::FILE* f = std::fopen(file.c_str(), "rb");
  if (!f)
  {
    return false;
  }
  std::string header;
  std::string line;
  int c;
  while (header.size() < 65536 && (c = std::getc(f)) != EOF)
  {
    header += static_cast<char>(c);
    if (c == '\n')
    {
      if (line == "end_header")
      {
        break;
      }
      line.clear();
    }
    else
    {
      line += static_cast<char>(c);
    }
  }
  bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed || line != "end_header")
  {
    return false;
  }
  auto typeSize = [](const std::string& t) -> long long {
    if (t == "char" || t == "uchar" || t == "int8" || t == "uint8")
      return 1;
    if (t == "short" || t == "ushort" || t == "int16" || t == "uint16")
      return 2;
    if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" ||
      t == "float32")
      return 4;
    if (t == "double" || t == "float64")
      return 8;
    return -1;
  };
  long long expected = static_cast<long long>(header.size());
  long long vertices = -1;
  long long faces = -1;
  std::string element;
  long long count = 0;
  std::istringstream lines(header);
  while (std::getline(lines, line))
  {
    std::istringstream words(line);
    std::string word;
    words >> word;
    if (word == "format" && (words >> word, word == "ascii"))
    {
      return true; // not what the tool writes; nothing to size
    }
    if (word == "element")
    {
      words >> element >> count;
      if (element == "vertex")
      {
        vertices = count;
      }
      else if (element == "face")
      {
        faces = count;
      }
    }
    else if (word == "property")
    {
      std::string type;
      words >> type;
      if (type == "list")
      {
        std::string countType, itemType;
        words >> countType >> itemType;
        if (element != "face" || typeSize(countType) < 0 || typeSize(itemType) < 0)
        {
          return true; // a layout the tool does not write
        }
        expected += count * typeSize(countType) +
          static_cast<long long>(surface->GetPolys()->GetNumberOfConnectivityIds()) *
            typeSize(itemType);
      }
      else if (typeSize(type) < 0)
      {
        return true;
      }
      else
      {
        expected += count * typeSize(type);
      }
    }
  }
  struct stat st;
  return vertices == surface->GetNumberOfPoints() && faces == surface->GetNumberOfPolys() &&
    stat(file.c_str(), &st) == 0 && static_cast<long long>(st.st_size) == expected;
}

// Whether the OBJ file vtkOBJWriter wrote holds every point and polygon
// of surface: the writer does not report a failed write (a full disk left
// a shorter file), so its lines are counted.
bool CompleteObj(const std::string& file, vtkPolyData* surface)
{
  std::FILE* f = std::fopen(file.c_str(), "rb");
  if (!f)
  {
    return false;
  }
  long long points = 0;
  long long faces = 0;
  int previous = '\n';
  int first = 0;
  int second = 0;
  int c;
  // The first two characters of each line tell "v " from "vn" and "f ".
  int column = 0;
  while ((c = std::getc(f)) != EOF)
  {
    if (previous == '\n')
    {
      column = 0;
    }
    if (column == 0)
    {
      first = c;
    }
    else if (column == 1)
    {
      second = c;
      points += first == 'v' && (second == ' ' || second == '\t');
      faces += first == 'f' && (second == ' ' || second == '\t');
    }
    ++column;
    previous = c;
  }
  bool failed = std::ferror(f) != 0;
  std::fclose(f);
  return !failed && (previous == '\n' || points + faces == 0) &&
    points == surface->GetNumberOfPoints() && faces == surface->GetNumberOfPolys();
}

}

void CheckSurfaceFormat(const std::string& path)
{
  const std::string only = OnlyExtension(path);
  if (IsSurfaceExtension(only))
  {
    throw Error("'" + path + "' has no base name, only the extension " + only, 2);
  }
  if (!IsSurfaceExtension(Extension(path)))
  {
    throw Error("unknown output format '" + path + "' (known: " + SurfaceExtensions + ")", 2);
  }
}

void WriteSurface(
  vtkPolyData* surface, const std::string& path, const std::string& file, bool quiet)
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
  // PLY and STL hold float coordinates: points the run keeps in double
  // (far from the origin) are rounded there, or overflow float.
  vtkPoints* points = surface->GetPoints();
  if ((ext == ".ply" || ext == ".stl") && points && points->GetDataType() == VTK_DOUBLE &&
    points->GetNumberOfPoints() > 0)
  {
    double bounds[6];
    points->GetBounds(bounds);
    for (double b : bounds)
    {
      if (!(std::fabs(b) <= std::numeric_limits<float>::max()))
      {
        throw Error("cannot write '" + path + "': " + ext.substr(1) +
          " stores float coordinates and the surface lies beyond float's range (write .vtp or "
          ".obj)");
      }
    }
    if (!quiet)
    {
      std::cerr << "precisemc: warning: '" << path << "': " << ext.substr(1)
                << " stores float coordinates, which round these points by more than the "
                   "run's accuracy (.vtp and .obj keep double)"
                << std::endl;
    }
  }

  // Only .vtp holds point arrays beyond normals: --gradients' array would
  // be left out without a word.
  if (ext != ".vtp" && !quiet && surface->GetPointData()->GetArray("Gradients"))
  {
    std::cerr << "precisemc: warning: '" << path << "': " << ext.substr(1)
              << " holds no \"Gradients\" array: --gradients is not written (.vtp holds it)"
              << std::endl;
  }

  TakeVTKErrors();
  writer->Update();
  std::vector<std::string> errors = TakeVTKErrors();
  // vtkPLYWriter and vtkOBJWriter do not report a failed write (a full
  // disk left a shorter file, and a success): what they wrote is checked.
  if (errors.empty() && writer->GetErrorCode() == 0 &&
    ((ext == ".ply" && !CompletePly(file, surface)) ||
      (ext == ".obj" && !CompleteObj(file, surface))))
  {
    errors.push_back("the file came out incomplete (is the disk full?)");
  }
  if (!errors.empty() || writer->GetErrorCode() != 0 || !IsRegularFile(file))
  {
    RemoveFile(file);
    std::string why = BestError(errors);
    if (why.empty())
    {
      why = writer->GetErrorCode() != 0
        ? vtkErrorCode::GetStringFromErrorCode(writer->GetErrorCode())
        : "the writer failed";
    }
    throw Error("cannot write '" + path + "': " + ForUser(why, file, path));
  }
}

}
