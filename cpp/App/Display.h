// An X display for off-screen rendering (--compare, --distance): VTK 9.1 on
// Debian renders through GLX, so it needs an X server even off screen.
#ifndef precisemc_app_Display_h
#define precisemc_app_Display_h

namespace pmcapp
{

// Returns when $DISPLAY is set. Otherwise re-executes the tool under
// "xvfb-run -a" (does not return), or, without xvfb-run (or if the tool
// already runs under it), starts Xvfb itself for the life of the process
// and sets $DISPLAY. Throws pmcapp::Error when neither exists.
void EnsureDisplay(int argc, char* argv[]);

}

#endif
