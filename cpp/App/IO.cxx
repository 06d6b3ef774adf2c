// Reading volumes and writing surfaces for the precisemc tool. VTK readers
// report problems through the output window (captured by Common.h) and
// often still produce an empty image, so the result is checked as well.
#include "IO.h"

#include "Common.h"

#include "DICOMAppHelper.h"
#include "DICOMCallback.h"
#include "DICOMParser.h"
#include "vtkAlgorithm.h"
#include "vtkArrayDispatch.h"
#include "vtkCellArray.h"
#include "vtkDataArray.h"
#include "vtkDataArrayRange.h"
#include "vtkDICOMImageReader.h"
#include "vtkDoubleArray.h"
#include "vtkErrorCode.h"
#include "vtkFloatArray.h"
#include "vtkImageData.h"
#include "vtkImageReader2.h"
#include "vtkInformation.h"
#include "vtkMath.h"
#include "vtkMatrix3x3.h"
#include "vtkMatrix4x4.h"
#include "vtkNIFTIImageHeader.h"
#include "vtkMetaImageReader.h"
#include "vtkNew.h"
#include "vtkNIFTIImageReader.h"
#include "vtkNrrdReader.h"
#include "vtkObjectFactory.h"
#include "vtkOBJWriter.h"
#include "vtkPLYWriter.h"
#include "vtkPointData.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkPreciseMarchingCubes.h"
#include "vtkSTLWriter.h"
#include "vtkStreamingDemandDrivenPipeline.h"
#include "vtkStructuredPointsReader.h"
#include "vtkXMLDataElement.h"
#include "vtkXMLImageDataReader.h"
#include "vtkXMLPolyDataWriter.h"
#include "vtk_zlib.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <iterator>
#include <limits>
#include <sstream>
#include <vector>

#include <dirent.h>
#include <sys/stat.h>
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

// The whitespace-separated words of `text`.
std::vector<std::string> Words(const std::string& text)
{
  std::vector<std::string> words;
  std::istringstream split(text);
  std::string word;
  while (split >> word)
  {
    words.push_back(word);
  }
  return words;
}

// The most slice files a header may name (a volume of so many slices in
// files of their own is none a user keeps; a pattern naming 10^9 of them
// made VTK's NRRD reader build as many names).
const long long MaxSliceFiles = 1 << 16;

// Why `pattern` cannot name slice files the way VTK's readers expand it
// (snprintf with the slice number, an int, as its one argument), "" when
// it can: exactly one integer conversion (%d, %03d, %x, ...), with %% for a
// literal percent sign. Any other conversion (%s, %n, two of them, a
// length modifier) made the reader pass garbage to snprintf: a crash.
std::string SlicePatternProblem(const std::string& pattern)
{
  int conversions = 0;
  const auto at = [&pattern](size_t j) { return j < pattern.size() ? pattern[j] : '\0'; };
  // At most three digits of width or precision: "%999999999d" would make
  // a file name a billion characters long.
  const auto digits = [&](size_t& j) {
    const size_t from = j;
    while (std::isdigit(static_cast<unsigned char>(at(j))))
    {
      ++j;
    }
    return j - from <= 3;
  };
  for (size_t i = 0; i < pattern.size(); ++i)
  {
    if (pattern[i] != '%')
    {
      continue;
    }
    size_t j = i + 1;
    if (at(j) == '%')
    {
      i = j;
      continue;
    }
    while (at(j) != '\0' && std::strchr("-+ #0", at(j)))
    {
      ++j;
    }
    bool short_enough = digits(j);
    if (at(j) == '.')
    {
      ++j;
      short_enough = digits(j) && short_enough;
    }
    if (!short_enough || at(j) == '\0' || !std::strchr("diouxX", at(j)))
    {
      return "holds '" + pattern.substr(i, std::min(pattern.size(), j + 1) - i) +
        "', not an integer conversion (%d, %03d, ...)";
    }
    ++conversions;
    i = j;
  }
  if (conversions != 1)
  {
    return "holds " + std::to_string(conversions) +
      " integer conversions, where the slice number fills exactly one";
  }
  return std::string();
}

// The path of `file`, a data file the header `path` names: relative to
// the header's directory unless absolute (as VTK's readers take it).
std::string DataFilePath(const std::string& path, const std::string& file)
{
  const size_t slash = path.find_last_of('/');
  return file.empty() || file[0] == '/' || slash == std::string::npos
    ? file
    : path.substr(0, slash + 1) + file;
}

// Throws unless `file`, a data file that the header `path` names (relative
// to the header's directory unless absolute), is a regular file: a FIFO
// made VTK's readers wait for a writer, a device (/dev/urandom) was read as
// samples.
unsigned long long CheckNamedDataFile(
  const std::string& path, const std::string& what, const std::string& file)
{
  const std::string full = DataFilePath(path, file);
  struct stat st;
  if (stat(full.c_str(), &st) != 0)
  {
    Unreadable(path, what + " names '" + file + "': " + std::strerror(errno));
  }
  if (!S_ISREG(st.st_mode))
  {
    Unreadable(path, what + " names '" + file + "', which is not a regular file (VTK's reader " +
        (S_ISFIFO(st.st_mode) ? "would wait for a writer" : "would read it as samples") + ")");
  }
  return static_cast<unsigned long long>(st.st_size);
}

// Bytes of a value of a NRRD type (its name in lower case, any of the
// spellings NRRD allows); 0 for a name not known.
int NrrdTypeBytes(const std::string& type)
{
  static const std::pair<const char*, int> types[] = { { "signed char", 1 }, { "int8", 1 },
    { "int8_t", 1 }, { "uchar", 1 }, { "unsigned char", 1 }, { "uint8", 1 }, { "uint8_t", 1 },
    { "short", 2 }, { "short int", 2 }, { "signed short", 2 }, { "signed short int", 2 },
    { "int16", 2 }, { "int16_t", 2 }, { "ushort", 2 }, { "unsigned short", 2 },
    { "unsigned short int", 2 }, { "uint16", 2 }, { "uint16_t", 2 }, { "int", 4 },
    { "signed int", 4 }, { "int32", 4 }, { "int32_t", 4 }, { "uint", 4 }, { "unsigned int", 4 },
    { "uint32", 4 }, { "uint32_t", 4 }, { "longlong", 8 }, { "long long", 8 },
    { "long long int", 8 }, { "signed long long", 8 }, { "signed long long int", 8 },
    { "int64", 8 }, { "int64_t", 8 }, { "ulonglong", 8 }, { "unsigned long long", 8 },
    { "unsigned long long int", 8 }, { "uint64", 8 }, { "uint64_t", 8 }, { "float", 4 },
    { "double", 8 } };
  for (const auto& t : types)
  {
    if (type == t.first)
    {
      return t.second;
    }
  }
  return 0;
}

