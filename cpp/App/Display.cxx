// Finding an X display for off-screen rendering: a private Xvfb started
// with -displayfd (the server picks a free display itself and writes its
// number to a pipe once it accepts connections). Unlike "xvfb-run -a",
// which guesses a free number from lock files, this cannot collide with
// another X server started at the same moment. -noreset: otherwise the
// server resets when its last client disconnects and refuses the clients
// that connect meanwhile (VTK then aborts: "bad X server connection").
#include "Display.h"

#include "Common.h"

#include <cstdlib>
#include <string>

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

// Last: Xlib defines macros (Status, None, Bool) that clash with the code
// above.
#ifdef PRECISEMC_APP_HAVE_X11
#include <X11/Xlib.h>
#endif

namespace pmcapp
{
namespace
{

pid_t XvfbPid = 0;

void StopXvfb()
{
  if (XvfbPid > 0)
  {
    kill(XvfbPid, SIGTERM);
    waitpid(XvfbPid, nullptr, 0);
    XvfbPid = 0;
  }
}

std::string FindProgram(const std::string& name)
{
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/local/bin:/usr/bin:/bin";
  size_t begin = 0;
  while (begin <= dirs.size())
  {
    size_t end = dirs.find(':', begin);
    if (end == std::string::npos)
    {
      end = dirs.size();
    }
    std::string dir = dirs.substr(begin, end - begin);
    std::string candidate = (dir.empty() ? "." : dir) + "/" + name;
    if (IsRegularFile(candidate) && access(candidate.c_str(), X_OK) == 0)
    {
      return candidate;
    }
    begin = end + 1;
  }
  return std::string();
}

// Why the X display cannot render, or "" when it can. VTK's X render
// window abort()s on a display it cannot open (after the work is done,
// with no error line), and cannot render without GLX: both are checked
// here, before any work. Without Xlib there is nothing to check with.
std::string DisplayProblem(const std::string& name)
{
#ifdef PRECISEMC_APP_HAVE_X11
  // Xlib prints its own complaints (e.g. "Authorization required").
  StderrSilenced silenced;
  std::string problem;
  ::Display* display = XOpenDisplay(name.c_str());
  if (!display)
  {
    problem = "cannot open the X display '" + name + "'";
  }
  else
  {
    int opcode, event, error;
    if (!XQueryExtension(display, "GLX", &opcode, &event, &error))
    {
      problem = "the X display '" + name + "' has no GLX (OpenGL)";
    }
    XCloseDisplay(display);
  }
  return problem;
#else
  (void)name;
  return std::string();
#endif
}

// Starts Xvfb on a free display and points $DISPLAY at it.
void StartXvfb(const std::string& xvfb)
{
  int fds[2];
  if (pipe(fds) != 0)
  {
    throw Error("cannot start Xvfb: pipe failed");
  }
  pid_t pid = fork();
  if (pid < 0)
  {
    close(fds[0]);
    close(fds[1]);
    throw Error("cannot start Xvfb: fork failed");
  }
  if (pid == 0)
  {
    // The server dies with the tool, whatever way the tool ends.
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    close(fds[0]);
    int devnull = open("/dev/null", O_RDWR);
    if (devnull >= 0)
    {
      dup2(devnull, 0);
      dup2(devnull, 1);
      dup2(devnull, 2);
    }
    std::string fd = std::to_string(fds[1]);
    execl(xvfb.c_str(), "Xvfb", "-displayfd", fd.c_str(), "-screen", "0", "2048x2048x24",
      "-nolisten", "tcp", "-noreset", static_cast<char*>(nullptr));
    _exit(127);
  }
  close(fds[1]);
  std::string number;
  char c;
  while (read(fds[0], &c, 1) == 1 && c != '\n')
  {
    number += c;
  }
  close(fds[0]);
  if (number.empty())
  {
    waitpid(pid, nullptr, 0);
    throw Error("cannot render --compare/--distance pictures: Xvfb did not start");
  }
  XvfbPid = pid;
  std::atexit(StopXvfb);
  // The server's own display is checked like any other.
  std::string problem = DisplayProblem(":" + number);
  if (!problem.empty())
  {
    throw Error("cannot render --compare/--distance pictures with the Xvfb started: " + problem);
  }
  setenv("DISPLAY", (":" + number).c_str(), 1);
}

}

void EnsureDisplay()
{
  const char* display = std::getenv("DISPLAY");
  std::string problem = "no $DISPLAY";
  if (display && *display)
  {
    problem = DisplayProblem(display);
    if (problem.empty())
    {
      return;
    }
  }
  // An unusable $DISPLAY is replaced like a missing one: the pictures are
  // rendered off screen, any X server with GLX will do.
  std::string xvfb = FindProgram("Xvfb");
  if (xvfb.empty())
  {
    throw Error("cannot render --compare/--distance pictures: " + problem +
      " and Xvfb is not installed (Debian: apt-get install xvfb)");
  }
  StartXvfb(xvfb);
}

}
