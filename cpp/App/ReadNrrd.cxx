// The checks of a NRRD header (.nrrd, .nhdr) before VTK's reader sees it,
// and its world frame applied after the read.
#include "ReadNrrd.h"

#include "ReadChecks.h"

#include "vtkImageData.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace pmcapp
{
namespace
{

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

// Bytes the samples of a header with these sizes and values of
// `valueBytes` bytes take; 0 when not known (a type not known, a size not
// positive, or a product beyond 2^62).
unsigned long long NrrdSampleBytes(const std::vector<long long>& sizes, int valueBytes)
{
  unsigned long long need = valueBytes > 0 ? static_cast<unsigned long long>(valueBytes) : 0;
  for (long long n : sizes)
  {
    need = n > 0 && need <= (1ULL << 62) / static_cast<unsigned long long>(n)
      ? need * static_cast<unsigned long long>(n)
      : 0;
  }
  return need;
}

// Raw samples cut short: VTK's reader failed with its own words ("File
// operation failed. row = 9, Tried to Read = 48, Read = 44, ...").
void RefuseShortRawData(const std::string& path, const std::string& where,
  unsigned long long have, unsigned long long need)
{
  if (need > 0 && have < need)
  {
    Unreadable(path, where + " holds " + std::to_string(have) + " bytes, fewer than the " +
        std::to_string(need) + " its samples take: the data is cut short");
  }
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
    const unsigned long long need = NrrdSampleBytes(sizes, valueBytes);
    if (encoding == "raw")
    {
      RefuseShortRawData(path, "its data file '" + dataFile + "'", have, need);
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
  if (!detached && encoding == "raw")
  {
    // The samples follow the blank line that ends the header (`read`
    // bytes in).
    in.clear();
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    if (size >= 0)
    {
      const unsigned long long total = static_cast<unsigned long long>(size);
      const unsigned long long after = total > read ? total - read : 0;
      RefuseShortRawData(
        path, "its data after the header", after, NrrdSampleBytes(sizes, valueBytes));
    }
  }
  header.sizes = sizes;
  return header;
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

}
