// The command line of the precisemc tool: parsing and the help text.
#ifndef precisemc_app_Options_h
#define precisemc_app_Options_h

#include <string>
#include <vector>

namespace pmcapp
{

struct Options
{
  std::string Input;       // a volume file or a DICOM directory; "" = samples
  std::string Sample;      // "" (none asked), a sample name or "all"
  std::string Array;       // --array: the point array to contour; "" = default
  std::vector<double> Values; // -v; empty = the default isovalue

  // The filter's properties (vtkPreciseMarchingCubes enums).
  double Epsilon = 0.01;
  int MaxLevel = 5;
  int Rule = 1;     // RULE_A1
  int Topology = 0; // TOPOLOGY_TRILINEAR
  int Filter = 0;   // RECONSTRUCTION_TRILINEAR (--filter)
  int Normals = 1;  // 0 = none, else vtkPreciseMarchingCubes::NormalModes
  bool Gradients = false; // --gradients: a "Gradients" point array
  unsigned long long MaxTriangles = 0;
  int Threads = 0;
  bool SMP = false; // --smp: the library's work as vtkSMPTools tasks

  std::string Output;   // -o
  std::string Compare;  // --compare PNG
  std::string Distance; // --distance PNG
  std::string WriteVolume; // --write-volume VTI: the volume contoured

  bool Measure = false;     // --measure: distances to S_K in the table
  int MeasureDensity = -1;  // --measure-density; -1 = not given (3)

  bool Quiet = false;
  bool Help = false;
  bool Version = false;
};

// Parses argv; throws pmcapp::Error (status 2) with a one-line message on
// any mistake (unknown option, missing or malformed value, value out of
// range, two inputs).
Options ParseArguments(int argc, char* argv[]);

// The text printed by --help.
std::string UsageText();

// Names of the enums, as accepted on the command line.
std::string RuleName(int rule);
std::string TopologyName(int topology);
std::string FilterName(int filter);
std::string NormalsName(int normals);

}

#endif
