// Built-in sample volumes of the precisemc tool, generated in code.
#ifndef precisemc_app_Samples_h
#define precisemc_app_Samples_h

#include "vtkSmartPointer.h"

#include <string>
#include <vector>

class vtkImageData;

namespace pmcapp
{

struct Sample
{
  std::string Name;        // "tube", "atoms", "ml"
  std::string Description; // one line for the terminal
  double IsoValue;         // the isovalue the sample is made for
  vtkSmartPointer<vtkImageData> Volume;
};

// The names accepted by --sample, "all" excluded.
std::vector<std::string> SampleNames();

// Generates the named sample (one of SampleNames()).
Sample MakeSample(const std::string& name);

}

#endif