// The data files a detached NRRD header names, as VTK 9.1's reader takes
// them ("data file: NAME", "data file: PATTERN MIN MAX STEP [SUBDIM]", or
// "data file: LIST" and a name a line): each must be a regular file, and a
// pattern an integer one (SlicePatternProblem()) naming one file a slice.
// A step of 0 or less made the reader name files without end (memory grew
// by 250 MB/s), and a range of 10^9 built as many names.
void CheckNrrdDataFiles(const std::string& path, const std::string& dataFile,
  const std::vector<std::string>& listed, const std::vector<long long>& sizes,
  const std::string& encoding, int valueBytes)
{
  if (dataFile.empty())
  {
    return;
  }
  const long long slices = sizes.empty() ? 0 : sizes.back();
  const bool gzip = encoding == "gzip" || encoding == "gz";
  const std::vector<std::string> words = Words(dataFile);
  const std::string what = "its data file field (" + dataFile + ")";
  if (words[0] == "LIST")
  {
    if (listed.empty())
    {
      Unreadable(path, what + " lists no file on the lines after it");
    }
    for (const std::string& file : listed)
    {
      CheckNamedDataFile(path, "its data file list", file);
    }
    // One file a slice: fewer made VTK's reader take a name past the list
    // (SIGSEGV), more were ignored.
    if (listed.size() > 1 && static_cast<long long>(listed.size()) != slices)
    {
      Unreadable(path, what + " lists " + std::to_string(listed.size()) + " files for " +
          std::to_string(slices) + " slices: VTK's NRRD reader reads one file a slice");
    }
    if (listed.size() > 1 && gzip)
    {
      Unreadable(path, "its gzip slice files: VTK's NRRD reader inflates the first only and "
                       "leaves the other slices unwritten (use raw slice files, or one file)");
    }
    return;
  }
  if (words.size() < 4)
  {
    const unsigned long long have = CheckNamedDataFile(path, "its data file field", dataFile);
    // VTK's reader takes what a data file holds beyond the samples for a
    // header before them (raw), or the compressed size beyond the samples'
    // for one (gzip: incompressible data read as garbage, exit status 0),
    // where NRRD puts the data at its start.
    unsigned long long need = valueBytes > 0 ? static_cast<unsigned long long>(valueBytes) : 0;
    for (long long n : sizes)
    {
      need = n > 0 && need <= (1ULL << 62) / static_cast<unsigned long long>(n)
        ? need * static_cast<unsigned long long>(n)
        : 0;
    }
    if (need > 0 && have > need)
    {
      Unreadable(path, "its data file '" + dataFile + "' holds " + std::to_string(have) +
          " bytes, more than the " + std::to_string(need) + " its samples take" +
          (gzip ? " uncompressed" : "") + ": VTK's NRRD reader would skip the first " +
          std::to_string(have - need) + " as a header");
    }
    return;
  }
  const std::string problem = SlicePatternProblem(words[0]);
  if (!problem.empty())
  {
    Unreadable(path, "the pattern of " + what + " " + problem);
  }
  // The reader's own reading of the numbers (atoi).
  const long long first = std::atoi(words[1].c_str());
  const long long last = std::atoi(words[2].c_str());
  const long long step = std::atoi(words[3].c_str());
  if (step <= 0)
  {
    Unreadable(path, what + " steps by " + std::to_string(step) +
        ": VTK's NRRD reader would name files without end");
  }
  const long long files = last < first ? 0 : (last - first) / step + 1;
  if (files > MaxSliceFiles)
  {
    Unreadable(path, what + " names " + std::to_string(files) + " files, more than the " +
        std::to_string(MaxSliceFiles) + " slice files read");
  }
  if (files != slices)
  {
    Unreadable(path, what + " names " + std::to_string(files) + " file" +
        (files == 1 ? "" : "s") + " (" + std::to_string(first) + " to " + std::to_string(last) +
        " by " + std::to_string(step) + ") for " + std::to_string(slices) +
        " slices: VTK's NRRD reader reads one file a slice");
  }
  if (gzip && files > 1)
  {
    Unreadable(path, "its gzip slice files: VTK's NRRD reader inflates the first only and "
                     "leaves the other slices unwritten (use raw slice files, or one file)");
  }
  char name[4096];
  for (long long i = first; i <= last; i += step)
  {
    std::snprintf(name, sizeof(name), words[0].c_str(), static_cast<int>(i));
    CheckNamedDataFile(path, what, name);
  }
}

// What VTK 9.1's NRRD reader would misread, crash or hang on, refused
// before it sees the file: ASCII data after an attached header (read as
// garbage without an error), an attached header that no blank line ends
// (its reader then never returns), sizes that are not positive integers
// (an allocation of a negative size), a dimension other than 3 or 4
// or missing, or not the number of sizes (it read past the end of its
// image, or a volume the header does not describe), and a 4D header whose
// first axis is spatial (read as vector components). Returns the header's
// sizes, which the caller compares with what the reader made of them, and
// its space directions and origin (see NrrdFrame).
struct NrrdHeader
{
  std::vector<long long> sizes;
  std::string directions; // the "space directions" value, "" if absent
  std::string origin;     // the "space origin" value, "" if absent
};

