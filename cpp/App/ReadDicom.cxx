// The checks of a DICOM directory and of the slices VTK's DICOM reader
// takes from it, and the reader that tells which files it took.
#include "ReadDicom.h"

#include "ReadChecks.h"

#include "DICOMCallback.h"
#include "DICOMParser.h"
#include "vtkImageData.h"
#include "vtkObjectFactory.h"
#include "vtkSmartPointer.h"

#include <algorithm>
#include <cctype>

#include <dirent.h>
#include <sys/stat.h>

namespace pmcapp
{
namespace
{

// A file name with each run of digits replaced by '#': "slice007.dcm" ->
// "slice#.dcm", "IM12" -> "IM#".
std::string NumberingPattern(const std::string& name)
{
  std::string pattern;
  for (size_t i = 0; i < name.size(); ++i)
  {
    if (std::isdigit(static_cast<unsigned char>(name[i])))
    {
      if (pattern.empty() || pattern.back() != '#')
      {
        pattern += '#';
      }
    }
    else
    {
      pattern += name[i];
    }
  }
  return pattern;
}

// Takes the declared length of a DICOM file's pixel data (the last such
// element) and whether the file held all of it: VTK's parser reads the
// value without looking at how much it got, and a read past the end of the
// file leaves its stream failed (Tell() -1).
struct PixelDataElement
{
  bool Found = false;
  bool Whole = true;
  quadbyte Length = 0;
  void Take(DICOMParser* parser, doublebyte, doublebyte, DICOMParser::VRTypes, unsigned char*,
    quadbyte length)
  {
    this->Found = true;
    this->Length = length;
    this->Whole = parser->GetDICOMFile()->Tell() >= 0;
  }
};

}

vtkStandardNewMacro(vtkSliceListingDICOMReader);

// What is wrong with the pixel data of a DICOM slice that VTK's reader
// took into the series ("" if nothing): the reader copies what it needs
// from the pixel data element without a check, so a file cut short within
// it, or declaring fewer bytes than its rows x columns need, was read with
// zeros or garbage for the rest, and compressed (encapsulated) data, which
// it does not decode, as zeros or garbage. The file is parsed by VTK's own
// parser; `layout` gets its header's layout.
std::string PixelDataProblem(const std::string& file, SliceLayout& layout)
{
  DICOMAppHelper header;
  PixelDataElement pixels;
  DICOMMemberCallback<PixelDataElement> take;
  take.SetCallbackFunction(&pixels, &PixelDataElement::Take);
  DICOMParser parser;
  {
    StderrCapture capture; // its notes on a file without the DICM prefix
    if (!parser.OpenFile(file))
    {
      return "cannot be opened";
    }
    header.RegisterCallbacks(&parser);
    parser.AddDICOMTagCallback(0x7FE0, 0x0010, DICOMParser::VR_OW, &take);
    parser.ReadHeader();
  }
  layout.Rows = header.GetHeight();
  layout.Columns = header.GetWidth();
  layout.BitsAllocated = header.GetBitsAllocated();
  layout.Samples = header.GetNumberOfComponents();
  layout.Signed = header.GetPixelRepresentation();
  const unsigned long long need = static_cast<unsigned long long>(header.GetWidth()) *
    static_cast<unsigned long long>(header.GetHeight()) * header.GetNumberOfComponents() *
    static_cast<unsigned long long>(header.GetBitsAllocated() / 8);
  const std::string what = std::to_string(header.GetWidth()) + "x" +
    std::to_string(header.GetHeight()) + " pixels of " +
    std::to_string(header.GetBitsAllocated()) + " bits" +
    (header.GetNumberOfComponents() > 1
        ? " x " + std::to_string(header.GetNumberOfComponents()) + " samples"
        : std::string());
  if (!pixels.Found)
  {
    return "has no pixel data (is the file cut short?)";
  }
  if (pixels.Length == 0xFFFFFFFFu)
  {
    return "holds compressed pixel data (transfer syntax " + header.GetTransferSyntaxUID() +
      "), which VTK's DICOM reader does not decode (it would read zeros or garbage)";
  }
  if (!pixels.Whole)
  {
    return "is cut short within its pixel data (" + what + ": " + std::to_string(need) +
      " bytes)";
  }
  if (pixels.Length < need)
  {
    return "holds " + std::to_string(pixels.Length) + " bytes of pixel data, fewer than its " +
      what + " need (" + std::to_string(need) + ")";
  }
  return "";
}

// A file of the directory `dir` named like the series' files (the same
// name but for its numbers: "slice007.dcm" beside "slice006.dcm", not a
// README, a DICOMDIR, a report or a hidden "._slice001.dcm" that a copy
// from a Mac leaves) that the reader left out, and that VTK's reader
// cannot read on its own either (so not a slice of another series
// numbered alike): "" when there is none.
std::string UnreadableSlice(const std::string& dir, const std::vector<std::string>& taken)
{
  std::vector<std::string> patterns;
  for (const std::string& name : taken)
  {
    patterns.push_back(NumberingPattern(name));
  }
  std::sort(patterns.begin(), patterns.end());
  patterns.erase(std::unique(patterns.begin(), patterns.end()), patterns.end());
  std::vector<std::string> sorted = taken;
  std::sort(sorted.begin(), sorted.end());
  DIR* d = opendir(dir.c_str());
  if (!d)
  {
    return "";
  }
  std::vector<std::string> others;
  while (dirent* entry = readdir(d))
  {
    const std::string name = entry->d_name;
    if (name.empty() || name[0] == '.' ||
      std::binary_search(sorted.begin(), sorted.end(), name) ||
      !std::binary_search(patterns.begin(), patterns.end(), NumberingPattern(name)))
    {
      continue;
    }
    if (IsRegularFile(dir + "/" + name))
    {
      others.push_back(name);
    }
  }
  closedir(d);
  std::sort(others.begin(), others.end());
  for (const std::string& name : others)
  {
    auto alone = vtkSmartPointer<vtkDICOMImageReader>::New();
    alone->SetFileName((dir + "/" + name).c_str());
    {
      StderrCapture capture;
      alone->Update();
    }
    TakeVTKErrors();
    vtkImageData* image = alone->GetOutput();
    if (!image || image->GetNumberOfPoints() == 0)
    {
      return name;
    }
  }
  return "";
}

// Why the files VTK's DICOM reader parsed in a directory cannot be read
// as one series ("" if they can): they belong to several (Series Instance
// UID). The reader reads the first series by UID and leaves the others
// out without a word, so of a CT series and another beside it (a second
// reconstruction, a localizer of the same size) the order of their UIDs
// chose the one contoured, exit status 0.
std::string SeveralSeries(vtkSliceListingDICOMReader* reader)
{
  const auto series = reader->Series();
  if (series.size() < 2)
  {
    return "";
  }
  const auto describe = [](const std::pair<std::string, std::vector<std::string>>& s) {
    const size_t n = s.second.size();
    return s.first +
      (n == 0 ? std::string()
              : " ('" + s.second.front() + "'" +
            (n > 1 ? " and " + std::to_string(n - 1) + " more file" + (n > 2 ? "s" : "")
                   : std::string()) +
            ")");
  };
  std::string listed = describe(series[0]) + " and " + describe(series[1]);
  if (series.size() > 2)
  {
    listed = describe(series[0]) + ", " + describe(series[1]) + " and " +
      std::to_string(series.size() - 2) + " more";
  }
  return "its files belong to " + std::to_string(series.size()) +
    " DICOM series (Series Instance UIDs " + listed + "), of which VTK's DICOM reader would "
    "read one only, without a word: put each series in a directory of its own";
}

// Throws when the DICOM directory `path` holds an entry that is neither a
// regular file nor a directory: VTK's DICOM reader opens every entry, and
// waited for a writer on a FIFO (or read a device without end).
void CheckDirectoryEntries(const std::string& path)
{
  DIR* d = opendir(path.c_str());
  if (!d)
  {
    return; // the reader speaks of it
  }
  std::string odd;
  while (dirent* entry = readdir(d))
  {
    const std::string name = entry->d_name;
    struct stat st;
    if (name == "." || name == ".." || stat((path + "/" + name).c_str(), &st) != 0)
    {
      continue;
    }
    if (!S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode))
    {
      odd = name;
      break;
    }
  }
  closedir(d);
  if (!odd.empty())
  {
    Unreadable(path, "the directory holds '" + odd + "', which is not a regular file (a FIFO "
        "or a device, which VTK's DICOM reader would wait on or read without end)");
  }
}

}
