// An X display for off-screen rendering (--compare, --distance): VTK 9.1 on
// Debian renders through GLX, so it needs an X server even off screen.
#ifndef precisemc_app_Display_h
#define precisemc_app_Display_h

namespace pmcapp
{

// Returns when $DISPLAY names a display that opens and has GLX. Otherwise
// (unset or unusable) starts Xvfb (found on $PATH) on a free display for
// the life of the process and sets $DISPLAY. Throws pmcapp::Error when
// Xvfb is missing, does not start or its display is unusable too.
void EnsureDisplay();

}

#endif
