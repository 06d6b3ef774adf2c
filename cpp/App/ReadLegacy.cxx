// The checks of a legacy VTK file (.vtk) before VTK's structured points
// reader sees it.
#include "ReadLegacy.h"

#include "ReadChecks.h"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <sstream>

namespace pmcapp
{
namespace
{

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

}
