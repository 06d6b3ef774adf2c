// Shared helpers of the precisemc tool: errors, VTK message capture, files.
#ifndef precisemc_app_Common_h
#define precisemc_app_Common_h

#include <stdexcept>
#include <string>
#include <vector>

class vtkObject;

namespace pmcapp
{

// A failure reported as one line "precisemc: error: <what>" and the exit
// status.
class Error : public std::runtime_error
{
public:
  explicit Error(const std::string& what, int status = 1)
    : std::runtime_error(what)
    , Status(status)
  {
  }
  int Status;
};

// Routes every VTK message (errors, warnings, text) into a buffer instead of
// the terminal, so that a failure is reported as exactly one line.
void CaptureVTKMessages();

// The VTK errors captured since the last call, cleaned (one line each:
// file/line prefixes and object addresses removed); clears the buffer.
std::vector<std::string> TakeVTKErrors();

// The VTK warnings captured since the last call; clears the buffer.
std::vector<std::string> TakeVTKWarnings();

// Sends file descriptor 2 to /dev/null while alive: some libraries under
// VTK (libpng, Xlib) print their complaints straight to stderr, which would
// break the one-line error report; the reason reaches it through VTK's
// errors or the caller.
class StderrSilenced
{
public:
  StderrSilenced();
  ~StderrSilenced();
  StderrSilenced(const StderrSilenced&) = delete;
  StderrSilenced& operator=(const StderrSilenced&) = delete;

private:
  int Saved = -1;
};

// The last component of a path: "a/b.vtp" -> "b.vtp", "b.vtp" -> "b.vtp".
std::string FileNameOf(const std::string& path);

// Lower-case extension of a file name, with the double extension ".nii.gz"
// and ".tar.gz" kept whole: "a/B.NII.GZ" -> ".nii.gz", "a/b" -> "".
// A name that starts with its only dot (a hidden file: ".png") has none.
std::string Extension(const std::string& path);

// For a name that is only an extension ("out/.PNG": no base, only the
// dot and the extension), that extension in lower case (".png"); else "".
// Extension() gives "" for it, which callers would word as a wrong
// extension.
std::string OnlyExtension(const std::string& path);

// The file name with "-<suffix>" inserted before its extension.
std::string WithSuffix(const std::string& path, const std::string& suffix);

bool IsDirectory(const std::string& path);
bool IsRegularFile(const std::string& path);

// The file that writing path replaces: path itself, or, when it is a
// symbolic link, the file the chain of links ends at (relative targets
// taken from their link's directory; the target need not exist yet). The
// tool writes through links, as the shell's ">" does: the link stays and
// its target gets the content. A chain of more than 40 links (a loop)
// throws Error.
std::string ThroughLinks(const std::string& path);

// Throws Error unless a file can be created at path (through its links,
// ThroughLinks): its directory exists and is writable (a temporary file is
// created there and removed: access() passes root everywhere), path is
// not a directory nor any other file that is not a regular one (a FIFO, a
// device: the temporary would be renamed over it), and the file there can
// be replaced (not another user's file in a sticky directory such as /tmp,
// where rename() fails though writing into the file works).
void CheckWritable(const std::string& path, const std::string& what);

// The file path names, for telling two spellings of one file apart:
// ThroughLinks(path)'s directory resolved (links, "." and "..") joined to
// its name; that path itself when the directory cannot be resolved.
std::string CanonicalPath(const std::string& path);

// A temporary file name next to path (same directory), to write to and
// then rename onto path: nothing is half-written. Unique within the run
// (a counter) and short enough for any file name that fits.
std::string TemporaryPathFor(const std::string& path);

// The most telling of a writer's captured errors; empty when there is
// none but the pipeline's own "returned failure for request" dump, which
// says nothing of the cause (the writer's error code may).
std::string BestError(const std::vector<std::string>& errors);

// A writer's error message as the user should read it: the temporary
// file's name (tmp) replaced by the output's (path), and vtkSTLWriter's
// "; deleting file: <tmp>" dropped (the temporary is removed, the file at
// path kept).
std::string ForUser(std::string why, const std::string& tmp, const std::string& path);

// Removes the file if it exists (no error).
void RemoveFile(const std::string& path);

// The files of a run, each written to a temporary file next to its path
// and renamed onto it by Commit() only once the whole run has succeeded:
// a failure late in the run (a picture, the last sample) must not leave
// the earlier outputs behind. The destructor removes the temporaries not
// committed, and so does a signal that kills the tool (SIGINT, SIGTERM,
// SIGHUP, SIGQUIT, SIGPIPE, SIGXCPU, SIGALRM, SIGVTALRM, SIGPROF,
// SIGUSR1, SIGUSR2) before the tool dies of it.
class PendingFiles
{
public:
  PendingFiles();
  ~PendingFiles();
  PendingFiles(const PendingFiles&) = delete;
  PendingFiles& operator=(const PendingFiles&) = delete;

  // The temporary file (TemporaryPathFor) to write path's content to,
  // next to the file it will replace (ThroughLinks(path)).
  std::string Add(const std::string& path);

  // Renames every temporary onto its path, all or nothing: the files
  // replaced are kept (hard links under hidden temporary names) until
  // every rename has succeeded, and put back if one fails; the files the
  // run created are then removed. Throws Error (every temporary removed).
  // A signal arriving meanwhile is held until the commit is over, then
  // undoes it before the tool dies of it.
  void Commit();

private:
  struct File
  {
    std::string Temporary;
    std::string Path;
  };
  std::vector<File> Files;
};

// "1234567" -> "1 234 567".
std::string Grouped(unsigned long long value);

// Number formatting with a fixed number of decimals, or as %g with six
// significant digits or more: enough to read the value back (as a float
// when it is one).
std::string Fixed(double value, int decimals);
std::string General(double value);

}

#endif
