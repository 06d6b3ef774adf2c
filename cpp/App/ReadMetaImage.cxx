// The checks of a MetaImage header (.mha, .mhd) and its data files before
// VTK's reader sees them, and its world frame applied after the read.
#include "ReadMetaImage.h"

#include "ReadChecks.h"

#include "vtkImageData.h"
#include "vtk_zlib.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <sys/stat.h>

namespace pmcapp
{
namespace
{

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

}

// MetaImage: TransformMatrix (or its other names, Rotation and
// Orientation) holds each axis's direction in turn, three numbers an axis
// (ITK's convention); VTK 9.1's reader reads the Offset as the origin but
// leaves the matrix out.
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

}
