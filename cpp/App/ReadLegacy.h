// Legacy VTK input (.vtk) of the precisemc tool: the checks before VTK's
// structured points reader runs (ReadLegacy.cxx).
#ifndef precisemc_app_ReadLegacy_h
#define precisemc_app_ReadLegacy_h

#include <string>

namespace pmcapp
{

// Refuses a file shorter than an attribute of its header declares, or a
// FIELD block that does not hold its arrays.
void CheckLegacySize(const std::string& path);

}

#endif
