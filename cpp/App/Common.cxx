#include "Common.h"

#include "vtkLogger.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkOutputWindow.h"

#include <algorithm>
#include <cctype>
#include <cfloat>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <sstream>

#include <climits>
#include <csignal>
#include <cstdlib>

#include <fcntl.h>
#include <pthread.h>
#include <sys/stat.h>
#include <unistd.h>

namespace pmcapp
{
namespace
{

std::vector<std::string> CapturedErrors;
std::vector<std::string> CapturedWarnings;

// The temporaries of the run not yet committed, for the signal handler
// below: plain C strings in a fixed table (a handler may only read them
// and call unlink). A slot is cleared before its string is freed.
constexpr int MaxPending = 256;
char* volatile PendingNames[MaxPending];

// The signals whose default action kills the tool and that it catches to
// remove its temporaries first (SIGKILL cannot be caught; SIGXFSZ is
// ignored in main(), a write past the limit then fails with EFBIG and is
// reported). SIGPIPE: output piped into a reader that quits early (| head);
// SIGXCPU: a soft CPU time limit (prlimit --cpu); SIGALRM, SIGVTALRM,
// SIGPROF: timers (timeout -s ALRM); SIGUSR1, SIGUSR2: sent by hand.
const int CleanupSignals[] = { SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGPIPE, SIGXCPU, SIGALRM,
  SIGVTALRM, SIGPROF, SIGUSR1, SIGUSR2 };

void RemovePendingAndDie(int sig)
{
  for (int i = 0; i < MaxPending; ++i)
  {
    const char* name = PendingNames[i];
    if (name)
    {
      unlink(name);
    }
  }
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

void RegisterPending(const std::string& tmp)
{
  for (int i = 0; i < MaxPending; ++i)
  {
    if (!PendingNames[i])
    {
      PendingNames[i] = strdup(tmp.c_str());
      return;
    }
  }
}

void UnregisterPending(const std::string& tmp)
{
  for (int i = 0; i < MaxPending; ++i)
  {
    char* name = PendingNames[i];
    if (name && tmp == name)
    {
      PendingNames[i] = nullptr;
      std::free(name);
      return;
    }
  }
}

// "ERROR: In /path/vtkFoo.cxx, line 12\nvtkFoo (0x55d0): Cannot open file\n\n"
// -> "Cannot open file".
std::string CleanMessage(const char* text)
{
  std::string all = text ? text : "";
  std::vector<std::string> lines;
  std::istringstream in(all);
  std::string line;
  while (std::getline(in, line))
  {
    // Trim.
    size_t b = line.find_first_not_of(" \t\r");
    size_t e = line.find_last_not_of(" \t\r");
    if (b == std::string::npos)
    {
      continue;
    }
    line = line.substr(b, e - b + 1);
    if (line.compare(0, 10, "ERROR: In ") == 0 || line.compare(0, 12, "Warning: In ") == 0 ||
      line.compare(0, 19, "Generic Warning: In") == 0)
    {
      continue;
    }
    // "vtkFoo (0x1234): message" -> "message".
    size_t paren = line.find(" (0x");
    size_t colon = line.find("): ");
    if (paren != std::string::npos && colon != std::string::npos && paren < colon &&
      line.compare(0, 3, "vtk") == 0)
    {
      line = line.substr(colon + 3);
    }
    lines.push_back(line);
  }
  std::string joined;
  for (const auto& l : lines)
  {
    if (!joined.empty())
    {
      joined += ' ';
    }
    joined += l;
  }
  return joined;
}

class CaptureOutputWindow : public vtkOutputWindow
{
public:
  static CaptureOutputWindow* New();
  vtkTypeMacro(CaptureOutputWindow, vtkOutputWindow);

  void DisplayText(const char*) override {}
  void DisplayErrorText(const char* text) override
  {
    std::string m = CleanMessage(text);
    if (!m.empty())
    {
      CapturedErrors.push_back(m);
    }
  }
  void DisplayWarningText(const char* text) override
  {
    std::string m = CleanMessage(text);
    if (!m.empty())
    {
      CapturedWarnings.push_back(m);
    }
  }
  void DisplayGenericWarningText(const char* text) override { this->DisplayWarningText(text); }
  void DisplayDebugText(const char*) override {}

protected:
  CaptureOutputWindow() = default;
  ~CaptureOutputWindow() override = default;

private:
  CaptureOutputWindow(const CaptureOutputWindow&) = delete;
  void operator=(const CaptureOutputWindow&) = delete;
};
vtkStandardNewMacro(CaptureOutputWindow);

std::string DirectoryOf(const std::string& path)
{
  size_t slash = path.find_last_of('/');
  if (slash == std::string::npos)
  {
    return ".";
  }
  if (slash == 0)
  {
    return "/";
  }
  return path.substr(0, slash);
}

}

std::string FileNameOf(const std::string& path)
{
  size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

void CaptureVTKMessages()
{
  // VTK 9 also logs errors to stderr through vtkLogger, besides the
  // output window.
  vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
  vtkNew<CaptureOutputWindow> window;
  vtkOutputWindow::SetInstance(window);
}

std::vector<std::string> TakeVTKErrors()
{
  std::vector<std::string> out;
  out.swap(CapturedErrors);
  return out;
}

std::vector<std::string> TakeVTKWarnings()
{
  std::vector<std::string> out;
  out.swap(CapturedWarnings);
  return out;
}

StderrSilenced::StderrSilenced()
{
  std::fflush(stderr);
  int devnull = open("/dev/null", O_WRONLY);
  if (devnull < 0)
  {
    return;
  }
  this->Saved = dup(STDERR_FILENO);
  if (this->Saved >= 0)
  {
    dup2(devnull, STDERR_FILENO);
  }
  close(devnull);
}

StderrSilenced::~StderrSilenced()
{
  if (this->Saved >= 0)
  {
    std::fflush(stderr);
    dup2(this->Saved, STDERR_FILENO);
    close(this->Saved);
  }
}

std::string Extension(const std::string& path)
{
  std::string name = FileNameOf(path);
  std::transform(name.begin(), name.end(), name.begin(),
    [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const char* twoPart : { ".nii.gz", ".tar.gz" })
  {
    size_t n = std::strlen(twoPart);
    if (name.size() > n && name.compare(name.size() - n, n, twoPart) == 0)
    {
      return twoPart;
    }
  }
  size_t dot = name.find_last_of('.');
  if (dot == std::string::npos || dot == 0)
  {
    return "";
  }
  return name.substr(dot);
}

std::string OnlyExtension(const std::string& path)
{
  const std::string name = FileNameOf(path);
  if (name.size() < 2 || name[0] != '.' || name.find('.', 1) != std::string::npos)
  {
    return std::string();
  }
  std::string ext = name;
  std::transform(ext.begin(), ext.end(), ext.begin(),
    [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

std::string WithSuffix(const std::string& path, const std::string& suffix)
{
  std::string ext = Extension(path);
  return path.substr(0, path.size() - ext.size()) + "-" + suffix + path.substr(path.size() - ext.size());
}

bool IsDirectory(const std::string& path)
{
  struct stat st;
  return stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

bool IsRegularFile(const std::string& path)
{
  struct stat st;
  return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

std::string ThroughLinks(const std::string& path)
{
  std::string at = path;
  for (int hops = 0; hops <= 40; ++hops)
  {
    struct stat st;
    if (lstat(at.c_str(), &st) != 0 || !S_ISLNK(st.st_mode))
    {
      return at;
    }
    std::vector<char> target(static_cast<size_t>(st.st_size > 0 ? st.st_size : PATH_MAX) + 1);
    ssize_t n = readlink(at.c_str(), target.data(), target.size());
    if (n < 0 || static_cast<size_t>(n) >= target.size())
    {
      return at; // Changed meanwhile: written as named.
    }
    std::string next(target.data(), static_cast<size_t>(n));
    if (next.empty())
    {
      return at;
    }
    if (next[0] != '/')
    {
      std::string dir = DirectoryOf(at);
      next = (dir == "/" ? dir : dir + "/") + next;
    }
    at = next;
  }
  throw Error("cannot write '" + path + "': too many levels of symbolic links");
}

void CheckWritable(const std::string& given, const std::string& what)
{
  if (given.empty())
  {
    throw Error(what + ": empty file name", 2);
  }
  const std::string path = ThroughLinks(given);
  // Messages name the file the user gave, and the link's target too.
  const std::string named =
    "'" + given + "'" + (path == given ? std::string() : " (a link to '" + path + "')");
  if (IsDirectory(path))
  {
    throw Error("cannot write " + what + " " + named + ": it is a directory");
  }
  std::string dir = DirectoryOf(path);
  struct stat dirStat;
  if (stat(dir.c_str(), &dirStat) != 0)
  {
    throw Error("cannot write " + what + " " + named + ": directory '" + dir + "' " +
      (errno == ENOTDIR ? "cannot be reached: a component of its path is not a directory"
                        : "does not exist"));
  }
  if (!S_ISDIR(dirStat.st_mode))
  {
    throw Error("cannot write " + what + " " + named + ": '" + dir + "' is not a directory");
  }
  if (access(dir.c_str(), W_OK) != 0)
  {
    throw Error("cannot write " + what + " " + named + ": directory '" + dir +
      "' is not writable (" + std::strerror(errno) + ")");
  }
  if (access(path.c_str(), F_OK) == 0 && access(path.c_str(), W_OK) != 0)
  {
    throw Error(
      "cannot write " + what + " " + named + ": " + std::strerror(errno));
  }
  // A name the file system cannot hold fails only at the final rename,
  // after the other outputs of the run are in place.
  const long nameMax = pathconf(dir.c_str(), _PC_NAME_MAX);
  if (FileNameOf(path).size() > static_cast<size_t>(nameMax > 0 ? nameMax : NAME_MAX))
  {
    throw Error("cannot write " + what + " " + named + ": " + std::strerror(ENAMETOOLONG));
  }
  // access() says yes to root for any directory that is not on a
  // read-only mount (/proc, /sys): the writer then failed after the whole
  // extraction. The temporary the output is written to is created (and
  // removed) now instead.
  // The signals that remove the run's temporary files wait meanwhile: the
  // probe is not one of them, and an interrupt between open() and unlink()
  // left it behind.
  sigset_t block, previous;
  sigemptyset(&block);
  for (int sig : CleanupSignals)
  {
    sigaddset(&block, sig);
  }
  pthread_sigmask(SIG_BLOCK, &block, &previous);
  std::string failure;
  for (int attempt = 0;; ++attempt)
  {
    // A name taken (another run's temporary, or a stale one by a reused
    // process id) says nothing of the directory: another is tried.
    const std::string probe = TemporaryPathFor(path);
    const int fd = open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0600);
    if (fd < 0)
    {
      if (errno == EEXIST && attempt < 100)
      {
        continue;
      }
      failure = "no file can be created in '" + dir + "' (" + std::strerror(errno) + ")";
      break;
    }
    close(fd);
    // A probe that cannot be removed stays in the user's directory.
    if (unlink(probe.c_str()) != 0)
    {
      failure = "the file '" + probe + "' created there to try it cannot be removed (" +
        std::strerror(errno) + ")";
    }
    break;
  }
  pthread_sigmask(SIG_SETMASK, &previous, nullptr);
  if (!failure.empty())
  {
    throw Error("cannot write " + what + " " + named + ": " + failure);
  }
}

std::string CanonicalPath(const std::string& given)
{
  const std::string path = ThroughLinks(given);
  char* dir = realpath(DirectoryOf(path).c_str(), nullptr);
  if (!dir)
  {
    return path;
  }
  std::string out = dir;
  std::free(dir);
  return (out == "/" ? out : out + "/") + FileNameOf(path);
}

std::string TemporaryPathFor(const std::string& path)
{
  static unsigned long counter = 0;
  std::string name = FileNameOf(path);
  std::string prefix = path.substr(0, path.size() - name.size());
  // The extension stays last: some writers (vtkPLYWriter) append theirs
  // to a name that does not end with it.
  std::string ext = Extension(name);
  std::string stem = name.substr(0, name.size() - ext.size());
  std::string tag =
    ".tmp" + std::to_string(static_cast<long>(getpid())) + "-" + std::to_string(++counter);
  // A name that fits may not fit with the dot and the tag added: the
  // stem is shortened instead (the tag keeps the names apart).
  const size_t maxName = NAME_MAX;
  if (1 + stem.size() + tag.size() + ext.size() > maxName)
  {
    stem.resize(maxName > 1 + tag.size() + ext.size() ? maxName - 1 - tag.size() - ext.size() : 0);
  }
  return prefix + "." + stem + tag + ext;
}

std::string BestError(const std::vector<std::string>& errors)
{
  for (const std::string& e : errors)
  {
    if (e.find("returned failure for request") == std::string::npos)
    {
      return e;
    }
  }
  return std::string();
}

std::string ForUser(std::string why, const std::string& tmp, const std::string& path)
{
  const size_t deleting = why.find("; deleting file");
  if (deleting != std::string::npos)
  {
    why.erase(deleting);
  }
  for (size_t at = why.find(tmp); !tmp.empty() && at != std::string::npos;
       at = why.find(tmp, at + path.size()))
  {
    why.replace(at, tmp.size(), path);
  }
  return why;
}

void CommitFile(const std::string& tmp, const std::string& path)
{
  // A file replaced keeps its permissions, as with the shell's '>' (the
  // temporary has the default ones).
  struct stat existing;
  if (stat(path.c_str(), &existing) == 0 && S_ISREG(existing.st_mode))
  {
    chmod(tmp.c_str(), existing.st_mode & 07777);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
  {
    int err = errno;
    std::remove(tmp.c_str());
    throw Error("cannot write '" + path + "': " + std::strerror(err));
  }
}

void RemoveFile(const std::string& path)
{
  std::remove(path.c_str());
}

PendingFiles::PendingFiles()
{
  for (int sig : CleanupSignals)
  {
    struct sigaction action = {};
    action.sa_handler = RemovePendingAndDie;
    sigemptyset(&action.sa_mask);
    // Not for a signal the caller ignores (nohup).
    struct sigaction old = {};
    if (sigaction(sig, nullptr, &old) == 0 && old.sa_handler != SIG_IGN)
    {
      sigaction(sig, &action, nullptr);
    }
  }
}

PendingFiles::~PendingFiles()
{
  for (const File& f : this->Files)
  {
    RemoveFile(f.Temporary);
    UnregisterPending(f.Temporary);
  }
}

std::string PendingFiles::Add(const std::string& path)
{
  File f;
  f.Path = ThroughLinks(path);
  f.Temporary = TemporaryPathFor(f.Path);
  this->Files.push_back(f);
  RegisterPending(f.Temporary);
  return f.Temporary;
}

void PendingFiles::Commit()
{
  // The paths were checked before the work and each temporary is in its
  // path's directory: a rename failing here is an unusual event (the
  // directory changed meanwhile).
  while (!this->Files.empty())
  {
    File f = this->Files.front();
    this->Files.erase(this->Files.begin());
    // Unregistered after the rename (an interrupt in between unlinks a
    // name that is gone), or after the failed rename removed it.
    struct Unregister
    {
      const std::string& Temporary;
      ~Unregister() { UnregisterPending(this->Temporary); }
    } unregister{ f.Temporary };
    CommitFile(f.Temporary, f.Path);
  }
}

std::string Grouped(unsigned long long value)
{
  std::string digits = std::to_string(value);
  std::string out;
  int count = 0;
  for (auto it = digits.rbegin(); it != digits.rend(); ++it)
  {
    if (count > 0 && count % 3 == 0)
    {
      out.insert(out.begin(), ' ');
    }
    out.insert(out.begin(), *it);
    ++count;
  }
  return out;
}

std::string Fixed(double value, int decimals)
{
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, value);
  return buf;
}

std::string General(double value)
{
  // Six significant digits, or as many more as it takes to tell the value
  // from its neighbours (a float's, when the value is one: a float array's
  // range reads 0.1, not 0.100000001490116); "1e+06" for 1000000.25 made
  // an isovalue outside the range print inside it.
  const bool isFloat = std::isfinite(value) && std::fabs(value) <= FLT_MAX &&
    static_cast<double>(static_cast<float>(value)) == value;
  char buf[64];
  if (value == std::floor(value) && std::fabs(value) < 1e15)
  {
    // Whole numbers in full ("1000000" beside "1000000.25", not "1e+06").
    std::snprintf(buf, sizeof(buf), "%.0f", value);
    return buf;
  }
  for (int digits = 6; digits <= 17; ++digits)
  {
    std::snprintf(buf, sizeof(buf), "%.*g", digits, value);
    const double back = std::strtod(buf, nullptr);
    if (isFloat ? static_cast<float>(back) == static_cast<float>(value) : back == value)
    {
      break;
    }
  }
  return buf;
}

}
