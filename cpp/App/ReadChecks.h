// Internal to the precisemc tool's volume reading: the helpers that IO.cxx
// and the format checks (Read*.cxx) share. Defined in ReadChecks.cxx,
// where each says what it does and why.
#ifndef precisemc_app_ReadChecks_h
#define precisemc_app_ReadChecks_h

#include <cstddef>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include <unistd.h>

class vtkImageData;

namespace pmcapp
{

// Throws pmcapp::Error: "cannot read '<path>': <why>".
[[noreturn]] void Unreadable(const std::string& path, const std::string& why);

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

// The whitespace-separated words of `text`.
std::vector<std::string> Words(const std::string& text);

// The most slice files a header may name (a volume of so many slices in
// files of their own is none a user keeps; a pattern naming 10^9 of them
// made VTK's NRRD reader build as many names).
const long long MaxSliceFiles = 1 << 16;

// Why `pattern` cannot name slice files as VTK's readers expand it, "" when
// it can.
std::string SlicePatternProblem(const std::string& pattern);

// The path of `file`, a data file the header `path` names.
std::string DataFilePath(const std::string& path, const std::string& file);

// Throws unless `file`, a data file the header `path` names, is a regular
// file; returns its size in bytes.
unsigned long long CheckNamedDataFile(
  const std::string& path, const std::string& what, const std::string& file);

// Places `volume` in the world frame its header gives (throws on a
// singular direction).
void SetFrame(vtkImageData* volume, const std::string& path, const double direction[9],
  const double spacing[3], const double origin[3]);

// The first `bytes` bytes of a file.
std::string FileHead(const std::string& path, size_t bytes);

}

#endif
