// MetaImage input (.mha, .mhd) of the precisemc tool: the checks of the
// header and its data before VTK's reader runs, and its world frame after
// (ReadMetaImage.cxx).
#ifndef precisemc_app_ReadMetaImage_h
#define precisemc_app_ReadMetaImage_h

#include <string>

class vtkImageData;

namespace pmcapp
{

// Refuses a header line VTK's reader would overflow on, or a header that
// does not end in the window the checks read.
void CheckMetaImageHeaderLines(const std::string& path);

// Refuses data files (a pattern, a LIST, one file) the reader would
// misread, crash or hang on.
void CheckMetaImageDataFiles(const std::string& path);

// Refuses compressed data that inflates to fewer bytes than DimSize needs.
void CheckMetaImageCompressedSize(const std::string& path);

// Applies the header's TransformMatrix (or Rotation, Orientation).
void ApplyMetaImageFrame(vtkImageData* volume, const std::string& path);

}

#endif
