// Finding an X display for off-screen rendering: re-execution under
// xvfb-run, or a private Xvfb started with -displayfd (the server writes
// its display number to a pipe once it accepts connections: no guessing of
// free numbers, no sleeping).
#include "Display.h"

#include "Common.h"

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

namespace pmcapp
{
namespace
{

// Set in the environment of the re-executed tool, so that it does not
// re-execute again if xvfb-run did not provide a display.
const char* const UnderXvfbRun = "PRECISEMC_UNDER_XVFB_RUN";

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

std::string SelfPath(const char* argv0)
{
  char buffer[4096];
  ssize_t n = readlink("/proc/self/exe", buffer, sizeof(buffer) - 1);
  if (n > 0)
  {
    buffer[n] = '\0';
    return buffer;
  }
  return argv0;
}

// Replaces this process by "xvfb-run -a <self> <args>"; returns only if
// exec fails.
void ReexecUnderXvfbRun(const std::string& xvfbRun, int argc, char* argv[])
{
  std::vector<std::string> args = { xvfbRun, "-a", "-s",
    "-screen 0 2048x2048x24 -nolisten tcp", SelfPath(argv[0]) };
  for (int i = 1; i < argc; ++i)
  {
    args.emplace_back(argv[i]);
  }
  std::vector<char*> raw;
  for (auto& a : args)
  {
    raw.push_back(&a[0]);
  }
  raw.push_back(nullptr);
  setenv(UnderXvfbRun, "1", 1);
  std::fflush(stdout);
  std::fflush(stderr);
  execv(xvfbRun.c_str(), raw.data());
  unsetenv(UnderXvfbRun);
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
      "-nolisten", "tcp", static_cast<char*>(nullptr));
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
    throw Error("cannot render: Xvfb did not start (no $DISPLAY)");
  }
  XvfbPid = pid;
  std::atexit(StopXvfb);
  setenv("DISPLAY", (":" + number).c_str(), 1);
}

}

void EnsureDisplay(int argc, char* argv[])
{
  const char* display = std::getenv("DISPLAY");
  if (display && *display)
  {
    return;
  }
  if (!std::getenv(UnderXvfbRun))
  {
    std::string xvfbRun = FindProgram("xvfb-run");
    if (!xvfbRun.empty())
    {
      ReexecUnderXvfbRun(xvfbRun, argc, argv);
    }
  }
  std::string xvfb = FindProgram("Xvfb");
  if (xvfb.empty())
  {
    throw Error("cannot render --compare/--distance pictures: no $DISPLAY and neither "
                "xvfb-run nor Xvfb is installed (Debian: apt-get install xvfb xauth)");
  }
  StartXvfb(xvfb);
}

}
