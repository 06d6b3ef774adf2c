// NRRD input (.nrrd, .nhdr) of the precisemc tool: the header's checks
// before VTK's reader runs and its world frame after (ReadNrrd.cxx).
#ifndef precisemc_app_ReadNrrd_h
#define precisemc_app_ReadNrrd_h

#include <string>
#include <vector>

class vtkImageData;

namespace pmcapp
{

// What CheckNrrdHeader() returns of a header.
struct NrrdHeader
{
  std::vector<long long> sizes;
  std::string directions; // the "space directions" value, "" if absent
  std::string origin;     // the "space origin" value, "" if absent
};

// Refuses what VTK 9.1's NRRD reader would misread, crash or hang on.
NrrdHeader CheckNrrdHeader(const std::string& path);

// Applies the header's space directions and space origin to `volume`.
void ApplyNrrdFrame(vtkImageData* volume, const std::string& path, const NrrdHeader& header);

}

#endif
