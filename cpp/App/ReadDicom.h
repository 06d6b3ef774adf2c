// DICOM input (a directory of slices) of the precisemc tool: the reader
// that lists the slices it takes, and the checks of them (ReadDicom.cxx).
#ifndef precisemc_app_ReadDicom_h
#define precisemc_app_ReadDicom_h

#include "Common.h"

#include "DICOMAppHelper.h"
#include "vtkDICOMImageReader.h"

#include <algorithm>
#include <array>
#include <string>
#include <utility>
#include <vector>

namespace pmcapp
{

// VTK's DICOM reader, which leaves out a file of the series it cannot
// parse (empty, cut short, not DICOM) without a word: the volume then
// lacks that slice and the slices around it close up. It tells which files
// it took.
class vtkSliceListingDICOMReader : public vtkDICOMImageReader
{
public:
  static vtkSliceListingDICOMReader* New();
  vtkTypeMacro(vtkSliceListingDICOMReader, vtkDICOMImageReader);

  // The names (without the directory) of the files read as the series.
  std::vector<std::string> TakenFiles()
  {
    std::vector<std::string> names;
    for (int i = 0; i < this->GetNumberOfDICOMFileNames(); ++i)
    {
      names.push_back(FileNameOf(this->GetDICOMFileName(i) ? this->GetDICOMFileName(i) : ""));
    }
    return names;
  }

  // Each slice's position along the slice normal (from its Image Position
  // (Patient)) and its file, ascending; all 0 when the files give none.
  std::vector<std::pair<float, std::string>> SlicePositions()
  {
    dicom_stl::vector<dicom_stl::pair<float, dicom_stl::string>> pairs;
    this->AppHelper->GetImagePositionPatientFilenamePairs(pairs);
    std::vector<std::pair<float, std::string>> out;
    for (const auto& p : pairs)
    {
      out.emplace_back(p.first, FileNameOf(p.second));
    }
    return out;
  }

  // Each series (Series Instance UID, ascending) among the files it
  // parsed, with the names of its files, sorted. The reader reads the
  // first series only and leaves the others out without a word.
  std::vector<std::pair<std::string, std::vector<std::string>>> Series()
  {
    dicom_stl::vector<dicom_stl::string> uids;
    this->AppHelper->GetSeriesUIDs(uids);
    std::vector<std::pair<std::string, std::vector<std::string>>> out;
    for (const auto& uid : uids)
    {
      dicom_stl::vector<dicom_stl::pair<float, dicom_stl::string>> pairs;
      this->AppHelper->GetImagePositionPatientFilenamePairs(uid, pairs);
      std::vector<std::string> names;
      for (const auto& p : pairs)
      {
        names.push_back(FileNameOf(p.second));
      }
      std::sort(names.begin(), names.end());
      out.emplace_back(uid, names);
    }
    return out;
  }

protected:
  vtkSliceListingDICOMReader() = default;
  ~vtkSliceListingDICOMReader() override = default;

private:
  vtkSliceListingDICOMReader(const vtkSliceListingDICOMReader&) = delete;
  void operator=(const vtkSliceListingDICOMReader&) = delete;
};

// The fields of a DICOM slice's header that lay its pixels out: VTK's
// reader sizes the volume by its first slice's and copies each slice's
// pixel data as that slice's header has it, so a slice laid out otherwise
// (a 4x4 localizer among 16x16 slices) overran the volume or was read as
// garbage.
struct SliceLayout
{
  int Rows = 0;
  int Columns = 0;
  int BitsAllocated = 0;
  int Samples = 0; // per pixel, as the reader counts them (3 for RGB)
  int Signed = 0;  // Pixel Representation

  // The fields in order, and their names.
  std::array<int, 5> Values() const
  {
    return { this->Rows, this->Columns, this->BitsAllocated, this->Samples, this->Signed };
  }
  static const char* Name(size_t field)
  {
    static const char* const names[] = { "rows", "columns", "bits allocated",
      "samples per pixel", "pixel representation" };
    return names[field];
  }
  // The first field in which `other` differs, -1 if none.
  int Differs(const SliceLayout& other) const
  {
    const std::array<int, 5> mine = this->Values();
    const std::array<int, 5> theirs = other.Values();
    const auto at = std::mismatch(mine.begin(), mine.end(), theirs.begin()).first;
    return at == mine.end() ? -1 : static_cast<int>(at - mine.begin());
  }
};

// What is wrong with the pixel data of the slice `file` ("" if nothing);
// `layout` gets its header's layout.
std::string PixelDataProblem(const std::string& file, SliceLayout& layout);

// A file of the directory `dir` named like the series' files that the
// reader left out and cannot read on its own either ("" if none).
std::string UnreadableSlice(const std::string& dir, const std::vector<std::string>& taken);

// Why the files `reader` parsed cannot be read as one series ("" if they
// can): they belong to more than one.
std::string SeveralSeries(vtkSliceListingDICOMReader* reader);

// Refuses a directory holding an entry that is neither a regular file nor
// a directory.
void CheckDirectoryEntries(const std::string& path);

}

#endif