NrrdHeader CheckNrrdHeader(const std::string& path)
{
  NrrdHeader header;
  std::ifstream in(path, std::ios::binary);
  std::string line;
  bool ascii = false;
  bool detached = false;
  bool ended = false;
  std::string dimension;
  std::string firstKind;      // of the first axis, "" if not given
  std::string firstDirection; // of the first axis, "" if not given
  std::vector<long long> sizes;
  // A header is a few hundred bytes: past a megabyte without a blank line
  // it is data.
  size_t read = 0;
  const size_t headerLimit = size_t(1) << 20;
  size_t controlAt = std::string::npos; // of the first control byte
  unsigned char controlByte = 0;
  std::string badSizes; // the first sizes value that is not all positive integers
  // The magic line first: another format under a NRRD name (a MetaImage
  // header renamed) was refused for a missing blank line, which misled.
  char magic[7] = {};
  if (!in.read(magic, sizeof(magic)) || std::string(magic, sizeof(magic)) != "NRRD000")
  {
    Unreadable(path, "it is not a NRRD file (it does not begin with the magic 'NRRD000')");
  }
  in.seekg(0);
  bool unterminated = false;     // the last line read had no newline
  bool sizesFirst = false;       // a sizes field before the dimension field
  std::string encoding = "raw";  // lower case
  int valueBytes = 0;            // of the type field's type, 0 if unknown
  std::string dataFile;          // the "data file" value, "" if absent
  bool listing = false;          // reading the files after "data file: LIST"
  std::vector<std::string> listed;
  while (read < headerLimit && std::getline(in, line))
  {
    unterminated = in.eof();
    const size_t lineStart = read;
    read += line.size() + 1;
    if (!line.empty() && line.back() == '\r')
    {
      line.pop_back();
    }
    if (line.empty())
    {
      ended = true; // the end of the header
      break;
    }
    if (listing)
    {
      // VTK's reader takes every line after LIST for a file, trimmed.
      std::string file = line;
      file.erase(0, file.find_first_not_of(" \t"));
      file.erase(file.find_last_not_of(" \t") + 1);
      if (file.empty())
      {
        break;
      }
      listed.push_back(file);
      continue;
    }
    // A NUL (or another control byte) in the header: VTK's reader then
    // never returned, or crashed. A header is text; tabs are allowed.
    // Refused after the loop: without a blank line ending the header,
    // these lines may be data, and that is the error to report.
    const auto control = std::find_if(line.begin(), line.end(), [](char c) {
      const unsigned char u = static_cast<unsigned char>(c);
      return (u < 0x20 && u != '\t' && u != '\r') || u == 0x7f;
    });
    if (control != line.end() && controlAt == std::string::npos)
    {
      controlAt = lineStart + static_cast<size_t>(control - line.begin());
      controlByte = static_cast<unsigned char>(*control);
    }
    // A field as VTK's reader takes it: its exact name, ": ", its value
    // (trimmed). A name in other case or without the blank after the colon
    // is a field it does not know: "SIZES:" or "dimension:3" left it
    // reading into an image it never allocated (SIGSEGV), so they count
    // as missing here too. Comments and "key:=value" pairs aside.
    const size_t delimiter = line.find(": ");
    if (line[0] == '#' || delimiter == std::string::npos)
    {
      continue;
    }
    const std::string field = line.substr(0, delimiter);
    std::string description = line.substr(delimiter + 2);
    description.erase(0, description.find_first_not_of(" \t"));
    description.erase(description.find_last_not_of(" \t") + 1);
    std::string lower = description;
    std::transform(lower.begin(), lower.end(), lower.begin(),
      [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (field == "encoding")
    {
      ascii = lower == "ascii" || lower == "text" || lower == "txt";
      encoding = lower;
    }
    if (field == "type")
    {
      valueBytes = NrrdTypeBytes(lower);
    }
    if (field == "data file" || field == "datafile")
    {
      detached = true;
      dataFile = description;
      listing = dataFile.compare(0, 4, "LIST") == 0;
    }
    if (field == "dimension")
    {
      dimension = description;
    }
    if (field == "kinds")
    {
      std::istringstream(lower) >> firstKind;
    }
    if (field == "space directions")
    {
      // "(1,0,0) (0,1,0) ..." or "none ...": the first entry up to its
      // closing parenthesis.
      firstDirection =
        lower.compare(0, 4, "none") == 0 ? "none" : lower.substr(0, lower.find(')') + 1);
      header.directions = lower;
    }
    if (field == "space origin")
    {
      header.origin = lower;
    }
    if (field == "sizes")
    {
      sizesFirst = sizesFirst || dimension.empty();
      const std::string& v = description;
      std::istringstream tokens(v);
      std::string token;
      sizes.clear();
      while (tokens >> token)
      {
        char* rest = nullptr;
        errno = 0;
        long long n = std::strtoll(token.c_str(), &rest, 10);
        if ((token.empty() || *rest != '\0' || errno != 0 || n < 1) && badSizes.empty())
        {
          badSizes = v; // refused after the loop, with the control bytes first
        }
        sizes.push_back(n);
      }
    }
  }
  if (!ended && !detached)
  {
    Unreadable(path, "no blank line ends the header before the data (VTK's NRRD reader would "
                     "never stop reading it)");
  }
  if (!ended && read >= headerLimit)
  {
    // (A detached header: its lines past the window went unchecked, and
    // VTK's reader crashed or hung on them.)
    Unreadable(path, "its header does not end within its first " +
        std::to_string(headerLimit >> 20) + " MiB");
  }
  if (!ended && unterminated)
  {
    Unreadable(path, "the header's last line ends without a newline (VTK's NRRD reader would "
                     "never stop reading it)");
  }
  if (controlAt != std::string::npos)
  {
    char code[8];
    std::snprintf(code, sizeof(code), "0x%02x", controlByte);
    Unreadable(path, std::string("its header holds a control byte (") + code + ") at byte " +
        std::to_string(controlAt) + ", which VTK's NRRD reader hangs or crashes on: a header "
        "is text");
  }
  if (!badSizes.empty())
  {
    Unreadable(path, "the header's sizes (" + badSizes + ") are not all positive integers");
  }
  if (ascii)
  {
    // Attached, it read garbage; detached, characters as samples (range
    // 48..57) and unwritten memory for values it could not parse.
    Unreadable(path, "ASCII-encoded NRRD data, which VTK's reader does not read correctly: use "
                     "raw or gzip encoding");
  }
  if (dimension.empty())
  {
    Unreadable(path, "the header has no dimension field");
  }
  if (dimension != "3" && dimension != "4")
  {
    Unreadable(path, "the header declares dimension " + dimension +
        ": VTK's NRRD reader reads volumes of dimension 3 (or 4, the first axis being vector "
        "components)");
  }
  if (sizesFirst)
  {
    // VTK's reader sizes its list of sizes by the dimension read so far.
    Unreadable(path, "its sizes field comes before its dimension field (VTK's NRRD reader "
                     "then reads no size, and crashed)");
  }
  if (sizes.size() != static_cast<size_t>(dimension[0] - '0'))
  {
    Unreadable(path, "the header declares dimension " + dimension + " but " +
        std::to_string(sizes.size()) + " sizes");
  }
  // Of 4 axes the reader takes the first for vector components, whatever
  // the header says of it: a time series (x y z t) would be read as
  // y z t samples of x components.
  const std::string misread = "VTK's NRRD reader takes the first of 4 axes for vector "
                              "components, and the header makes it ";
  const std::string instead = " (write the volume as .mha, .nii or .vti, one file per "
                              "3D volume)";
  if (dimension == "4" && (firstKind == "domain" || firstKind == "space" || firstKind == "time"))
  {
    Unreadable(path, misread + "a '" + firstKind + "' axis" + instead);
  }
  if (dimension == "4" && !firstDirection.empty() && firstDirection != "none")
  {
    Unreadable(path, misread + "a spatial axis (space direction " + firstDirection + ")" + instead);
  }
  CheckNrrdDataFiles(path, dataFile, listed, sizes, encoding, valueBytes);
  header.sizes = sizes;
  return header;
}

// The vectors "(x,y,z)" of a NRRD field value, in order, "none" entries
// left out; throws when an entry is neither.
std::vector<std::array<double, 3>> NrrdVectors(
  const std::string& path, const std::string& field, const std::string& value)
{
  std::vector<std::array<double, 3>> out;
  size_t at = 0;
  const auto bad = [&]() {
    Unreadable(path, "its " + field + " (" + value + ") are not vectors of three numbers");
  };
  while ((at = value.find_first_not_of(" \t", at)) != std::string::npos)
  {
    if (value.compare(at, 4, "none") == 0)
    {
      at += 4;
      continue;
    }
    const size_t close = value.find(')', at);
    if (value[at] != '(' || close == std::string::npos)
    {
      bad();
    }
    std::array<double, 3> v{};
    std::string inner = value.substr(at + 1, close - at - 1);
    std::replace(inner.begin(), inner.end(), ',', ' ');
    std::istringstream numbers(inner);
    std::string extra;
    if (!(numbers >> v[0] >> v[1] >> v[2]) || (numbers >> extra) || !std::isfinite(v[0]) ||
      !std::isfinite(v[1]) || !std::isfinite(v[2]))
    {
      bad();
    }
    out.push_back(v);
    at = close + 1;
  }
  return out;
}

// Places `volume` in the world frame its header gives: a world point is
// origin + direction x (spacing * index), `direction` row-major. Throws
// when the frame cannot be an image's (a singular direction).
void SetFrame(vtkImageData* volume, const std::string& path, const double direction[9],
  const double spacing[3], const double origin[3])
{
  const double* d = direction;
  const double det = d[0] * (d[4] * d[8] - d[5] * d[7]) - d[1] * (d[3] * d[8] - d[5] * d[6]) +
    d[2] * (d[3] * d[7] - d[4] * d[6]);
  if (!std::isfinite(det) || std::fabs(det) < 1e-6)
  {
    Unreadable(path, "its header's orientation matrix is singular");
  }
  volume->SetDirectionMatrix(direction);
  volume->SetSpacing(spacing[0], spacing[1], spacing[2]);
  volume->SetOrigin(origin[0], origin[1], origin[2]);
}

// NRRD: each spatial axis's space direction is its step in the world (the
// reader kept only their lengths, as spacing), and the space origin is the
// world position of the first sample. Coordinates are the file's space's
// own (no change between LPS and RAS).
void ApplyNrrdFrame(vtkImageData* volume, const std::string& path, const NrrdHeader& header)
{
  if (header.directions.empty() && header.origin.empty())
  {
    return;
  }
  double direction[9] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
  double spacing[3];
  double origin[3];
  volume->GetSpacing(spacing);
  volume->GetOrigin(origin);
  if (!header.directions.empty())
  {
    const auto axes = NrrdVectors(path, "space directions", header.directions);
    if (axes.size() != 3)
    {
      Unreadable(path, "its space directions (" + header.directions + ") give " +
          std::to_string(axes.size()) + " spatial axes, not 3");
    }
    for (int a = 0; a < 3; ++a)
    {
      const double length = std::sqrt(
        axes[a][0] * axes[a][0] + axes[a][1] * axes[a][1] + axes[a][2] * axes[a][2]);
      if (!(length > 0.0) || !std::isfinite(length))
      {
        Unreadable(path, "its space direction of axis " + std::to_string(a) + " has no length");
      }
      spacing[a] = length;
      for (int r = 0; r < 3; ++r)
      {
        direction[3 * r + a] = axes[a][r] / length;
      }
    }
  }
  if (!header.origin.empty())
  {
    const auto o = NrrdVectors(path, "space origin", header.origin);
    if (o.size() != 1)
    {
      Unreadable(path, "its space origin (" + header.origin + ") is not one vector");
    }
    std::copy(o[0].begin(), o[0].end(), origin);
  }
  SetFrame(volume, path, direction, spacing, origin);
}

// MetaImage: TransformMatrix (or its other names, Rotation and
// Orientation) holds each axis's direction in turn, three numbers an axis
// (ITK's convention); VTK 9.1's reader reads the Offset as the origin but
// leaves the matrix out.
std::string FileHead(const std::string& path, size_t bytes);

// One "Key = value" line of a MetaImage header, and the byte offset just
// past it in the file.
struct MetaField
{
  std::string key;
  std::string value;
  size_t end;
};

// `t` without the blanks around it (and a line's closing '\r').
std::string TrimHeaderText(std::string t)
{
  t.erase(0, t.find_first_not_of(" \t"));
  t.erase(t.find_last_not_of(" \t\r") + 1);
  return t;
}

// The bytes of a MetaImage file its header must end in (see
// CheckMetaImageHeaderLines()).
const size_t MetaImageHeaderLimit = size_t(1) << 16;

// The fields of a MetaImage header, up to ElementDataFile (the last, after
// which LOCAL data starts), keys and values trimmed.
std::vector<MetaField> MetaImageFields(const std::string& path)
{
  std::vector<MetaField> fields;
  std::istringstream header(FileHead(path, MetaImageHeaderLimit));
  std::string line;
  size_t consumed = 0;
  while (std::getline(header, line))
  {
    consumed += line.size() + 1;
    const size_t eq = line.find('=');
    if (eq == std::string::npos)
    {
      continue;
    }
    fields.push_back(
      { TrimHeaderText(line.substr(0, eq)), TrimHeaderText(line.substr(eq + 1)), consumed });
    if (fields.back().key == "ElementDataFile")
    {
      break; // the end of the header
    }
  }
  return fields;
}

// The fields of a MetaImage header that lay its data out.
struct MetaImageLayout
{
  std::vector<long long> dims; // DimSize
  long long channels = 1;      // ElementNumberOfChannels
  int elementSize = 0;         // bytes of an ElementType value; 0: a type of unknown size
  bool compressed = false;     // CompressedData
  long long compressedSize = -1; // CompressedDataSize (bytes read), -1 if absent
  std::string dataFile;        // ElementDataFile
  size_t dataOffset = 0;       // just past the ElementDataFile line (LOCAL data, a LIST)
};

MetaImageLayout ReadMetaImageLayout(const std::string& path)
{
  MetaImageLayout layout;
  for (const MetaField& field : MetaImageFields(path))
  {
    std::istringstream values(field.value);
    if (field.key == "CompressedData")
    {
      // MetaIO's boolean: true when it starts with T, t or 1 ("TRUE", "1").
      const char first = field.value.empty() ? '\0' : field.value[0];
      layout.compressed = first == 'T' || first == 't' || first == '1';
    }
    else if (field.key == "DimSize")
    {
      long long n;
      while (values >> n)
      {
        layout.dims.push_back(n);
      }
    }
    else if (field.key == "CompressedDataSize")
    {
      values >> layout.compressedSize;
    }
    else if (field.key == "ElementNumberOfChannels")
    {
      values >> layout.channels;
    }
    else if (field.key == "ElementType")
    {
      static const std::pair<const char*, int> sizes[] = { { "MET_CHAR", 1 }, { "MET_UCHAR", 1 },
        { "MET_SHORT", 2 }, { "MET_USHORT", 2 }, { "MET_INT", 4 }, { "MET_UINT", 4 },
        { "MET_FLOAT", 4 }, { "MET_LONG_LONG", 8 }, { "MET_ULONG_LONG", 8 },
        { "MET_DOUBLE", 8 } };
      for (const auto& size : sizes)
      {
        layout.elementSize = field.value == size.first ? size.second : layout.elementSize;
      }
    }
    else if (field.key == "ElementDataFile")
    {
      layout.dataFile = field.value;
      layout.dataOffset = field.end;
    }
  }
  return layout;
}

void ApplyMetaImageFrame(vtkImageData* volume, const std::string& path)
{
  for (const MetaField& field : MetaImageFields(path))
  {
    const std::string& key = field.key;
    if (key != "TransformMatrix" && key != "Rotation" && key != "Orientation")
    {
      continue;
    }
    std::istringstream numbers(field.value);
    double m[9];
    std::string extra;
    bool good = true;
    for (double& x : m)
    {
      good = good && (numbers >> x) && std::isfinite(x);
    }
    if (!good || (numbers >> extra))
    {
      Unreadable(path, "its " + key + " is not nine numbers");
    }
    double direction[9];
    for (int a = 0; a < 3; ++a)
    {
      for (int r = 0; r < 3; ++r)
      {
        direction[3 * r + a] = m[3 * a + r];
      }
    }
    double spacing[3];
    double origin[3];
    volume->GetSpacing(spacing);
    volume->GetOrigin(origin);
    SetFrame(volume, path, direction, spacing, origin);
    return;
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

template <class In, class Out>
void ScaleValues(const In* in, Out* out, vtkIdType n, double slope, double intercept)
{
  for (vtkIdType i = 0; i < n; ++i)
  {
    out[i] = static_cast<Out>(static_cast<double>(in[i]) * slope + intercept);
  }
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

// The value of attribute `name` in the XML start tag `tag`, as XML writes
// it: spaces allowed around the '=', the value in double or single
// quotes. False when the tag has no such attribute.
bool FindXmlAttribute(const std::string& tag, const std::string& name, std::string& value)
{
  const auto space = [&tag](size_t i) {
    return i < tag.size() && std::isspace(static_cast<unsigned char>(tag[i]));
  };
  for (size_t at = tag.find(name); at != std::string::npos; at = tag.find(name, at + 1))
  {
    // A whole attribute name, not the end of a longer one.
    if (at > 0 && !space(at - 1))
    {
      continue;
    }
    size_t i = at + name.size();
    while (space(i))
    {
      ++i;
    }
    if (i >= tag.size() || tag[i] != '=')
    {
      continue;
    }
    ++i;
    while (space(i))
    {
      ++i;
    }
    if (i >= tag.size() || (tag[i] != '"' && tag[i] != '\''))
    {
      continue;
    }
    const size_t end = tag.find(tag[i], i + 1);
    value = end == std::string::npos ? "" : tag.substr(i + 1, end - i - 1);
    return true;
  }
  return false;
}

// The bytes of a .vti file its checks read for the XML part (a large
// ASCII FieldData array before the data, or a long comment, pushed the
// tags a 64 KiB or 1 MiB window held out of it, and the checks passed).
const size_t VtiXmlWindow = size_t(1) << 24;

// Where `tag` (as "<ImageData") starts in `xml` from `from` on, outside
// its comments ("<!-- ... -->"; an unclosed one runs to the end);
// npos if nowhere. A tag written in a comment is none: an <ImageData
// Origin="0 0 0"> or an <AppendedData> there was checked in place of the
// real one, and a NaN origin or a cut block passed.
size_t FindTag(const std::string& xml, const std::string& tag, size_t from = 0)
{
  size_t at = xml.find(tag, from);
  size_t open = xml.find("<!--");
  while (at != std::string::npos && open != std::string::npos && open <= at)
  {
    const size_t close = xml.find("-->", open + 4);
    if (close == std::string::npos)
    {
      return std::string::npos; // inside a comment that runs to the end
    }
    if (at < close + 3)
    {
      at = xml.find(tag, close + 3); // inside this comment: look past it
    }
    open = xml.find("<!--", close + 3);
  }
  return at;
}

// The value of attribute `name` in the XML start tag `tag` ("" if absent).
std::string XmlAttribute(const std::string& tag, const std::string& name)
{
  std::string value;
  return FindXmlAttribute(tag, name, value) ? value : "";
}

// The first `bytes` bytes of a file (fewer if it is shorter; "" if it
// cannot be opened).
std::string FileHead(const std::string& path, size_t bytes)
{
  std::ifstream in(path, std::ios::binary);
  std::string head(in ? bytes : 0, '\0');
  in.read(&head[0], static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(std::max<std::streamsize>(in.gcount(), 0)));
  return head;
}

// A .vti whose <ImageData> Origin, Spacing or Direction is not 3 (9 for
// Direction) finite numbers: VTK's reader drops an attribute it cannot
// parse ("NaN", "Infinity", a word, too few numbers, none) and uses the
// default (origin 0, spacing 1, identity) without a word, so the surface
// came out at a place and scale the file does not give.
void CheckVtiGeometry(const std::string& path)
{
  const std::string head = FileHead(path, VtiXmlWindow);
  const size_t tag = FindTag(head, "<ImageData");
  const size_t end = tag == std::string::npos ? tag : head.find('>', tag);
  if (end == std::string::npos)
  {
    return;
  }
  const std::string element = head.substr(tag, end - tag);
  for (const auto& attribute : { std::make_pair("Origin", 3), std::make_pair("Spacing", 3),
         std::make_pair("Direction", 9) })
  {
    const std::string name = attribute.first;
    std::string value;
    if (!FindXmlAttribute(element, name, value))
    {
      continue;
    }
    std::istringstream words(value);
    std::string word;
    int count = 0;
    bool finite = true;
    while (words >> word)
    {
      char* stop = nullptr;
      const double v = std::strtod(word.c_str(), &stop);
      finite = finite && stop == word.c_str() + word.size() && std::isfinite(v);
      ++count;
    }
    if (!finite || count != attribute.second)
    {
      Unreadable(path, "its " + name + " \"" + value + "\" is not " +
          std::to_string(attribute.second) + " finite numbers (VTK's reader would use the "
          "default instead)");
    }
  }
}

// The bytes that base64 `text` (whitespace ignored) starts with, at most
// `bytes` of them; fewer where the text ends, pads or is not base64.
std::string Base64Prefix(const std::string& text, size_t bytes)
{
  std::string out;
  unsigned bits = 0;
  int held = 0;
  for (char c : text)
  {
    if (out.size() >= bytes || c == '=')
    {
      break;
    }
    if (std::isspace(static_cast<unsigned char>(c)))
    {
      continue;
    }
    const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    const char* at = std::strchr(digits, c);
    if (!at || c == '\0')
    {
      break;
    }
    bits = (bits << 6) | static_cast<unsigned>(at - digits);
    held += 6;
    if (held >= 8)
    {
      held -= 8;
      out.push_back(static_cast<char>((bits >> held) & 0xff));
    }
  }
  return out;
}

// The byte count in an uncompressed block's header (header_type's size,
// the file's byte order); false when `header` is shorter.
bool BlockByteCount(const std::string& header, int headerSize, bool bigEndian,
  unsigned long long& count)
{
  if (header.size() < static_cast<size_t>(headerSize))
  {
    return false;
  }
  count = 0;
  for (int b = 0; b < headerSize; ++b)
  {
    count |= static_cast<unsigned long long>(static_cast<unsigned char>(
               header[static_cast<size_t>(bigEndian ? headerSize - 1 - b : b)]))
      << (8 * b);
  }
  return true;
}

// The base64 characters of an uncompressed block of `count` bytes: VTK 9.1
// encodes the header and the data as one stream (a 40^3 float array with a
// UInt32 header is 4 * ceil(256004 / 3) characters, not the header's 8 plus
// the data's), padded at its end. A header encoded on its own, padded, as
// compressed blocks have it, needs more: a file written so passes too.
unsigned long long Base64BlockSize(int headerSize, unsigned long long count)
{
  return (static_cast<unsigned long long>(headerSize) + count + 2) / 3 * 4;
}

// A .vti whose uncompressed appended data was cut short: VTK 9.1's reader
// fills the missing values with zeros or garbage and reports nothing. Each
// array's block (a byte count of header_type, then the bytes; base64
// encoded as one stream with encoding="base64") must end within the file,
// before its closing </AppendedData> if it has one. (Compressed data is
// not looked at here: its reader fails on a cut block.)
void CheckAppendedData(const std::string& path)
{
  // The XML part comes first; the appended data follows the '_' after
  // <AppendedData ...>.
  const std::string head = FileHead(path, VtiXmlWindow);
  std::ifstream in(path, std::ios::binary);
  if (!in)
  {
    return;
  }
  const size_t appended = FindTag(head, "<AppendedData");
  const size_t fileTag = FindTag(head, "<VTKFile");
  if (appended == std::string::npos || fileTag == std::string::npos)
  {
    return;
  }
  const std::string vtkFile = head.substr(fileTag, head.find('>', fileTag) - fileTag);
  const size_t appendedEnd = head.find('>', appended);
  const std::string encoding = appendedEnd == std::string::npos
    ? std::string()
    : XmlAttribute(head.substr(appended, appendedEnd - appended), "encoding");
  const bool base64 = encoding == "base64";
  if ((encoding != "raw" && !base64) || !XmlAttribute(vtkFile, "compressor").empty())
  {
    return;
  }
  const size_t underscore = head.find('_', appendedEnd);
  if (underscore == std::string::npos)
  {
    return;
  }
  const unsigned long long dataStart = underscore + 1;
  const int headerSize = XmlAttribute(vtkFile, "header_type") == "UInt64" ? 8 : 4;
  const bool bigEndian = XmlAttribute(vtkFile, "byte_order") == "BigEndian";
  // The characters of an encoded header, and the bytes they decode to.
  const int headerChars = (headerSize + 2) / 3 * 4;
  in.clear();
  in.seekg(0, std::ios::end);
  unsigned long long fileSize = static_cast<unsigned long long>(in.tellg());
  // The data ends before the closing tag, when the file still has it.
  {
    const unsigned long long tailSize = std::min<unsigned long long>(fileSize, 4096);
    std::string tail(static_cast<size_t>(tailSize), '\0');
    in.seekg(static_cast<std::streamoff>(fileSize - tailSize));
    in.read(&tail[0], static_cast<std::streamsize>(tailSize));
    const size_t closing = tail.rfind("</AppendedData>");
    if (in.gcount() == static_cast<std::streamsize>(tailSize) && closing != std::string::npos &&
      fileSize - tailSize + closing >= dataStart)
    {
      fileSize = fileSize - tailSize + closing;
    }
    in.clear();
  }
  for (size_t at = FindTag(head, "<DataArray"); at != std::string::npos && at < appended;
       at = FindTag(head, "<DataArray", at + 1))
  {
    const std::string tag = head.substr(at, head.find('>', at) - at);
    const std::string offsetText = XmlAttribute(tag, "offset");
    if (XmlAttribute(tag, "format") != "appended" || offsetText.empty())
    {
      continue;
    }
    const unsigned long long offset = std::strtoull(offsetText.c_str(), nullptr, 10);
    const unsigned long long block = dataStart + offset;
    const int stored = base64 ? headerChars : headerSize;
    std::string header(static_cast<size_t>(stored), '\0');
    unsigned long long count = 0;
    bool complete = block + stored <= fileSize;
    if (complete)
    {
      in.seekg(static_cast<std::streamoff>(block));
      in.read(&header[0], stored);
      complete = in.gcount() == stored &&
        BlockByteCount(base64 ? Base64Prefix(header, headerSize) : header, headerSize,
          bigEndian, count) &&
        count <= fileSize;
      in.clear();
    }
    if (complete)
    {
      const unsigned long long size =
        base64 ? Base64BlockSize(headerSize, count) : headerSize + count;
      complete = block + size <= fileSize;
    }
    if (!complete)
    {
      Unreadable(path,
        "the appended data of array '" + XmlAttribute(tag, "Name") +
          "' ends past the end of the file (is the file complete?)");
    }
  }
}

// A compressed .vti array whose block header (header_type words: the
// number of blocks, the size of a block, the size of the last one, then
// each block's compressed size) gives no block, blocks of 0 bytes, or a
// last block larger than a block: VTK 9.1's reader dereferenced a null
// block (SIGSEGV) or divided by the block size (SIGFPE). Appended (raw or
// base64) and inline arrays, in the XML window of the file; an array of no
// tuples may have no block.
void CheckCompressedBlockHeaders(const std::string& path)
{
  const std::string head = FileHead(path, VtiXmlWindow);
  const size_t fileTag = FindTag(head, "<VTKFile");
  if (fileTag == std::string::npos)
  {
    return;
  }
  const std::string vtkFile = head.substr(fileTag, head.find('>', fileTag) - fileTag);
  if (XmlAttribute(vtkFile, "compressor").empty())
  {
    return;
  }
  const int headerSize = XmlAttribute(vtkFile, "header_type") == "UInt64" ? 8 : 4;
  const bool bigEndian = XmlAttribute(vtkFile, "byte_order") == "BigEndian";
  const size_t words = static_cast<size_t>(3 * headerSize);
  const size_t appended = FindTag(head, "<AppendedData");
  const size_t appendedEnd = appended == std::string::npos ? appended : head.find('>', appended);
  const bool base64 = appendedEnd != std::string::npos &&
    XmlAttribute(head.substr(appended, appendedEnd - appended), "encoding") == "base64";
  const size_t underscore =
    appendedEnd == std::string::npos ? std::string::npos : head.find('_', appendedEnd);
  std::ifstream in(path, std::ios::binary);
  for (size_t at = FindTag(head, "<DataArray"); at != std::string::npos && at < appended;
       at = FindTag(head, "<DataArray", at + 1))
  {
    const size_t close = head.find('>', at);
    if (close == std::string::npos)
    {
      return;
    }
    const std::string tag = head.substr(at, close - at);
    const std::string format = XmlAttribute(tag, "format");
    std::string header; // the first three words of the block header
    if (format == "binary")
    {
      header = Base64Prefix(head.substr(close + 1, 4 * words), words);
    }
    else if (format == "appended" && underscore != std::string::npos)
    {
      const unsigned long long offset =
        std::strtoull(XmlAttribute(tag, "offset").c_str(), nullptr, 10);
      const size_t stored = base64 ? (words + 2) / 3 * 4 : words;
      std::string raw(stored, '\0');
      in.clear();
      in.seekg(static_cast<std::streamoff>(underscore + 1 + offset));
      in.read(&raw[0], static_cast<std::streamsize>(stored));
      raw.resize(static_cast<size_t>(std::max<std::streamsize>(0, in.gcount())));
      header = base64 ? Base64Prefix(raw, words) : raw;
    }
    else
    {
      continue;
    }
    unsigned long long blocks = 0, blockSize = 0, lastSize = 0;
    if (!BlockByteCount(header, headerSize, bigEndian, blocks) ||
      !BlockByteCount(header.substr(static_cast<size_t>(headerSize)), headerSize, bigEndian,
        blockSize) ||
      !BlockByteCount(header.substr(static_cast<size_t>(2 * headerSize)), headerSize, bigEndian,
        lastSize))
    {
      continue; // cut short: the reader says so
    }
    if (XmlAttribute(tag, "NumberOfTuples") == "0" && blocks == 0)
    {
      continue;
    }
    if (blocks == 0 || blockSize == 0 || lastSize > blockSize)
    {
      Unreadable(path, "the compressed data of array '" + XmlAttribute(tag, "Name") +
          "' has a block header of " + std::to_string(blocks) + " blocks of " +
          std::to_string(blockSize) + " bytes, the last of " + std::to_string(lastSize) +
          ", which VTK's XML reader crashes on");
    }
  }
}

// A .vti whose uncompressed inline binary (base64) DataArray holds fewer
// characters than its header's byte count needs (cut short, the element
// closed again): VTK 9.1's reader reads on into the closing tag and fills
// the rest with garbage, without a word. The file is read through once,
// up to any <AppendedData> (raw bytes follow it).
void CheckInlineBinaryData(const std::string& path)
{
  // (Any spelling of the attribute: format='binary' or format = "binary"
  // passed a search for the text format="binary", as did a first binary
  // array past the first 64 KiB.)
  const std::string head = FileHead(path, VtiXmlWindow);
  const size_t fileTag = head.find("<VTKFile");
  if (fileTag == std::string::npos || head.find("binary") == std::string::npos)
  {
    return;
  }
  const std::string vtkFile = head.substr(fileTag, head.find('>', fileTag) - fileTag);
  if (!XmlAttribute(vtkFile, "compressor").empty())
  {
    return;
  }
  const int headerSize = XmlAttribute(vtkFile, "header_type") == "UInt64" ? 8 : 4;
  const bool bigEndian = XmlAttribute(vtkFile, "byte_order") == "BigEndian";
  const size_t headerChars = static_cast<size_t>((headerSize + 2) / 3 * 4);
  std::ifstream in(path, std::ios::binary);
  std::istreambuf_iterator<char> it(in), end;
  while (it != end)
  {
    if (*it++ != '<')
    {
      continue;
    }
    std::string tag;
    while (it != end && *it != '>')
    {
      tag.push_back(*it++);
    }
    if (it != end)
    {
      ++it;
    }
    if (tag.compare(0, 12, "AppendedData") == 0)
    {
      return;
    }
    if (tag.compare(0, 9, "DataArray") != 0 || XmlAttribute(tag, "format") != "binary" ||
      (!tag.empty() && tag.back() == '/'))
    {
      continue;
    }
    // The element's text: its characters (whitespace aside) and the first
    // ones, which hold the header.
    std::string start;
    unsigned long long chars = 0;
    for (; it != end && *it != '<'; ++it)
    {
      if (!std::isspace(static_cast<unsigned char>(*it)))
      {
        ++chars;
        if (start.size() < headerChars)
        {
          start.push_back(*it);
        }
      }
    }
    unsigned long long count = 0;
    const bool hasHeader =
      BlockByteCount(Base64Prefix(start, static_cast<size_t>(headerSize)), headerSize, bigEndian,
        count);
    const unsigned long long need =
      hasHeader ? Base64BlockSize(headerSize, count) : headerChars;
    if (!hasHeader || chars < need)
    {
      Unreadable(path,
        "the binary data of array '" + XmlAttribute(tag, "Name") + "' is " +
          std::to_string(chars) + " base64 characters, fewer than the " + std::to_string(need) +
          " its size needs (is the file complete?)");
    }
  }
}

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
vtkStandardNewMacro(vtkPieceCheckingImageDataReader);

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

protected:
  vtkSliceListingDICOMReader() = default;
  ~vtkSliceListingDICOMReader() override = default;

private:
  vtkSliceListingDICOMReader(const vtkSliceListingDICOMReader&) = delete;
  void operator=(const vtkSliceListingDICOMReader&) = delete;
};
vtkStandardNewMacro(vtkSliceListingDICOMReader);

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

// A MetaImage header line whose key or value is 255 characters or longer
// (a long Name or Comment): MetaIO copies them into buffers of 255 bytes,
// and VTK 9.1's reader aborted ("buffer overflow detected"). A line
// without '=' counts as a key. Up to ElementDataFile, the header's end.
void CheckMetaImageHeaderLines(const std::string& path)
{
  const size_t limit = 254; // characters; the 255th byte ends the string
  std::istringstream header(FileHead(path, MetaImageHeaderLimit));
  std::string line;
  int number = 0;
  bool ended = false;
  while (std::getline(header, line))
  {
    ++number;
    const size_t eq = line.find('=');
    const std::string key = TrimHeaderText(line.substr(0, eq));
    const std::string value =
      eq == std::string::npos ? std::string() : TrimHeaderText(line.substr(eq + 1));
    if (key.size() > limit || value.size() > limit)
    {
      const bool longKey = key.size() > limit;
      Unreadable(path, "line " + std::to_string(number) + " of its header has a " +
          (longKey ? "key" : "value") + " of " +
          std::to_string(longKey ? key.size() : value.size()) + " characters" +
          (longKey ? std::string() : " ('" + key + "')") + ", more than the " +
          std::to_string(limit) + " VTK's MetaImage reader holds (it would abort)");
    }
    if (key == "NDims")
    {
      // MetaIO reads NDims numbers for each vector field: a negative or
      // huge count made VTK's reader loop without end.
      char* rest = nullptr;
      errno = 0;
      const long n = std::strtol(value.c_str(), &rest, 10);
      if (value.empty() || *rest != '\0' || errno != 0 || n < 1 || n > 10)
      {
        Unreadable(path, "line " + std::to_string(number) + " of its header gives NDims = " +
            value + ", not a number of dimensions from 1 to 10");
      }
    }
    if (key == "ElementDataFile")
    {
      ended = true; // the end of the header
      break;
    }
  }
  // Every check reads the header in this window: one that does not end in
  // it (thousands of comment lines first) was read by VTK's reader
  // unchecked, and crashed or hung as the checks say.
  if (!ended)
  {
    Unreadable(path, "no ElementDataFile line ends its header within its first " +
        std::to_string(MetaImageHeaderLimit / 1024) + " KiB");
  }
}

// The slice files a MetaImage's "ElementDataFile = LIST [dimension]" names
// on the lines after it, as VTK 9.1's reader (MetaIO) takes them: one a
// line, each holding `dimension` axes (default and when 0 or beyond
// NDims: all but the last), trailing spaces dropped, a line counting
// only when a newline ends it. Fewer lines than files needed left the
// other slices zeros without a word, and an empty line among them was
// read before its start. Each file must hold a slice's bytes (not looked
// at for compressed data).
void CheckMetaImageFileList(const std::string& path, const std::vector<long long>& dims,
  const std::string& dataFile, size_t listOffset, unsigned long long elementBytes,
  bool compressed)
{
  std::istringstream words(dataFile);
  std::string list;
  std::string dimensionWord;
  words >> list >> dimensionWord;
  const long long ndims = static_cast<long long>(dims.size());
  const double given = dimensionWord.empty() ? 0.0 : std::atof(dimensionWord.c_str());
  if (!(given >= 0.0 && given < 1e9))
  {
    Unreadable(path, "its ElementDataFile (" + dataFile + ") gives a file dimension that is "
        "not a count");
  }
  long long fileDims = static_cast<long long>(given);
  if (fileDims == 0 || fileDims > ndims)
  {
    fileDims = ndims - 1;
  }
  unsigned long long files = 1;
  unsigned long long fileBytes = elementBytes;
  for (long long a = 0; a < ndims; ++a)
  {
    if (dims[a] < 1 || dims[a] > (1LL << 31))
    {
      return; // the declared-size check speaks of such headers
    }
    (a < fileDims ? fileBytes : files) *= static_cast<unsigned long long>(dims[a]);
  }
  std::ifstream in(path, std::ios::binary);
  in.seekg(static_cast<std::streamoff>(listOffset));
  std::string line;
  unsigned long long listed = 0;
  for (; listed < files && std::getline(in, line) && !in.eof(); ++listed)
  {
    // MetaIO drops trailing spaces and unprintable bytes, never the first.
    size_t keep = line.size();
    while (keep > 1 && (std::isspace(static_cast<unsigned char>(line[keep - 1])) ||
                         !std::isprint(static_cast<unsigned char>(line[keep - 1]))))
    {
      --keep;
    }
    line.resize(keep);
    const std::string number = "line " + std::to_string(listed + 1) + " of its file list";
    if (line.empty())
    {
      Unreadable(path, number + " is empty (VTK's MetaImage reader would read before its "
                                "start)");
    }
    const std::string file = DataFilePath(path, line);
    struct stat st;
    if (stat(file.c_str(), &st) != 0 || !S_ISREG(st.st_mode))
    {
      Unreadable(path, number + " names '" + line + "', which is not a readable file");
    }
    if (!compressed && static_cast<unsigned long long>(st.st_size) < fileBytes)
    {
      Unreadable(path, number + " names '" + line + "', which holds " +
          std::to_string(st.st_size) + " bytes, fewer than a slice's " +
          std::to_string(fileBytes));
    }
  }
  if (listed < files)
  {
    Unreadable(path, "its file list names " + std::to_string(listed) + " file" +
        (listed == 1 ? "" : "s") + " (one a line, each line ended by a newline) for " +
        std::to_string(files) + " slices: VTK's MetaImage reader would leave the others zeros");
  }
}

// A MetaImage whose ElementDataFile is a pattern of slice file names
// ("s%d.raw min max step", MetaIO's rules: min 1, max min + slices - 1,
// the step (max - min) / slices without its own word, and with more than
// four words the last three): a step of 0 made VTK 9.1's reader divide by
// zero (SIGFPE), a negative one loop, and a range naming fewer files than
// the volume has slices left the others zeros without a word.
// A LIST of files is checked as CheckMetaImageFileList says.
void CheckMetaImageDataFiles(const std::string& path)
{
  const MetaImageLayout layout = ReadMetaImageLayout(path);
  const std::vector<long long>& dims = layout.dims;
  const std::string& dataFile = layout.dataFile;
  if (layout.channels < 1)
  {
    // VTK's reader then read none of the file's samples, but memory it
    // never wrote, exit status 0.
    Unreadable(path, "its header gives " + std::to_string(layout.channels) +
        " channels (ElementNumberOfChannels): at least 1");
  }
  if (dims.size() >= 2 && dataFile.compare(0, 4, "LIST") == 0)
  {
    // Bytes of one element; 0 (an unknown type) checks no file's size.
    const long long channels = layout.channels;
    CheckMetaImageFileList(path, dims, dataFile, layout.dataOffset,
      channels >= 1 && channels < (1LL << 20)
        ? static_cast<unsigned long long>(layout.elementSize) * channels
        : 0,
      layout.compressed);
    return;
  }
  if (dataFile.find('%') == std::string::npos)
  {
    if (!dataFile.empty() && dataFile != "LOCAL")
    {
      CheckNamedDataFile(path, "its ElementDataFile", dataFile);
    }
    return;
  }
  const std::vector<std::string> words = Words(dataFile);
  const std::string problem = SlicePatternProblem(words[0]);
  if (!problem.empty())
  {
    Unreadable(path, "its ElementDataFile pattern (" + dataFile + ") " + problem);
  }
  if (dims.empty() || dims.back() < 1)
  {
    return;
  }
  const long long slices = dims.back();
  // MetaIO takes each number as (int)atof(word); beyond int it is undefined.
  bool inRange = true;
  const auto number = [&inRange](const std::string& word) {
    const double v = std::atof(word.c_str());
    inRange = inRange && std::fabs(v) < 1e9;
    return inRange ? static_cast<long long>(v) : 0LL;
  };
  const size_t n = words.size();
  long long first = 1;
  long long last = slices;
  long long step = 1;
  if (n >= 2)
  {
    first = number(words[1]);
    last = first + slices - 1;
  }
  if (n >= 3)
  {
    last = number(words[2]);
    step = (last - first) / slices;
  }
  if (n >= 4)
  {
    step = number(words[3]);
  }
  if (n >= 5)
  {
    first = number(words[n - 3]);
    last = number(words[n - 2]);
    step = number(words[n - 1]);
  }
  const std::string pattern = "its ElementDataFile pattern (" + dataFile + ")";
  if (!inRange)
  {
    Unreadable(path, pattern + " has a number beyond what VTK's MetaImage reader takes");
  }
  if (step <= 0)
  {
    Unreadable(path, pattern + " steps by " + std::to_string(step) +
        (n == 3 ? " ((max - min) / slices, in integers)" : "") + ": VTK's MetaImage reader " +
        (step == 0 ? "would divide by zero (a crash)" : "would never reach its end"));
  }
  const long long files = last < first ? 0 : (last - first) / step + 1;
  if (files < slices)
  {
    Unreadable(path, pattern + " names " + std::to_string(files) + " file" +
        (files == 1 ? "" : "s") + " (" + std::to_string(first) + " to " + std::to_string(last) +
        " by " + std::to_string(step) + ") for " + std::to_string(slices) +
        " slices: VTK's MetaImage reader would leave the others zeros");
  }
  // The files of the slices read (the first ones; MetaIO names them with
  // snprintf and the slice number, as here).
  char name[4096];
  for (long long k = 0; k < std::min(slices, MaxSliceFiles); ++k)
  {
    std::snprintf(name, sizeof(name), words[0].c_str(), static_cast<int>(first + k * step));
    CheckNamedDataFile(path, pattern, name);
  }
}

// A compressed MetaImage whose data inflates to fewer bytes than its
// DimSize declares: VTK 9.1's reader fills the rest with zeros and reports
// nothing (a header claiming 1000^3 samples took 9 s to read a few KB of
// data and zeros). Checked before the read, by inflating the data once;
// only the layouts the reader reads from one stream (LOCAL, or one file
// named by ElementDataFile) and element types of a known size.
void CheckMetaImageCompressedSize(const std::string& path)
{
  const MetaImageLayout layout = ReadMetaImageLayout(path);
  const bool compressed = layout.compressed;
  const std::vector<long long>& dims = layout.dims;
  const long long channels = layout.channels;
  const int elementSize = layout.elementSize;
  const std::string& dataFile = layout.dataFile;
  const size_t dataOffset = layout.dataOffset; // of LOCAL data in the header's file
  if (!compressed || elementSize == 0 || dims.empty() || channels < 1 || dataFile.empty() ||
    dataFile == "LIST" || dataFile.find('%') != std::string::npos ||
    dataFile.find(' ') != std::string::npos)
  {
    return;
  }
  unsigned long long want = static_cast<unsigned long long>(elementSize) * channels;
  for (long long n : dims)
  {
    if (n < 1 || want > (1ULL << 62) / static_cast<unsigned long long>(n))
    {
      return; // the declared-size check speaks of such headers
    }
    want *= static_cast<unsigned long long>(n);
  }
  const bool local = dataFile == "LOCAL";
  const std::string file = local ? path : DataFilePath(path, dataFile);
  std::ifstream in(file, std::ios::binary);
  if (!in)
  {
    return; // the reader names a missing data file
  }
  in.seekg(static_cast<std::streamoff>(local ? dataOffset : 0));
  z_stream z = {};
  if (inflateInit(&z) != Z_OK)
  {
    return;
  }
  std::vector<unsigned char> input(1 << 16);
  std::vector<unsigned char> output(1 << 16);
  unsigned long long got = 0;
  int status = Z_OK;
  // MetaIO reads CompressedDataSize bytes of compressed data when the
  // header gives it (half of a whole stream was read as half the samples
  // and zeros, exit status 0): inflated here from as many.
  unsigned long long left = layout.compressedSize > 0
    ? static_cast<unsigned long long>(layout.compressedSize)
    : ~0ULL;
  while (status != Z_STREAM_END && got < want)
  {
    if (z.avail_in == 0)
    {
      in.read(reinterpret_cast<char*>(input.data()),
        static_cast<std::streamsize>(std::min<unsigned long long>(input.size(), left)));
      left -= static_cast<unsigned long long>(in.gcount());
      z.next_in = input.data();
      z.avail_in = static_cast<uInt>(in.gcount());
      if (z.avail_in == 0)
      {
        break; // the data ends without the stream's end
      }
    }
    z.next_out = output.data();
    z.avail_out = static_cast<uInt>(output.size());
    status = inflate(&z, Z_NO_FLUSH);
    got += output.size() - z.avail_out;
    if (status != Z_OK && status != Z_STREAM_END)
    {
      break;
    }
  }
  inflateEnd(&z);
  if (got < want)
  {
    Unreadable(path, "its compressed data holds " + std::to_string(got) + " bytes where its "
        "DimSize declares " + std::to_string(want) + " (VTK's reader would fill the rest with "
        "zeros)");
  }
}

// The arrays of a legacy FIELD block whose "FIELD name count" line `words`
// was just read from `header` (the file's first bytes): each must be
// "name components tuples type" with a type the reader knows, followed by
// its values (ASCII numbers, or binary bytes). Throws when one is not;
// stops where the window of `header` ends.
template <typename TypeSize>
void CheckLegacyFieldBlock(const std::string& path, std::istringstream& header,
  std::istringstream& words, bool binary, const TypeSize& typeSize)
{
  std::string name;
  long long arrays = -1;
  words >> name >> arrays;
  if (arrays < 0 || arrays > (1 << 20))
  {
    Unreadable(path, "its FIELD block '" + name + "' declares " + std::to_string(arrays) +
        " arrays");
  }
  for (long long k = 0; k < arrays; ++k)
  {
    std::string arrayName, type;
    long long components = -1, tuples = -1;
    if (!(header >> arrayName))
    {
      return; // past the window
    }
    const bool described = static_cast<bool>(header >> components >> tuples >> type);
    if (!described || components < 1 || tuples < 0 || typeSize(type) < 0)
    {
      Unreadable(path, "its FIELD block '" + name + "' declares " + std::to_string(arrays) +
          " arrays, and array " + std::to_string(k + 1) + " is not 'name components tuples "
          "type' with a type VTK's reader knows (it crashed on such a block)");
    }
    const unsigned long long values =
      static_cast<unsigned long long>(components) * static_cast<unsigned long long>(tuples);
    if (binary)
    {
      header.ignore(1); // the newline after the array's line
      header.seekg(static_cast<std::streamoff>(values * std::max(1, typeSize(type))),
        std::ios::cur);
      if (!header)
      {
        return;
      }
      continue;
    }
    std::string value;
    for (unsigned long long v = 0; v < values; ++v)
    {
      if (!(header >> value))
      {
        return;
      }
    }
  }
}

// A legacy .vtk file shorter than the values an attribute of its header
// declares (scalars, vectors, normals, tensors, texture coordinates,
// colour scalars, a lookup table, a FIELD array; point or cell data, each
// attribute in the first 16 MiB): VTK's reader allocates and reads them all
// first (a 4 KB file declaring 1000^3 floats took 18 s and 4 GB before it
// failed). ASCII values take two bytes each at least.
void CheckLegacySize(const std::string& path)
{
  // 16 MiB: an attribute after 80 KB of field data went unchecked in 64 KiB.
  std::istringstream header(FileHead(path, 1 << 24));
  std::string line;
  bool binary = false;
  unsigned long long count = 0; // of POINT_DATA or CELL_DATA
  const auto upper = [](std::string w) {
    std::transform(w.begin(), w.end(), w.begin(),
      [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
    return w;
  };
  // Bytes of a value of a legacy type name (any case, as the reader takes
  // it); 0 for bit, -1 for a name it does not know.
  const auto typeSize = [](std::string type) {
    std::transform(type.begin(), type.end(), type.begin(),
      [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    static const std::pair<const char*, int> sizes[] = { { "bit", 0 }, { "char", 1 },
      { "unsigned_char", 1 }, { "short", 2 }, { "unsigned_short", 2 }, { "int", 4 },
      { "unsigned_int", 4 }, { "long", 8 }, { "unsigned_long", 8 }, { "float", 4 },
      { "double", 8 }, { "vtktypeint64", 8 }, { "vtktypeuint64", 8 } };
    int size = -1;
    for (const auto& t : sizes)
    {
      size = type == t.first ? t.second : size;
    }
    return size;
  };
  while (std::getline(header, line))
  {
    std::istringstream words(line);
    std::string word;
    words >> word;
    word = upper(word);
    if (word == "BINARY")
    {
      binary = true;
      continue;
    }
    if (word == "POINT_DATA" || word == "CELL_DATA")
    {
      words >> count;
      continue;
    }
    if (count == 0 && word == "FIELD")
    {
      // The dataset's field data, before the geometry: a block that does
      // not hold the arrays it declares made VTK's reader dereference a
      // null array (SIGSEGV).
      CheckLegacyFieldBlock(path, header, words, binary, typeSize);
      continue;
    }
    if (count == 0)
    {
      continue;
    }
    // The first attribute's values: `tuples` of `components` values of
    // `type` (the declared count's, or a FIELD array's own).
    std::string name, type;
    unsigned long long components = 0;
    unsigned long long tuples = count;
    if (word == "SCALARS")
    {
      words >> name >> type;
      if (!(words >> components) || components < 1 || components > 4)
      {
        components = 1;
      }
    }
    else if (word == "VECTORS" || word == "NORMALS")
    {
      words >> name >> type;
      components = 3;
    }
    else if (word == "TENSORS" || word == "TENSORS6")
    {
      words >> name >> type;
      components = word == "TENSORS" ? 9 : 6;
    }
    else if (word == "TEXTURE_COORDINATES")
    {
      words >> name >> components >> type;
    }
    else if (word == "COLOR_SCALARS")
    {
      words >> name >> components;
      type = binary ? "unsigned_char" : "float";
    }
    else if (word == "LOOKUP_TABLE")
    {
      // "LOOKUP_TABLE default" names none; a table of its own gives its
      // size, and 4 values an entry follow (2e9 entries took 1 GB before
      // the reader failed).
      words >> name;
      if (!(words >> tuples))
      {
        continue;
      }
      components = 4;
      type = binary ? "unsigned_char" : "float";
    }
    else if (word == "FIELD")
    {
      // Each array takes a line at least: a count beyond the file's bytes
      // made the reader allocate for it (2e9: 16 GB, over a minute).
      long long arrays = 0;
      words >> name >> arrays;
      std::ifstream in(path, std::ios::binary | std::ios::ate);
      const long long bytes = in ? static_cast<long long>(in.tellg()) : 0;
      if (arrays < 0 || arrays > bytes / 8)
      {
        Unreadable(path, "its FIELD attribute '" + name + "' declares " + std::to_string(arrays) +
            " arrays, more than its " + std::to_string(bytes) + " bytes can hold");
      }
      // The first array's line: name, components, tuples, type.
      std::string arrayLine;
      if (!std::getline(header, arrayLine))
      {
        return;
      }
      std::istringstream array(arrayLine);
      array >> name >> components >> tuples >> type;
    }
    else
    {
      continue;
    }
    const int size = typeSize(type);
    if (size <= 0 || components < 1 || components > 64 || tuples < 1 ||
      tuples > (1ULL << 60) / components / 8)
    {
      continue; // the reader, or the declared-size check, speaks of these
    }
    const unsigned long long values = tuples * components;
    const unsigned long long need = values * (binary ? static_cast<unsigned long long>(size) : 2);
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    const unsigned long long have = in ? static_cast<unsigned long long>(in.tellg()) : 0;
    if (have < need)
    {
      Unreadable(path, "the file holds " + std::to_string(have) + " bytes, fewer than the " +
          std::to_string(need) + " that the " + std::to_string(values) + " " +
          (binary ? "" : "ASCII ") + type + " values of its attribute " + word + " '" + name +
          "' need");
    }
    // On to the next attribute (one of 10^9 samples after a real one took
    // 4.4 GB before the reader failed).
  }
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

namespace
{

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
