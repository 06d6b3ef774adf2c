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

// Set while PendingFiles::Commit() renames the files into place: a signal
// then only records itself in HeldSignal, and the commit, once its renames
// are over, undoes them and dies of it (a run killed never leaves part of
// its outputs, nor all of them, behind).
volatile std::sig_atomic_t Committing = 0;
volatile std::sig_atomic_t HeldSignal = 0;

void RemovePendingAndDie(int sig)
{
  if (Committing)
  {
    HeldSignal = sig;
    return;
  }
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

// Whether the process has a capability (its bit in the CapEff line of
// /proc/self/status): root's usual powers, or one given to the process
// alone. Without /proc, root is taken to have it.
bool HasCapability(int bit)
{
  std::FILE* f = std::fopen("/proc/self/status", "r");
  if (!f)
  {
    return geteuid() == 0;
  }
  char line[256];
  unsigned long long caps = 0;
  bool found = false;
  while (!found && std::fgets(line, sizeof(line), f))
  {
    found = std::sscanf(line, "CapEff: %llx", &caps) == 1;
  }
  std::fclose(f);
  return found ? ((caps >> bit) & 1u) != 0 : geteuid() == 0;
}

// CAP_FOWNER of <linux/capability.h>: lets the process replace any file
// in a sticky directory.
constexpr int CapFowner = 3;

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
  // A FIFO or a device (or a link to one: "-o /dev/null" through a link)
  // would be replaced by a regular file at the commit, for everyone.
  struct stat target;
  const bool exists = stat(path.c_str(), &target) == 0;
  if (exists && !S_ISREG(target.st_mode))
  {
    throw Error("'" + given + "' is not a regular file" +
      (path == given ? std::string() : " (it links to '" + path + "')"));
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
  // In a sticky directory (/tmp, a shared scratch directory) only the
  // file's owner, the directory's owner and a process with CAP_FOWNER
  // (root) may replace a file: the final rename() would fail with EPERM,
  // after the work, though writing into the file (">") works.
  if (exists && (dirStat.st_mode & S_ISVTX) != 0 && target.st_uid != geteuid() &&
    dirStat.st_uid != geteuid() && !HasCapability(CapFowner))
  {
    throw Error("cannot write " + what + " " + named + ": it belongs to another user and its "
      "directory '" + dir + "' is sticky (as /tmp), where only the file's owner may replace it");
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
  // path's directory: a failure here is an unusual event (the directory
  // changed meanwhile, a file bind-mounted over, ...). The commit is all
  // or nothing all the same: the files replaced are kept under a hidden
  // name (a hard link, in their own directory) until every rename has
  // succeeded, and put back if one fails.
  std::vector<File> files;
  files.swap(this->Files);
  const size_t n = files.size();
  std::vector<bool> existed(n, false); // a file was at the path before
  std::vector<std::string> kept(n);    // its hard link; "" if none made
  size_t renamed = 0;                  // files[0, renamed) are in place
  std::string failure;
  HeldSignal = 0;
  Committing = 1; // a signal now waits for the end of the renames

  // 1. Nothing is renamed over a file that is not a regular one (a FIFO,
  // a device): CheckWritable refused it, but it may have appeared since.
  for (size_t i = 0; i < n && failure.empty(); ++i)
  {
    struct stat st;
    existed[i] = lstat(files[i].Path.c_str(), &st) == 0;
    if (existed[i] && !S_ISREG(st.st_mode))
    {
      failure = "'" + files[i].Path + "' is not a regular file";
    }
  }
  // 2. Each file to be replaced gets a second name. When none can be made
  // (a file system without hard links, a name taken 100 times), that file
  // is replaced without this net, as before.
  for (size_t i = 0; i < n && failure.empty(); ++i)
  {
    for (int attempt = 0; existed[i] && attempt < 100; ++attempt)
    {
      const std::string name = TemporaryPathFor(files[i].Path);
      if (link(files[i].Path.c_str(), name.c_str()) == 0)
      {
        kept[i] = name;
        break;
      }
      if (errno != EEXIST)
      {
        break;
      }
    }
  }
  // 3. The renames. A file replaced keeps its permissions, as with the
  // shell's '>' (the temporary has the default ones).
  for (size_t i = 0; i < n && failure.empty(); ++i)
  {
    struct stat st;
    if (stat(files[i].Path.c_str(), &st) == 0 && S_ISREG(st.st_mode))
    {
      chmod(files[i].Temporary.c_str(), st.st_mode & 07777);
    }
    if (std::rename(files[i].Temporary.c_str(), files[i].Path.c_str()) != 0)
    {
      failure = "cannot write '" + files[i].Path + "': " + std::strerror(errno);
      break;
    }
    ++renamed;
  }

  // 4. Success: the second names go. Failure, or a signal that came
  // meanwhile: the files renamed are undone (the old file put back from its
  // link, a new one removed), the other temporaries and links removed.
  const int sig = HeldSignal;
  std::string lost; // what could not be undone
  for (size_t i = 0; i < n; ++i)
  {
    const File& f = files[i];
    if (failure.empty() && sig == 0)
    {
      if (!kept[i].empty())
      {
        unlink(kept[i].c_str());
      }
    }
    else if (i >= renamed)
    {
      RemoveFile(f.Temporary);
      if (!kept[i].empty())
      {
        unlink(kept[i].c_str());
      }
    }
    else if (!kept[i].empty())
    {
      if (std::rename(kept[i].c_str(), f.Path.c_str()) != 0)
      {
        lost += "; '" + f.Path + "' was replaced (the file there before is kept as '" +
          kept[i] + "')";
      }
    }
    else if (!existed[i])
    {
      RemoveFile(f.Path);
    }
    else
    {
      lost += "; '" + f.Path + "' was replaced";
    }
    UnregisterPending(f.Temporary);
  }
  Committing = 0;
  // (A signal that came after the decision above finds the files
  // committed: the tool dies of it all the same.)
  if (sig != 0 || HeldSignal != 0)
  {
    RemovePendingAndDie(sig != 0 ? sig : HeldSignal);
  }
  if (!failure.empty())
  {
    throw Error(failure + lost);
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
