// The helpers the volume readers' checks share (ReadChecks.h): the error
// of an unreadable file, the data files and slice-file patterns a header
// names, a header's world frame, a file's first bytes.
#include "ReadChecks.h"

#include "Common.h"

#include "vtkImageData.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include <sys/stat.h>

namespace pmcapp
{
[[noreturn]] void Unreadable(const std::string& path, const std::string& why)
{
  throw Error("cannot read '" + path + "': " + why);
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

}
