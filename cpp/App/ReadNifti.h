// NIfTI input (.nii, .nii.gz) of the precisemc tool: the header's checks
// before VTK's reader runs, its scaling and world frame after (ReadNifti.cxx).
#ifndef precisemc_app_ReadNifti_h
#define precisemc_app_ReadNifti_h

#include <string>

class vtkImageData;
class vtkNIFTIImageReader;

namespace pmcapp
{

// Refuses what VTK 9.1's NIfTI reader crashes on or misreads in a header.
void CheckNiftiHeader(const std::string& path);

// Applies the header's scl_slope and scl_inter to the volume's scalars.
void ApplyNiftiScaling(vtkNIFTIImageReader* reader, vtkImageData* volume);

// Applies the header's sform (else qform) to `volume`.
void ApplyNiftiFrame(vtkImageData* volume, const std::string& path, vtkNIFTIImageReader* reader);

}

#endif
