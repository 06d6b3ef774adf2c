// VTK XML image data input (.vti) of the precisemc tool: the file's checks
// before the reader runs, and the reader (ReadVtkXml.cxx).
#ifndef precisemc_app_ReadVtkXml_h
#define precisemc_app_ReadVtkXml_h

#include "vtkDataArray.h"
#include "vtkXMLDataElement.h"
#include "vtkXMLImageDataReader.h"

#include <algorithm>
#include <cstring>
#include <string>
#include <vector>

namespace pmcapp
{

// Refuses an <ImageData> Origin, Spacing or Direction that is not finite
// numbers.
void CheckVtiGeometry(const std::string& path);

// Refuses uncompressed appended data cut short.
void CheckAppendedData(const std::string& path);

// Refuses inline binary (base64) data cut short.
void CheckInlineBinaryData(const std::string& path);

// Refuses compressed blocks whose header VTK's reader crashes on.
void CheckCompressedBlockHeaders(const std::string& path);

// VTK's XML image data reader, which allocates the whole extent and fills
// what the file's pieces hold: samples no piece holds are left as they
// were allocated (zero or garbage), without a word. It tells which are.
// It also refuses String point scalars and does not read String arrays.
// (Named vtk* so that CleanMessage strips its "name (0x...): " prefix.)
class vtkPieceCheckingImageDataReader : public vtkXMLImageDataReader
{
public:
  static vtkPieceCheckingImageDataReader* New();
  vtkTypeMacro(vtkPieceCheckingImageDataReader, vtkXMLImageDataReader);

  // After the read: "" when every sample of the whole extent lies in a
  // piece, else why not.
  std::string UncoveredSamples()
  {
    const int* whole = this->WholeExtent;
    long long n[3];
    for (int a = 0; a < 3; ++a)
    {
      n[a] = static_cast<long long>(whole[2 * a + 1]) - whole[2 * a] + 1;
      if (n[a] < 1)
      {
        return std::string();
      }
    }
    if (this->NumberOfPieces < 1 || !this->PieceExtents)
    {
      return "the file has no pieces";
    }
    // Nearly every file has a piece holding the whole extent: done.
    for (int p = 0; p < this->NumberOfPieces; ++p)
    {
      const int* e = this->PieceExtents + 6 * p;
      bool all = true;
      for (int a = 0; a < 3; ++a)
      {
        all = all && e[2 * a] <= whole[2 * a] && e[2 * a + 1] >= whole[2 * a + 1];
      }
      if (all)
      {
        return std::string();
      }
    }
    // A bit per sample: an eighth of the smallest volume's size.
    std::vector<bool> covered(static_cast<size_t>(n[0] * n[1] * n[2]), false);
    for (int p = 0; p < this->NumberOfPieces; ++p)
    {
      const int* e = this->PieceExtents + 6 * p;
      int lo[3], hi[3];
      for (int a = 0; a < 3; ++a)
      {
        lo[a] = std::max(e[2 * a], whole[2 * a]);
        hi[a] = std::min(e[2 * a + 1], whole[2 * a + 1]);
      }
      for (long long k = lo[2]; k <= hi[2]; ++k)
      {
        for (long long j = lo[1]; j <= hi[1]; ++j)
        {
          const long long row = ((k - whole[4]) * n[1] + (j - whole[2])) * n[0] - whole[0];
          for (long long i = lo[0]; i <= hi[0]; ++i)
          {
            covered[static_cast<size_t>(row + i)] = true;
          }
        }
      }
    }
    const long long missing = std::count(covered.begin(), covered.end(), false);
    if (missing == 0)
    {
      return std::string();
    }
    return "its " + std::to_string(this->NumberOfPieces) +
      (this->NumberOfPieces == 1 ? " piece leaves " : " pieces leave ") +
      std::to_string(missing) + " of the " +
      std::to_string(n[0] * n[1] * n[2]) +
      " samples of the whole extent out (is the file complete?)";
  }

protected:
  vtkPieceCheckingImageDataReader() = default;
  ~vtkPieceCheckingImageDataReader() override = default;

  // A piece whose point data names a String array its Scalars is refused
  // with the header: VTK cannot make it the scalars, and the tool would
  // contour another array of the file instead.
  using vtkXMLImageDataReader::ReadPiece;
  int ReadPiece(vtkXMLDataElement* ePiece) override
  {
    if (!this->Superclass::ReadPiece(ePiece))
    {
      return 0;
    }
    vtkXMLDataElement* pointData = this->PointDataElements[this->Piece];
    const char* scalars = pointData ? pointData->GetAttribute("Scalars") : nullptr;
    for (int i = 0; scalars && i < pointData->GetNumberOfNestedElements(); ++i)
    {
      vtkXMLDataElement* array = pointData->GetNestedElement(i);
      const char* name = array->GetAttribute("Name");
      const char* type = array->GetAttribute("type");
      if (name && type && std::strcmp(name, scalars) == 0 && std::strcmp(type, "String") == 0)
      {
        vtkErrorMacro("its point scalars '" << scalars << "' are of type String, not numbers");
        return 0;
      }
    }
    return 1;
  }

  // String arrays are not read: the tool contours numbers only, and VTK
  // 9.1's reader crashed (a null pointer) reporting a String array whose
  // values it could not parse.
  int ReadArrayForPoints(vtkXMLDataElement* da, vtkAbstractArray* array) override
  {
    if (!vtkDataArray::SafeDownCast(array))
    {
      return 1;
    }
    this->PointArray = da;
    const int read = this->Superclass::ReadArrayForPoints(da, array);
    this->PointArray = nullptr;
    return read;
  }
  int ReadArrayForCells(vtkXMLDataElement* da, vtkAbstractArray* array) override
  {
    return !vtkDataArray::SafeDownCast(array) || this->Superclass::ReadArrayForCells(da, array);
  }

  // VTK says only "Error reading extent ..." of a point array's ASCII
  // data with too few values or a word among them: this error, first,
  // says which.
  int ReadArrayValues(vtkXMLDataElement* da, vtkIdType arrayIndex, vtkAbstractArray* array,
    vtkIdType startIndex, vtkIdType numValues, FieldType type = OTHER) override
  {
    if (this->Superclass::ReadArrayValues(da, arrayIndex, array, startIndex, numValues, type))
    {
      return 1;
    }
    const char* format = da->GetAttribute("format");
    if (da == this->PointArray && format && std::strcmp(format, "ascii") == 0 &&
      !this->GetAbortExecute())
    {
      const char* name = da->GetAttribute("Name");
      const char* word = da->GetAttribute("type");
      vtkErrorMacro("the ASCII data of its array '"
        << (name ? name : "") << "' holds fewer values than the array needs, or one that is "
        << "not a " << (word ? word : array->GetDataTypeAsString()) << " number");
    }
    return 0;
  }

private:
  vtkXMLDataElement* PointArray = nullptr; // the point array being read
  vtkPieceCheckingImageDataReader(const vtkPieceCheckingImageDataReader&) = delete;
  void operator=(const vtkPieceCheckingImageDataReader&) = delete;
};

}

#endif
